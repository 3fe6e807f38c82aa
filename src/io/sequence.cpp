#include "mcslam/io/sequence.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <string_view>
#include <system_error>
#include <tuple>
#include <vector>

#include "io/text_util.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/io/association.hpp"

namespace mcslam::io {
namespace fs = std::filesystem;

namespace {

struct ListEntry {
  double timestamp = 0.0;
  std::string listed_path;  // as written in the list
  std::string path;         // joined with the sequence directory
};

std::string join(const std::string& directory, std::string_view listed) {
  return (fs::path(directory) / fs::path(listed)).string();
}

bool file_exists(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

double parse_timestamp(std::string_view token, const std::string& where, const char* what) {
  const auto value = detail::parse_double(token);
  if (!value)
    throw InputError(
        file_error(where, std::string("malformed ") + what + " '" + std::string(token) + "'"));
  if (!std::isfinite(*value))
    throw InputError(
        file_error(where, std::string("non-finite ") + what + " '" + std::string(token) + "'"));
  if (*value < 0.0)
    throw InputError(
        file_error(where, std::string("negative ") + what + " '" + std::string(token) + "'"));
  return *value;
}

// Checks strict increase; `previous` holds the last value and its token.
void check_increasing(double value, std::string_view token, const std::string& where,
                      std::optional<std::pair<double, std::string>>& previous) {
  if (previous && !(value > previous->first)) {
    const char* problem =
        value == previous->first ? "duplicated timestamp " : "out-of-order timestamp ";
    throw InputError(file_error(
        where, problem + std::string(token) +
                   " (timestamps must increase strictly; previous: " + previous->second + ")"));
  }
  previous = std::make_pair(value, std::string(token));
}

// Summarises the missing files of one list in a single warning.
void warn_missing(const std::string& list_path, std::size_t missing, const std::string& first,
                  std::vector<std::string>& warnings) {
  if (missing == 0) return;
  const std::string count = std::to_string(missing);
  warnings.push_back(file_error(
      list_path, count +
                     (missing == 1 ? " listed file does not exist" : " listed files do not exist") +
                     " (first: " + first + "); skipped"));
}

// Reads a "timestamp path" list (rgb.txt, depth.txt), keeping the entries whose file exists.
std::vector<ListEntry> read_list(const std::string& directory, const std::string& list_path,
                                 std::vector<std::string>& warnings) {
  if (!file_exists(list_path)) throw InputError(file_error(list_path, "list file not found"));
  const std::vector<std::string> lines = detail::split_lines(detail::read_text_file(list_path));

  std::vector<ListEntry> entries;
  std::optional<std::pair<double, std::string>> previous;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (detail::is_blank_or_comment(lines[i])) continue;
    const std::string where = detail::at_line(list_path, static_cast<int>(i + 1));
    const auto fields = detail::split_fields(lines[i]);
    if (fields.size() != 2)
      throw InputError(file_error(
          where, "expected 2 columns 'timestamp path', got " + std::to_string(fields.size())));
    const double t = parse_timestamp(fields[0], where, "timestamp");
    check_increasing(t, fields[0], where, previous);
    entries.push_back({t, std::string(fields[1]), join(directory, fields[1])});
  }
  if (entries.empty()) throw InputError(file_error(list_path, "the list has no entries"));

  std::vector<ListEntry> existing;
  existing.reserve(entries.size());
  std::size_t missing = 0;
  std::string first_missing;
  for (ListEntry& e : entries) {
    if (file_exists(e.path)) {
      existing.push_back(std::move(e));
    } else if (missing++ == 0) {
      first_missing = e.listed_path;
    }
  }
  if (existing.empty())
    throw InputError(file_error(list_path, "none of the " + std::to_string(entries.size()) +
                                               " listed files exists (first: " + first_missing +
                                               ")"));
  warn_missing(list_path, missing, first_missing, warnings);
  return existing;
}

// TUM associate.py's pairing (io/association.hpp), the result sorted by RGB timestamp.
std::vector<FrameEntry> associate(const std::vector<ListEntry>& rgb,
                                  const std::vector<ListEntry>& depth, double max_difference) {
  std::vector<double> rgb_stamps, depth_stamps;
  for (const ListEntry& e : rgb) rgb_stamps.push_back(e.timestamp);
  for (const ListEntry& e : depth) depth_stamps.push_back(e.timestamp);
  const auto matches = associate_stamps(rgb_stamps, depth_stamps, max_difference);
  std::vector<FrameEntry> frames;
  frames.reserve(matches.size());
  for (const auto& [i, j] : matches)
    frames.push_back({rgb[i].timestamp, rgb[i].path, depth[j].timestamp, depth[j].path});
  return frames;
}

// Reads an associate.py output file ("t_rgb rgb_path t_depth depth_path").
std::vector<FrameEntry> read_associations(const std::string& directory, const std::string& path,
                                          std::vector<std::string>& warnings) {
  const std::vector<std::string> lines = detail::split_lines(detail::read_text_file(path));
  std::vector<FrameEntry> frames;
  std::optional<std::pair<double, std::string>> previous;
  std::size_t missing = 0;
  std::string first_missing;
  std::size_t listed = 0;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (detail::is_blank_or_comment(lines[i])) continue;
    const std::string where = detail::at_line(path, static_cast<int>(i + 1));
    const auto fields = detail::split_fields(lines[i]);
    if (fields.size() != 4)
      throw InputError(file_error(
          where, "expected 4 columns 'rgb_timestamp rgb_path depth_timestamp depth_path', got " +
                     std::to_string(fields.size())));
    FrameEntry frame;
    frame.rgb_timestamp = parse_timestamp(fields[0], where, "rgb timestamp");
    frame.depth_timestamp = parse_timestamp(fields[2], where, "depth timestamp");
    check_increasing(frame.rgb_timestamp, fields[0], where, previous);
    frame.rgb_path = join(directory, fields[1]);
    frame.depth_path = join(directory, fields[3]);
    ++listed;
    const bool rgb_ok = file_exists(frame.rgb_path);
    if (rgb_ok && file_exists(frame.depth_path)) {
      frames.push_back(std::move(frame));
    } else if (missing++ == 0) {
      first_missing = std::string(rgb_ok ? fields[3] : fields[1]);
    }
  }
  if (listed == 0) throw InputError(file_error(path, "the associations file has no entries"));
  if (frames.empty())
    throw InputError(file_error(
        path, "none of the " + std::to_string(listed) +
                  " listed pairs has both files (first missing: " + first_missing + ")"));
  warn_missing(path, missing, first_missing, warnings);
  return frames;
}

std::string describe_type(int type) {
  const int depth = CV_MAT_DEPTH(type);
  const char* bits = "unknown-depth";
  switch (depth) {
    case CV_8U:
      bits = "8-bit";
      break;
    case CV_8S:
      bits = "8-bit signed";
      break;
    case CV_16U:
      bits = "16-bit";
      break;
    case CV_16S:
      bits = "16-bit signed";
      break;
    case CV_32S:
      bits = "32-bit integer";
      break;
    case CV_32F:
      bits = "32-bit float";
      break;
    case CV_64F:
      bits = "64-bit float";
      break;
    case CV_16F:
      bits = "16-bit float";
      break;
    default:
      break;
  }
  return std::string(bits) + " " + std::to_string(CV_MAT_CN(type)) + "-channel";
}

std::string describe_size(const cv::Mat& image) {
  return std::to_string(image.cols) + "x" + std::to_string(image.rows);
}

}  // namespace

std::optional<std::string> SequenceOptions::check() const {
  if (!std::isfinite(max_time_difference) || max_time_difference <= 0.0)
    return "max_time_difference must be a positive number of seconds";
  return std::nullopt;
}

RgbdSequence RgbdSequence::open(const std::string& directory, const SequenceOptions& options) {
  if (const auto problem = options.check()) throw InputError("sequence options: " + *problem);

  RgbdSequence sequence;
  std::string dir = directory;
  while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
  sequence.directory_ = dir;
  std::error_code ec;
  if (dir.empty() || !fs::is_directory(dir, ec))
    throw InputError(file_error(directory, "sequence directory not found"));

  if (!options.associations_file.empty()) {
    std::string path = options.associations_file;
    if (!file_exists(path) && fs::path(path).is_relative() && file_exists(join(dir, path)))
      path = join(dir, path);
    if (!file_exists(path))
      throw InputError(file_error(options.associations_file, "associations file not found"));
    sequence.frames_ = read_associations(dir, path, sequence.warnings_);
    return sequence;
  }

  const std::string rgb_list = join(dir, "rgb.txt");
  const std::string depth_list = join(dir, "depth.txt");
  const std::vector<ListEntry> rgb = read_list(dir, rgb_list, sequence.warnings_);
  const std::vector<ListEntry> depth = read_list(dir, depth_list, sequence.warnings_);
  sequence.frames_ = associate(rgb, depth, options.max_time_difference);
  if (sequence.frames_.empty())
    throw InputError(file_error(dir, "no RGB and depth timestamps lie within " +
                                         detail::format_double("%g", options.max_time_difference) +
                                         " s of each other (rgb.txt from " +
                                         rgb.front().listed_path + ", depth.txt from " +
                                         depth.front().listed_path + ")"));
  return sequence;
}

std::string RgbdSequence::name() const {
  std::error_code ec;
  fs::path path = fs::absolute(directory_, ec);
  if (ec) path = directory_;
  path = path.lexically_normal();
  if (path.filename().empty()) path = path.parent_path();
  return path.filename().string();
}

std::optional<std::string> RgbdSequence::groundtruth_path() const {
  const std::string path = join(directory_, "groundtruth.txt");
  if (file_exists(path)) return path;
  return std::nullopt;
}

namespace {

/// Reads and decodes an image file. libjpeg decodes a truncated JPEG without an error (the
/// missing rows come out grey), so a JPEG must end with its end-of-image marker (trailing bytes
/// after it are allowed). Returns an empty matrix when the file cannot be read or decoded.
cv::Mat read_image(const std::string& path, int flags) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return {};
  const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)),
                                         std::istreambuf_iterator<char>());
  const bool jpeg = bytes.size() >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF;
  if (jpeg) {
    const std::size_t tail = std::min<std::size_t>(bytes.size(), 4096);
    bool end_marker = false;
    for (std::size_t i = bytes.size() - tail; i + 1 < bytes.size() && !end_marker; ++i)
      end_marker = bytes[i] == 0xFF && bytes[i + 1] == 0xD9;
    if (!end_marker) throw InputError(file_error(path, "truncated JPEG (no end-of-image marker)"));
  }
  if (bytes.empty()) return {};
  return cv::imdecode(bytes, flags);
}

}  // namespace

RgbdImages load_rgbd(const FrameEntry& frame, double depth_factor) {
  if (!std::isfinite(depth_factor) || depth_factor <= 0.0)
    throw InputError(file_error(frame.depth_path, "depth factor must be positive, got " +
                                                      detail::format_double("%g", depth_factor)));
  static const std::string kUnreadable = "cannot read image (missing, truncated or not an image)";
  RgbdImages images;
  images.rgb = read_image(frame.rgb_path, cv::IMREAD_COLOR);
  if (images.rgb.empty()) throw InputError(file_error(frame.rgb_path, kUnreadable));

  const cv::Mat raw = read_image(frame.depth_path, cv::IMREAD_UNCHANGED);
  if (raw.empty()) throw InputError(file_error(frame.depth_path, kUnreadable));
  if (raw.type() != CV_16UC1)
    throw InputError(
        file_error(frame.depth_path,
                   "depth must be a 16-bit single-channel PNG, got " + describe_type(raw.type())));
  if (raw.size() != images.rgb.size())
    throw InputError(file_error(frame.depth_path,
                                "depth size " + describe_size(raw) + " differs from the RGB size " +
                                    describe_size(images.rgb) + " of " + frame.rgb_path));

  images.depth.create(raw.size(), CV_32FC1);
  for (int r = 0; r < raw.rows; ++r) {
    const std::uint16_t* in = raw.ptr<std::uint16_t>(r);
    float* out = images.depth.ptr<float>(r);
    for (int c = 0; c < raw.cols; ++c)
      out[c] = static_cast<float>(static_cast<double>(in[c]) / depth_factor);
  }
  return images;
}

void check_image_size(const RgbdImages& images, int width, int height,
                      const std::string& rgb_path) {
  if (images.rgb.cols != width || images.rgb.rows != height)
    throw InputError(file_error(rgb_path, "image is " + std::to_string(images.rgb.cols) + "x" +
                                              std::to_string(images.rgb.rows) +
                                              " but the camera is " + std::to_string(width) + "x" +
                                              std::to_string(height)));
}

}  // namespace mcslam::io
