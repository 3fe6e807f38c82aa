// Fuzzes the MCAP reader (a ROS 2 recording's storage file): the input is the file. Opening and
// reading every message must end in messages or an InputError, never a crash or a hang.
#include "fuzz_support.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/rosbag2/recording.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mcslam;
  const std::string path =
      fuzz::write("input.mcap", std::string_view(reinterpret_cast<const char*>(data), size));
  try {
    const auto r = rosbag2::Recording::open(path);
    std::vector<bool> all(r->topics().size(), true);
    std::vector<rosbag2::MessageRef> refs;
    std::size_t bytes = 0;
    r->read(all, [&](const rosbag2::MessageRef& ref, const rosbag2::Payload& p) {
      if (ref.topic >= r->topics().size()) __builtin_trap();
      bytes += p.size;
      refs.push_back(ref);
    });
    for (const auto& ref : refs) {
      const rosbag2::Payload p = r->fetch(ref);
      if (p.size != ref.size && ref.size != 0) __builtin_trap();
    }
    (void)bytes;
  } catch (const InputError&) {
  }
  return 0;
}
