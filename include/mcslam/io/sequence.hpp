#pragma once
// RGB-D sequences in the TUM RGB-D layout: rgb.txt and depth.txt ("timestamp relative/path"
// per line), optionally an associations file, and groundtruth.txt.

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

namespace mcslam::io {

/// One associated RGB-D pair. Paths are the sequence directory joined with the listed path (a
/// listed absolute path stays as it is).
struct FrameEntry {
  double rgb_timestamp = 0.0;
  std::string rgb_path;
  double depth_timestamp = 0.0;
  std::string depth_path;
};

struct SequenceOptions {
  /// Largest |t_rgb - t_depth| (seconds, exclusive) of an associated pair.
  double max_time_difference = 0.02;
  /// Optional TUM associate.py output ("t_rgb rgb_path t_depth depth_path" per line). Empty:
  /// associate rgb.txt and depth.txt. A relative path is used as given when it exists, otherwise
  /// it is looked up in the sequence directory. Paths inside it are relative to the sequence.
  std::string associations_file;

  /// An empty optional when the options are usable; otherwise what is wrong.
  std::optional<std::string> check() const;
};

class RgbdSequence {
 public:
  /// Reads and associates the sequence's lists. Throws InputError ("<file>:<line>: ...") for a
  /// missing directory or list, malformed lines (a list line is exactly "timestamp path"),
  /// negative or non-finite timestamps, timestamps that do not increase strictly, lists without
  /// entries, and when no pair associates. Listed files that do not exist are skipped with one
  /// warning per list file.
  static RgbdSequence open(const std::string& directory, const SequenceOptions& options = {});

  /// The directory as given, without trailing separators.
  const std::string& directory() const { return directory_; }
  /// The folder's own name, e.g. "rgbd_dataset_freiburg1_rpy".
  std::string name() const;
  /// Associated frames, sorted by (strictly increasing) RGB timestamp.
  const std::vector<FrameEntry>& frames() const { return frames_; }
  /// directory/groundtruth.txt when that file exists.
  std::optional<std::string> groundtruth_path() const;
  /// Problems that did not stop loading, e.g.
  /// "<dir>/depth.txt: 6 listed files do not exist (first: depth/xxx.png); skipped".
  const std::vector<std::string>& warnings() const { return warnings_; }

 private:
  std::string directory_;
  std::vector<FrameEntry> frames_;
  std::vector<std::string> warnings_;
};

struct RgbdImages {
  cv::Mat rgb;    ///< CV_8UC3, BGR
  cv::Mat depth;  ///< CV_32FC1, metres; 0 = no depth
};

/// InputError naming `rgb_path` when the colour image is not width x height (the camera's).
void check_image_size(const RgbdImages& images, int width, int height, const std::string& rgb_path);

/// Loads one frame: the RGB image (png or jpg) as 8-bit BGR and the 16-bit single-channel depth
/// PNG divided by `depth_factor` (raw value per metre; 0 stays 0). Throws InputError naming the
/// file when an image cannot be read, the depth image is not 16-bit single-channel, or the sizes
/// of the two images differ.
RgbdImages load_rgbd(const FrameEntry& frame, double depth_factor);

}  // namespace mcslam::io
