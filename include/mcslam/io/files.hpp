#pragma once
// Small file-system helpers shared by every writer of the project.

#include <string>

namespace mcslam::io {

/// Writes `content` to "<path>.tmp-<pid>" in the same directory, flushes it to disk and renames
/// it over `path`, so readers never see a half-written file. Throws InputError
/// "<path>: cannot write (reason)" when the directory is missing or not writable.
void write_file_atomic(const std::string& path, const std::string& content);

/// Creates the directory and its parents when needed (an empty path means the current directory
/// and does nothing). Throws InputError naming the path when it cannot be created or is a file.
void ensure_directory(const std::string& path);

}  // namespace mcslam::io
