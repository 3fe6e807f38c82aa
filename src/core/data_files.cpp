#include "mcslam/core/data_files.hpp"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <system_error>

// Both set by src/CMakeLists.txt for this file: the data folder relative to an installation
// prefix ("share/mcslam") and its absolute path under the configured prefix.
#ifndef MCSLAM_DATA_SUBDIR
#error "MCSLAM_DATA_SUBDIR must be defined"
#endif
#ifndef MCSLAM_INSTALL_DATA_DIR
#error "MCSLAM_INSTALL_DATA_DIR must be defined"
#endif

namespace mcslam {
namespace {

namespace fs = std::filesystem;

std::mutex& hint_mutex() {
  static std::mutex m;
  return m;
}
std::string& hint() {
  static std::string h;
  return h;
}

/// The file that holds this function's code (an executable or a shared object), or "".
fs::path this_binary() {
  Dl_info info{};
  if (::dladdr(reinterpret_cast<const void*>(&this_binary), &info) == 0 ||
      info.dli_fname == nullptr)
    return {};
  std::error_code ec;
  fs::path p = fs::canonical(info.dli_fname, ec);
  return ec ? fs::path() : p;
}

fs::path running_executable() {
  std::error_code ec;
  fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path() : p;
}

void add_unique(std::vector<std::string>& out, const fs::path& p) {
  const std::string s = p.lexically_normal().string();
  for (const auto& existing : out)
    if (existing == s) return;
  out.push_back(s);
}

}  // namespace

std::vector<std::string> data_file_candidates(const std::string& name) {
  std::vector<std::string> out;
  if (const char* dir = std::getenv("MCSLAM_DATA_DIR"); dir != nullptr && *dir != '\0')
    add_unique(out, fs::path(dir) / name);
  {
    std::lock_guard lock(hint_mutex());
    if (!hint().empty()) add_unique(out, fs::path(hint()) / name);
  }
  for (const fs::path& binary : {this_binary(), running_executable()}) {
    if (binary.empty()) continue;
    // <prefix>/bin/mcslam, <prefix>/lib/python3.11/dist-packages/mcslam/_mcslam.so, and the
    // build tree's tests a few levels down: eight levels are plenty.
    fs::path dir = binary.parent_path();
    for (int level = 0; level < 8 && !dir.empty(); ++level) {
      add_unique(out, dir / MCSLAM_DATA_SUBDIR / name);
      if (dir == dir.root_path()) break;
      dir = dir.parent_path();
    }
  }
  add_unique(out, fs::path(MCSLAM_INSTALL_DATA_DIR) / name);
  return out;
}

std::string find_data_file(const std::string& name) {
  const std::vector<std::string> candidates = data_file_candidates(name);
  for (const auto& c : candidates) {
    std::error_code ec;
    if (fs::is_regular_file(c, ec)) return c;
  }
  return candidates.front();
}

void set_data_dir_hint(const std::string& directory) {
  std::lock_guard lock(hint_mutex());
  hint() = directory;
}

}  // namespace mcslam
