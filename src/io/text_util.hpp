#pragma once
// Internal helpers of the io module: reading text files and parsing numbers strictly.

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace mcslam::io::detail {

/// The whole file; throws InputError "<path>: cannot open file (reason)" when it cannot be read.
std::string read_text_file(const std::string& path);

/// The file's lines without line terminators ("\n" or "\r\n").
std::vector<std::string> split_lines(const std::string& text);

/// Splits on spaces and tabs (and commas when `commas` is true); empty fields are dropped.
std::vector<std::string_view> split_fields(std::string_view line, bool commas = false);

/// True for blank lines and lines whose first non-blank character is '#'.
bool is_blank_or_comment(std::string_view line);

/// The number the whole token spells (an optional leading '+' is allowed), or nullopt. "inf" and
/// "nan" parse; callers check finiteness.
std::optional<double> parse_double(std::string_view token);

/// The integer the whole token spells, or nullopt.
std::optional<long long> parse_integer(std::string_view token);

/// "<path>:<line>" for messages.
std::string at_line(const std::string& path, int line);

/// printf-style formatting of one double, e.g. format_double("%.6f", t).
std::string format_double(const char* format, double value);

}  // namespace mcslam::io::detail
