#include "mcslam/io/files.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>

#include "io/test_support.hpp"

namespace mcslam::io {
namespace {

using iotest::expect_input_error;
using iotest::TempDir;

std::string read_file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(Files, WriteFileAtomicCreatesAndReplaces) {
  TempDir dir;
  const std::string path = dir.file("out.txt");
  write_file_atomic(path, "first\n");
  EXPECT_EQ(read_file_bytes(path), "first\n");
  write_file_atomic(path, std::string("second\0binary", 13));
  EXPECT_EQ(read_file_bytes(path), std::string("second\0binary", 13));
  write_file_atomic(path, "");
  EXPECT_EQ(read_file_bytes(path), "");
  int files = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir.str())) ++files;
  EXPECT_EQ(files, 1);  // no temporary left behind
}

TEST(Files, WriteFileAtomicErrors) {
  TempDir dir;
  expect_input_error([&] { write_file_atomic(dir.file("missing/out.txt"), "x"); },
                     {dir.file("missing/out.txt") + ": cannot write (", "No such file"});
  std::filesystem::create_directory(dir.file("sub"));
  expect_input_error([&] { write_file_atomic(dir.file("sub"), "x"); }, {"sub", "cannot write"});
  EXPECT_TRUE(std::filesystem::is_directory(dir.file("sub")));
  EXPECT_TRUE(std::filesystem::is_empty(dir.file("sub")));
}

TEST(Files, EnsureDirectory) {
  TempDir dir;
  const std::string nested = dir.file("a/b/c");
  ensure_directory(nested);
  EXPECT_TRUE(std::filesystem::is_directory(nested));
  ensure_directory(nested);  // already there: fine
  ensure_directory("");      // the current directory: nothing to do
  dir.write("file", "x");
  expect_input_error([&] { ensure_directory(dir.file("file")); },
                     {dir.file("file"), "not a directory"});
  expect_input_error([&] { ensure_directory(dir.file("file/sub")); },
                     {dir.file("file/sub"), "cannot create"});
}

}  // namespace
}  // namespace mcslam::io
