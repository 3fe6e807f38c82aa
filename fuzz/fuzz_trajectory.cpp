// Fuzzes the TUM trajectory reader (ground truth and estimates): the input is the file. A file
// that reads must give finite poses with unit quaternions, and written back it must read the same.
#include <cmath>

#include "fuzz_support.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/io/trajectory_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mcslam;
  const std::string path = fuzz::write("trajectory.txt", fuzz::as_text(data, size));
  Trajectory trajectory;
  try {
    trajectory = io::read_tum_trajectory(path);
  } catch (const InputError&) {
    return 0;
  }
  for (const StampedPose& p : trajectory) {
    if (!std::isfinite(p.timestamp) || !p.T_w_c.translation().allFinite()) __builtin_trap();
    if (std::abs(p.T_w_c.quaternion().norm() - 1.0) > 1e-6) __builtin_trap();
  }
  const std::string copy = (fuzz::scratch() / "copy.txt").string();
  io::write_tum_trajectory(copy, trajectory);
  if (io::read_tum_trajectory(copy).size() != trajectory.size()) __builtin_trap();
  return 0;
}
