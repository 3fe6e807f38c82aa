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

}  // namespace

void write_file_atomic(const std::string& path, const std::string& content) {
  const std::string tmp = path + ".tmp-" + std::to_string(static_cast<long long>(::getpid()));
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw_write_error(path, errno);

  auto fail = [&](int err) {
    ::close(fd);
    ::unlink(tmp.c_str());
    throw_write_error(path, err);
  };
  const char* data = content.data();
  std::size_t left = content.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, data, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail(errno);
    }
    data += n;
    left -= static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0 && errno != EINVAL && errno != EROFS) fail(errno);
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    throw_write_error(path, err);
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    throw_write_error(path, err);
  }
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
