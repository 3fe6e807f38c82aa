#include "mcslam/io/files.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "mcslam/core/error.hpp"

namespace mcslam::io {
namespace {

[[noreturn]] void throw_write_error(const std::string& path, int err) {
  throw InputError(file_error(path, std::string("cannot write (") + std::strerror(err) + ")"));
}

std::string temporary_name(const std::string& path) {
  return path + ".tmp-" + std::to_string(static_cast<long long>(::getpid()));
}

/// Writes all of `content`; the errno of the failure, or 0.
int write_all(int fd, const std::string& content) {
  const char* data = content.data();
  std::size_t left = content.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, data, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    data += n;
    left -= static_cast<std::size_t>(n);
  }
  return 0;
}

/// Flushes and closes `fd`, then renames `tmp` over `path`; removes `tmp` and throws on failure.
void finish_atomic(int fd, const std::string& tmp, const std::string& path) {
  int err = 0;
  if (::fsync(fd) != 0 && errno != EINVAL && errno != EROFS) err = errno;
  if (::close(fd) != 0 && err == 0) err = errno;
  if (err == 0 && ::rename(tmp.c_str(), path.c_str()) != 0) err = errno;
  if (err != 0) {
    ::unlink(tmp.c_str());
    throw_write_error(path, err);
  }
}

}  // namespace

void write_file_atomic(const std::string& path, const std::string& content) {
  const std::string tmp = temporary_name(path);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw_write_error(path, errno);
  if (const int err = write_all(fd, content); err != 0) {
    ::close(fd);
    ::unlink(tmp.c_str());
    throw_write_error(path, err);
  }
  finish_atomic(fd, tmp, path);
}

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)), tmp_(temporary_name(path_)) {
  fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) throw_write_error(path_, errno);
}

AtomicFile::~AtomicFile() {
  if (fd_ < 0) return;
  ::close(fd_);
  ::unlink(tmp_.c_str());
}

void AtomicFile::append(const std::string& text) {
  if (fd_ < 0) throw InputError(file_error(path_, "cannot write (already committed)"));
  if (const int err = write_all(fd_, text); err != 0) throw_write_error(path_, err);
}

void AtomicFile::commit() {
  if (fd_ < 0) throw InputError(file_error(path_, "cannot write (already committed)"));
  const int fd = fd_;
  fd_ = -1;  // finish_atomic closes it, and removes the temporary file on failure
  finish_atomic(fd, tmp_, path_);
}

void ensure_directory(const std::string& path) {
  if (path.empty()) return;
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (fs::exists(status)) {
    if (fs::is_directory(status)) return;
    throw InputError(file_error(path, "cannot create directory: it exists and is not a directory"));
  }
  fs::create_directories(path, ec);
  if (ec) throw InputError(file_error(path, "cannot create directory (" + ec.message() + ")"));
  if (!fs::is_directory(path, ec)) throw InputError(file_error(path, "cannot create directory"));
}

}  // namespace mcslam::io
