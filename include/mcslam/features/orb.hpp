#pragma once
// ORB features (oriented FAST keypoints + rotated binary descriptors) extracted from an image
// pyramid and spread evenly over the image, ORB-SLAM2 style.

#include <Eigen/Core>
#include <array>
#include <bit>
#include <cstdint>
#include <cstring>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>
#include <vector>

namespace mcslam::features {

/// A 256-bit binary descriptor. Bit j of byte i holds the outcome of binary test 8 * i + j.
struct OrbDescriptor {
  alignas(8) std::array<std::uint8_t, 32> bytes{};

  bool operator==(const OrbDescriptor& other) const = default;
};

/// Number of set bits of x. Where the build may not assume the x86-64 POPCNT instruction (the
/// baseline target, without -mpopcnt or -march), std::popcount compiles to a call into libgcc's
/// table-driven routine; the inline bit-sliced count is several times faster there (descriptor
/// distances are the inner loop of every matcher).
inline int popcount64(std::uint64_t x) {
#if defined(__x86_64__) && !defined(__POPCNT__)
  x = x - ((x >> 1) & 0x5555555555555555ULL);
  x = (x & 0x3333333333333333ULL) + ((x >> 2) & 0x3333333333333333ULL);
  x = (x + (x >> 4)) & 0x0F0F0F0F0F0F0F0FULL;
  return static_cast<int>((x * 0x0101010101010101ULL) >> 56);
#else
  return std::popcount(x);
#endif
}

/// Number of differing bits between two descriptors, in [0, 256].
inline int hamming_distance(const OrbDescriptor& a, const OrbDescriptor& b) {
  int distance = 0;
  for (int w = 0; w < 4; ++w) {
    std::uint64_t wa = 0;
    std::uint64_t wb = 0;
    std::memcpy(&wa, a.bytes.data() + 8 * w, sizeof(wa));
    std::memcpy(&wb, b.bytes.data() + 8 * w, sizeof(wb));
    distance += popcount64(wa ^ wb);
  }
  return distance;
}

struct Keypoint {
  /// Position in level-0 (full resolution) pixel coordinates.
  Eigen::Vector2f uv = Eigen::Vector2f::Zero();
  /// Pyramid level the keypoint was detected on (its scale is scale_factors()[level]).
  int level = 0;
  /// Orientation (intensity centroid direction) in degrees, in [0, 360), measured in image
  /// coordinates (x right, y down).
  float angle_deg = 0.0f;
  /// FAST corner score.
  float response = 0.0f;
};

struct OrbOptions {
  /// Number of keypoints to keep over all levels.
  int num_features = 1000;
  int num_levels = 8;
  /// Scale ratio between consecutive pyramid levels.
  double scale_factor = 1.2;
  /// FAST threshold; a grid cell that yields no corner is searched again with
  /// min_fast_threshold, which keeps keypoints on low-contrast (e.g. motion-blurred) regions.
  int fast_threshold = 20;
  int min_fast_threshold = 7;
  /// Inside the image region given to extract() as moving (where the previous frame saw moving
  /// objects), features are kept at most this many times as densely as an even spread over
  /// the image's area would put them: a level keeps at most moving_density x (the region's share
  /// of the image) x its quota there, and the rest of its budget goes to the static scene.
  /// People close to the camera are textured (clothing) in front of plain walls, and the spread
  /// of corners then gives them nearly all of the budget: Bonn crowd part 1, frame 318, had 969
  /// of 1000 features on people (who filled ~75 % of the image) and 19 pose inliers. With 1,
  /// Bonn crowd part 1 sequential gives 0.0193 m against 0.0195 m, and from frame 240 (people
  /// in view from the start) 0.0175 against 0.0224 m; on the synthetic scenes, whose walls are
  /// as textured as the people, it is mixed (0.0032 against 0.0050 m with one person, 0.0049
  /// to 0.0056 against 0.0044 m with four), so it is off by default (docs/crowd.md).
  /// 0: no limit.
  double moving_density = 0.0;

  /// An empty optional when the options are usable; otherwise what is wrong.
  std::optional<std::string> check() const;
};

/// Keypoints and their descriptors (same size, same order: by level, then spatially).
struct OrbFeatures {
  std::vector<Keypoint> keypoints;
  std::vector<OrbDescriptor> descriptors;

  std::size_t size() const { return keypoints.size(); }
  bool empty() const { return keypoints.empty(); }
};

class OrbExtractor {
 public:
  /// Precomputes the per-level scales and feature quotas and the test pattern. Throws
  /// mcslam::InputError when options.check() fails.
  explicit OrbExtractor(const OrbOptions& options);

  /// Extracts up to options().num_features features from an 8-bit grey image (CV_8UC1; any other
  /// type, or an empty image, yields no features). Keypoints keep a margin of
  /// kBorder pixels (at their level) from the image border. Thread-safe: several images may be
  /// extracted concurrently with the same extractor; the result is deterministic.
  /// `moving`: empty, or a CV_8UC1 mask of the image's size, non-zero where moving objects are
  /// expected; the corners there get at most options().moving_density times the mask's share
  /// of the image area of each level's quota, the others the rest.
  OrbFeatures extract(const cv::Mat& gray, const cv::Mat& moving = {}) const;

  int num_levels() const { return options_.num_levels; }
  /// scale_factor^level: 1, 1.2, 1.44, ...
  const std::vector<double>& scale_factors() const { return scale_factors_; }
  const std::vector<double>& inv_scale_factors() const { return inv_scale_factors_; }
  /// Squared scale (variance multiplier of a keypoint's position) per level and its inverse.
  const std::vector<double>& level_sigma2() const { return level_sigma2_; }
  const std::vector<double>& inv_level_sigma2() const { return inv_level_sigma2_; }
  /// Target number of features per level (geometric in the scale; sums to num_features).
  /// Levels with too few corners hand their remainder to the other levels at extraction time.
  const std::vector<int>& features_per_level() const { return features_per_level_; }
  const OrbOptions& options() const { return options_; }

  /// Radius of the circular patch used for orientation and descriptors.
  static constexpr int kHalfPatch = 15;
  /// Minimum distance (level pixels) of a keypoint from the level image border.
  static constexpr int kBorder = 16;

 private:
  OrbOptions options_;
  std::vector<double> scale_factors_;
  std::vector<double> inv_scale_factors_;
  std::vector<double> level_sigma2_;
  std::vector<double> inv_level_sigma2_;
  std::vector<int> features_per_level_;
  /// Half-width of the circular patch per row offset |v| in [0, kHalfPatch].
  std::array<int, kHalfPatch + 1> umax_{};
  /// Test pattern: 256 pairs (x1, y1, x2, y2), each point within radius kHalfPatch.
  std::array<std::array<float, 4>, 256> pattern_{};
};

}  // namespace mcslam::features
