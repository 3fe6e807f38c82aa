#pragma once
// Temporary directories and InputError message checks, shared by the test suites.

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "mcslam/core/error.hpp"

namespace mcslam::test {

/// A fresh temporary directory "<prefix>_<pid>_<n>", removed with its contents on destruction.
class TempDir {
 public:
  explicit TempDir(const std::string& prefix = "mcslam_test") {
    static std::atomic<int> counter{0};
    const auto base = std::filesystem::temp_directory_path();
    for (;;) {
      path_ = base / (prefix + "_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
      if (std::filesystem::create_directory(path_)) break;
    }
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& relative) const { return path_ / relative; }
  std::string str() const { return path_.string(); }
  std::string file(const std::string& relative) const { return (path_ / relative).string(); }

  /// Writes `content` (binary) to the relative path, creating parent directories; returns it.
  std::string write(const std::string& relative, const std::string& content) const {
    const auto p = path_ / relative;
    std::filesystem::create_directories(p.parent_path());
    std::ofstream out(p, std::ios::binary);
    out << content;
    return p.string();
  }

 private:
  std::filesystem::path path_;
};

/// Runs fn and expects an InputError whose message contains every one of `parts`.
inline void expect_input_error(const std::function<void()>& fn,
                               const std::vector<std::string>& parts) {
  try {
    fn();
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    for (const auto& part : parts)
      EXPECT_NE(message.find(part), std::string::npos)
          << "message '" << message << "' lacks '" << part << "'";
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected InputError, got " << e.what();
  }
}

}  // namespace mcslam::test
