#pragma once
// Shared by the libFuzzer targets: a scratch folder per process, and writing the input to files
// there, since the parsers under test read files as mcslam does.

#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>

namespace mcslam::fuzz {

/// A folder removed with everything in it when the process ends normally (a crash keeps it).
struct ScratchFolder {
  std::filesystem::path path;
  explicit ScratchFolder(std::filesystem::path p) : path(std::move(p)) {
    std::filesystem::create_directories(path);
  }
  ~ScratchFolder() {
    std::error_code ignored;
    std::filesystem::remove_all(path, ignored);
  }
  ScratchFolder(const ScratchFolder&) = delete;
  ScratchFolder& operator=(const ScratchFolder&) = delete;
};

/// This process's scratch folder (made once, under $TMPDIR or /tmp; removed at exit).
inline const std::filesystem::path& scratch() {
  static const ScratchFolder dir(std::filesystem::temp_directory_path() /
                                 ("mcslam_fuzz_" + std::to_string(::getpid())));
  return dir.path;
}

inline std::string write(const std::string& name, std::string_view bytes) {
  const auto path = scratch() / name;
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(bytes.data(), static_cast<long>(bytes.size()));
  return path.string();
}

inline std::string_view as_text(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

}  // namespace mcslam::fuzz
