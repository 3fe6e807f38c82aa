#include "mcslam/app/detect.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <system_error>
#include <utility>
#include <vector>

#include "io/text_util.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/core/timing.hpp"
#include "mcslam/io/files.hpp"
#include "mcslam/perception/detection.hpp"

namespace mcslam::app {
namespace {

namespace fs = std::filesystem;

struct ImageEntry {
  double timestamp = 0.0;
  std::string path;
};

bool is_file(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

// rgb.txt with the rules of io::RgbdSequence (which also needs depth.txt, unlike detection):
// "timestamp path" lines, '#' comments, finite non-negative strictly increasing timestamps,
// paths relative to the folder; listed files that do not exist are skipped with one warning.
std::vector<ImageEntry> read_rgb_list(const std::string& directory,
                                      std::vector<std::string>& warnings) {
  const std::string list = (fs::path(directory) / "rgb.txt").string();
  if (!is_file(list))
    throw InputError(file_error(directory, "not an image, and the folder has no rgb.txt"));
  const std::vector<std::string> lines = io::detail::split_lines(io::detail::read_text_file(list));
  std::vector<ImageEntry> entries;
  std::size_t listed = 0, missing = 0;
  std::string first_missing;
  std::optional<std::pair<double, std::string>> previous;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (io::detail::is_blank_or_comment(lines[i])) continue;
    const std::string where = io::detail::at_line(list, static_cast<int>(i + 1));
    const auto fields = io::detail::split_fields(lines[i]);
    if (fields.size() != 2)
      throw InputError(file_error(
          where, "expected 2 columns 'timestamp path', got " + std::to_string(fields.size())));
    const std::string token(fields[0]);
    const auto t = io::detail::parse_double(fields[0]);
    if (!t) throw InputError(file_error(where, "malformed timestamp '" + token + "'"));
    if (!std::isfinite(*t)) throw InputError(file_error(where, "non-finite timestamp " + token));
    if (*t < 0.0) throw InputError(file_error(where, "negative timestamp " + token));
    if (previous && !(*t > previous->first))
      throw InputError(file_error(
          where, "timestamp " + token +
                     " does not increase strictly (previous: " + previous->second + ")"));
    previous = std::make_pair(*t, token);
    ++listed;
    const std::string path = (fs::path(directory) / fs::path(std::string(fields[1]))).string();
    if (is_file(path)) {
      entries.push_back({*t, path});
    } else if (missing++ == 0) {
      first_missing = std::string(fields[1]);
    }
  }
  if (listed == 0) throw InputError(file_error(list, "the list has no entries"));
  if (entries.empty())
    throw InputError(file_error(list, "none of the " + std::to_string(listed) +
                                          " listed files exists (first: " + first_missing + ")"));
  if (missing > 0)
    warnings.push_back(file_error(
        list, std::to_string(missing) +
                  (missing == 1 ? " listed file does not exist" : " listed files do not exist") +
                  " (first: " + first_missing + "); skipped"));
  return entries;
}

// annotated/<image name>.jpg, unique even when two listed images share a name.
std::string annotated_name(const std::string& image_path, std::set<std::string>& used) {
  std::string stem = fs::path(image_path).stem().string();
  if (stem.empty()) stem = "image";
  std::string name = stem;
  for (int k = 2; !used.insert(name).second; ++k) name = stem + "_" + std::to_string(k);
  return name + ".jpg";
}

class ProgressBar {
 public:
  ProgressBar(bool enabled, std::size_t total) : enabled_(enabled), total_(total) {}
  void update(std::size_t done) {
    if (!enabled_ || (done % 5 != 0 && done != total_)) return;
    const int width = 30;
    const int filled = total_ == 0 ? width : static_cast<int>(width * done / total_);
    std::fprintf(stderr, "\r[%s%s] %zu/%zu ", std::string(filled, '#').c_str(),
                 std::string(width - filled, '.').c_str(), done, total_);
    if (done == total_) std::fputc('\n', stderr);
    std::fflush(stderr);
  }

 private:
  bool enabled_;
  std::size_t total_;
};

double round_to(double value, double step) { return std::round(value / step) * step; }

/// The images to run on: the input image, or the sequence's rgb.txt (up to --max-frames);
/// warnings for listed files that are missing.
std::vector<ImageEntry> list_images(const DetectRequest& request,
                                    std::vector<std::string>& warnings) {
  std::vector<ImageEntry> images;
  std::error_code ec;
  if (fs::is_directory(request.input, ec)) {
    images = read_rgb_list(request.input, warnings);
  } else if (is_file(request.input)) {
    images.push_back({0.0, request.input});
  } else {
    throw InputError(file_error(request.input, "no such image or sequence folder"));
  }
  if (request.max_frames > 0 && images.size() > static_cast<std::size_t>(request.max_frames))
    images.resize(static_cast<std::size_t>(request.max_frames));
  return images;
}

/// An annotated image (InputError when it cannot be written).
void write_annotated(const std::string& path, const cv::Mat& image) {
  bool written = false;
  try {
    written = cv::imwrite(path, image);
  } catch (const cv::Exception&) {
    written = false;
  }
  if (!written) throw InputError(file_error(path, "cannot write the annotated image"));
}

/// What the detector found over the images, and the boxes for detections.json.
struct DetectTally {
  perception::DetectionsFile file;
  std::optional<cv::Size> common_size;
  bool sizes_agree = true;
  std::map<std::string, int> per_class;
  std::vector<double> detector_ms;
  std::size_t total = 0, frames_with_objects = 0;
};

/// The detector on every image: the boxes, drawn into annotated/ and counted.
DetectTally detect_all(const perception::Detector& detector, const std::vector<ImageEntry>& images,
                       const fs::path& annotated_dir, bool progress) {
  DetectTally tally;
  tally.detector_ms.reserve(images.size());
  std::set<std::string> used_names;
  ProgressBar bar(progress, images.size());
  for (std::size_t i = 0; i < images.size(); ++i) {
    const ImageEntry& entry = images[i];
    cv::Mat image = cv::imread(entry.path, cv::IMREAD_COLOR);
    if (image.empty())
      throw InputError(
          file_error(entry.path, "cannot read image (missing, truncated or not an image)"));
    if (!tally.common_size) tally.common_size = image.size();
    tally.sizes_agree = tally.sizes_agree && *tally.common_size == image.size();

    const Stopwatch watch;
    std::vector<perception::Detection> detections = detector.detect(image);
    tally.detector_ms.push_back(watch.elapsed_ms());

    tally.total += detections.size();
    if (!detections.empty()) ++tally.frames_with_objects;
    for (const auto& d : detections) ++tally.per_class[d.class_name];

    perception::draw_detections(image, detections);
    write_annotated((annotated_dir / annotated_name(entry.path, used_names)).string(), image);
    tally.file.frames.push_back({entry.timestamp, std::move(detections)});
    bar.update(i + 1);
  }
  if (tally.common_size && tally.sizes_agree) {
    tally.file.image_width = tally.common_size->width;
    tally.file.image_height = tally.common_size->height;
  }
  return tally;
}

}  // namespace

nlohmann::json detect_images(const DetectRequest& request) {
  if (const auto problem = request.options.check()) throw InputError(*problem);
  if (request.max_frames < 0)
    throw InputError("max_frames must be >= 0, got " + std::to_string(request.max_frames));
  if (request.output_dir.empty()) throw InputError("no output folder given");

  // The images first, so a wrong path fails before the model loads or anything is written.
  std::vector<std::string> warnings;
  const std::vector<ImageEntry> images = list_images(request, warnings);
  for (const auto& warning : warnings) std::cerr << "mcslam: warning: " << warning << "\n";

  const Stopwatch load_watch;
  const perception::Detector detector(request.model, request.options);
  const double load_ms = load_watch.elapsed_ms();

  const fs::path out(request.output_dir);
  const fs::path annotated_dir = out / "annotated";
  io::ensure_directory(request.output_dir);
  io::ensure_directory(annotated_dir.string());

  DetectTally tally = detect_all(detector, images, annotated_dir, request.progress);
  tally.file.source = fs::path(request.model).filename().string();
  const std::string detections_path = (out / "detections.json").string();
  perception::write_detections(detections_path, tally.file);

  const SampleStats stats = compute_stats(tally.detector_ms);
  nlohmann::json summary;
  summary["input"] = request.input;
  summary["model"] = detector.path();
  summary["format"] = perception::to_string(detector.format());
  summary["input_size"] = {detector.input_size().width, detector.input_size().height};
  summary["classes"] = detector.class_names().size();
  summary["confidence"] = request.options.confidence;
  summary["nms_iou"] = request.options.nms_iou;
  summary["frames"] = images.size();
  summary["frames_with_detections"] = tally.frames_with_objects;
  summary["detections"] = tally.total;
  summary["detections_per_class"] = tally.per_class;
  summary["detector_ms"] = {{"median", round_to(stats.median, 0.01)},
                            {"p95", round_to(stats.p95, 0.01)},
                            {"mean", round_to(stats.mean, 0.01)},
                            {"max", round_to(stats.max, 0.01)}};
  summary["load_ms"] = round_to(load_ms, 0.1);
  summary["output_dir"] = request.output_dir;
  summary["detections_file"] = detections_path;
  summary["warnings"] = warnings;
  return summary;
}

std::string detect_summary_text(const nlohmann::json& summary) {
  std::ostringstream s;
  s << "frames: " << summary.value("frames", 0) << " ("
    << summary.value("frames_with_detections", 0) << " with objects)\n";
  s << "detections: " << summary.value("detections", 0);
  const auto& per_class = summary.at("detections_per_class");
  if (!per_class.empty()) {
    // Most frequent classes first.
    std::vector<std::pair<int, std::string>> counts;
    for (const auto& [name, count] : per_class.items()) counts.emplace_back(count.get<int>(), name);
    std::sort(counts.begin(), counts.end(), [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    s << " (";
    for (std::size_t i = 0; i < counts.size(); ++i)
      s << (i ? ", " : "") << counts[i].second << " " << counts[i].first;
    s << ")";
  }
  s << "\n";
  const auto& size = summary.at("input_size");
  char line[200];
  std::snprintf(line, sizeof line, "detector: %s %dx%d, median %.1f ms, p95 %.1f ms per image\n",
                summary.value("format", std::string()).c_str(), size.at(0).get<int>(),
                size.at(1).get<int>(), summary.at("detector_ms").value("median", 0.0),
                summary.at("detector_ms").value("p95", 0.0));
  s << line;
  return s.str();
}

}  // namespace mcslam::app
