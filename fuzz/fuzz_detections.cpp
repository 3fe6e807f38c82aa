// Fuzzes the detections file reader (JSON "mcslam-detections"): the input is the file. A file
// that reads must give boxes with non-negative sizes and scores in [0, 1].
#include "fuzz_support.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/perception/detection.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mcslam;
  const std::string path = fuzz::write("detections.json", fuzz::as_text(data, size));
  try {
    const perception::DetectionsFile file = perception::read_detections(path);
    for (const auto& frame : file.frames)
      for (const auto& d : frame.detections)
        if (!(d.box.width >= 0) || !(d.box.height >= 0) || !(d.score >= 0 && d.score <= 1))
          __builtin_trap();
  } catch (const InputError&) {
  }
  return 0;
}
