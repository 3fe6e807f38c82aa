// Fuzzes the sequence lists: the input, split at its first NUL byte, becomes rgb.txt and
// depth.txt of a folder whose images exist, and the sequence is opened. Bad lists must end in
// InputError; anything else (another exception, a crash, a sanitizer report) is a bug.
#include <filesystem>

#include "fuzz_support.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/io/sequence.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace fs = std::filesystem;
  using namespace mcslam;
  static const fs::path dir = [] {
    const fs::path d = fuzz::scratch() / "seq";
    fs::create_directories(d / "rgb");
    fs::create_directories(d / "depth");
    // Files the lists may name (the parser only checks that listed files exist).
    for (const char* name : {"rgb/1.png", "rgb/2.png", "depth/1.png", "depth/2.png", "a", "b"})
      fuzz::write(std::string("seq/") + name, "x");
    return d;
  }();
  const std::string_view text = fuzz::as_text(data, size);
  const std::size_t split = text.find('\0');
  fuzz::write("seq/rgb.txt", text.substr(0, split));
  fuzz::write("seq/depth.txt", split == std::string_view::npos ? text : text.substr(split + 1));
  try {
    const io::RgbdSequence sequence = io::RgbdSequence::open(dir.string());
    double previous = -1.0;
    for (const io::FrameEntry& f : sequence.frames()) {
      // What open() promises: strictly increasing, finite, non-negative RGB timestamps.
      if (!(f.rgb_timestamp > previous) || !std::isfinite(f.rgb_timestamp)) __builtin_trap();
      previous = f.rgb_timestamp;
    }
  } catch (const InputError&) {
  }
  return 0;
}
