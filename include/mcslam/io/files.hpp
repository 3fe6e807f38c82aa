#pragma once
// Small file-system helpers shared by every writer of the project.

#include <string>

namespace mcslam::io {

/// Writes `content` to "<path>.tmp-<pid>" in the same directory, flushes it to disk and renames
/// it over `path`, so readers never see a half-written file. Throws InputError
/// "<path>: cannot write (reason)" when the directory is missing or not writable.
void write_file_atomic(const std::string& path, const std::string& content);

/// A file written piece by piece that appears under its name only when committed: the text goes
/// to "<path>.tmp-<pid>" as it comes (so a long run does not hold it in memory), and commit()
/// flushes it to disk and renames it over `path`. Destroyed without commit(), it removes the
/// temporary file and leaves `path` as it was. Write errors throw InputError naming `path`.
class AtomicFile {
 public:
  explicit AtomicFile(std::string path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  void append(const std::string& text);
  void commit();
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::string tmp_;
  int fd_ = -1;
};

/// Creates the directory and its parents when needed (an empty path means the current directory
/// and does nothing). Throws InputError naming the path when it cannot be created or is a file.
void ensure_directory(const std::string& path);

}  // namespace mcslam::io
