#pragma once
// Running the real `mcslam` binary from a test: shell quoting, captured output, exit status.

#include <sys/wait.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <sstream>
#include <string>

namespace mcslam::test {

/// True when `part` occurs in `text`.
inline bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

inline std::string quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

inline std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

inline void write_file(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

struct CliResult {
  int exit_code = -1;    // -1 when the process did not exit normally
  bool crashed = false;  // ended by a signal
  std::string out;
  std::string err;
};

inline std::ostream& operator<<(std::ostream& os, const CliResult& r) {
  return os << "exit " << r.exit_code << (r.crashed ? " (signal)" : "") << "\nstdout:\n"
            << r.out << "\nstderr:\n"
            << r.err;
}

/// Number of lines (newline characters) in a program's output.
inline int count_lines(const std::string& text) {
  int lines = 0;
  for (char c : text) lines += c == '\n';
  return lines;
}

/// Runs `<exe> <args>` (args already quoted), stdout and stderr going to the given files, and
/// returns the exit code and both outputs.
inline CliResult run_command(const std::string& exe, const std::string& args,
                             const std::filesystem::path& out, const std::filesystem::path& err) {
  const std::string command = quote(exe) + " " + args + " >" + quote(out.string()) + " 2>" +
                              quote(err.string()) + " </dev/null";
  const int status = std::system(command.c_str());
  CliResult r;
  if (status != -1 && WIFEXITED(status)) r.exit_code = WEXITSTATUS(status);
  // std::system runs /bin/sh, which reports a child killed by signal N as exit code 128 + N.
  r.crashed = (status != -1 && WIFSIGNALED(status)) || r.exit_code > 128;
  r.out = read_file(out);
  r.err = read_file(err);
  return r;
}

/// The same, with the outputs in `dir` as stdout_<n>.txt and stderr_<n>.txt (n counts the calls
/// of this process, so that every run keeps its own).
inline CliResult run_command(const std::string& exe, const std::string& args,
                             const std::filesystem::path& dir) {
  static std::atomic<int> runs{0};
  const std::string n = std::to_string(runs++);
  return run_command(exe, args, dir / ("stdout_" + n + ".txt"), dir / ("stderr_" + n + ".txt"));
}

}  // namespace mcslam::test
