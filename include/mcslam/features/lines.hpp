#pragma once
// Line segments: LSD detection, LBD descriptors, 3D endpoints from depth, and the geometric
// tests used to match a predicted segment (a projected 3D line) to an observed one.

#include <Eigen/Core>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/features/orb.hpp"

namespace mcslam::features {

/// LBD descriptor (mcslam's own, src/features/line_band_descriptor.hpp): a 256-bit binary
/// string, compared by Hamming distance like ORB's.
using LineDescriptor = OrbDescriptor;

struct LineOptions {
  /// The segment detector, run on the image scaled by detection_scale:
  /// - "region" (the default; "auto" means the same): mcslam's own detector with LSD's method
  ///   (regions of pixels whose gradients share a direction within 22.5 degrees, a rectangle
  ///   fitted to each, density refinement; src/features/region_line_detector.hpp). On 100
  ///   frames each of freiburg1_rpy and Bonn crowd at 256 x 192, 97-98 % of OpenCV's LSD
  ///   segments of 10 px or more come out within 0.5 px at both ends, in 0.23-0.25x its time
  ///   on one core (1.47 against 5.78 ms; 1.20 against 5.26 ms; tests/features/
  ///   line_detector_bench.cpp).
  /// - "lsd": OpenCV's Line Segment Detector with standard refinement, the reference.
  /// - "fld": the Fast Line Detector of OpenCV contrib's ximgproc (Canny edges split into
  ///   straight runs, each then moved onto its intensity step to a fraction of a pixel). It
  ///   splits some edges LSD finds whole, and the depth fit of a shorter piece can miss the line
  ///   tests' bound (1.8 cm off the true edge at 2.5 m against 1.5 cm); over the synthetic
  ///   crowds its ATE was up to 1.3x LSD's (docs/crowd.md).
  std::string detector = "auto";
  /// Segments shorter than this (pixels, full resolution) are dropped.
  double min_length = 25.0;
  /// At most this many segments are kept, longest first.
  int max_lines = 80;
  /// LSD runs on the image scaled by this factor (<= 1; smaller is faster and keeps the
  /// dominant structure); endpoints are returned in full-resolution pixels. The LBD descriptors
  /// are computed on the same scaled image. At 640x480, 0.4 takes ~8.5 ms per frame for LSD +
  /// LBD on one core (0.5: ~11.5 ms) with the same number of lines kept.
  double detection_scale = 0.4;
  /// 3D fitting from depth: samples taken along the segment.
  int depth_samples = 24;
  /// At least this fraction of the samples needs a valid depth.
  double min_valid_fraction = 0.5;
  /// A sample is an inlier when its distance to the fitted 3D line is below
  /// max(fit_tolerance, fit_tolerance_per_metre * z^2) metres (depth noise grows with z^2).
  double fit_tolerance = 0.01;
  double fit_tolerance_per_metre = 0.005;
  /// At least this fraction of the valid samples must be inliers; segments whose samples split
  /// into two depth layers (a segment straddling a depth discontinuity) fail this.
  double min_inlier_fraction = 0.8;

  std::optional<std::string> check() const;
};

struct LineFeature {
  /// Endpoints in full-resolution, undistorted pixels.
  Eigen::Vector2f start = Eigen::Vector2f::Zero();
  Eigen::Vector2f end = Eigen::Vector2f::Zero();
  LineDescriptor descriptor;
  /// Endpoints in the camera frame (metres), fitted from depth; valid when has_depth.
  bool has_depth = false;
  Eigen::Vector3d start_c = Eigen::Vector3d::Zero();
  Eigen::Vector3d end_c = Eigen::Vector3d::Zero();

  float length() const { return (end - start).norm(); }
  Eigen::Vector2f midpoint() const { return 0.5f * (start + end); }
  /// Normalised homogeneous line l = (a, b, c) with a^2 + b^2 = 1: a u + b v + c is the signed
  /// distance in pixels of (u, v) to the infinite line through the segment. l is start x end in
  /// homogeneous coordinates, so (a, b) is the direction end - start turned by +90 degrees,
  /// (-dy, dx) / |d|. Zero for a zero-length segment.
  Eigen::Vector3d coefficients() const;
};

class LineExtractor {
 public:
  /// Throws mcslam::InputError when options.check() fails.
  explicit LineExtractor(const LineOptions& options);
  ~LineExtractor();
  LineExtractor(const LineExtractor&) = delete;
  LineExtractor& operator=(const LineExtractor&) = delete;

  /// Segments with descriptors (has_depth false) from an 8-bit grey image (CV_8UC1; anything
  /// else, or an empty image, yields none). Deterministic. Not thread-safe: one extractor per
  /// thread.
  std::vector<LineFeature> extract(const cv::Mat& gray) const;

  /// Fits the 3D endpoints of `line` from a CV_32FC1 depth image in metres (0 or non-finite =
  /// missing) of the camera's size. Returns false (and leaves has_depth false) when too few
  /// samples have depth or when they do not lie on one 3D line.
  bool fit_depth(const PinholeCamera& camera, const cv::Mat& depth, LineFeature& line) const;

  const LineOptions& options() const { return options_; }

 private:
  struct Impl;
  LineOptions options_;
  std::unique_ptr<Impl> impl_;
};

/// How close a predicted segment (e.g. a map line projected into the image) must be to an
/// observed one to be its match.
struct LineMatchCriteria {
  int max_descriptor_distance = 80;
  /// Angle between the two segments' directions.
  double max_angle_deg = 10.0;
  /// Mean distance of the predicted endpoints to the observed infinite line (pixels).
  double max_distance = 20.0;
  /// Length of the overlap of the two segments, measured along the observed one, relative to the
  /// shorter segment.
  double min_overlap = 0.3;
};

/// A predicted segment and its descriptor.
struct PredictedLine {
  Eigen::Vector2d start = Eigen::Vector2d::Zero();
  Eigen::Vector2d end = Eigen::Vector2d::Zero();
  LineDescriptor descriptor;
};

/// True when `predicted` passes the geometric tests of `criteria` against `observed`
/// (descriptor not compared).
bool line_geometry_consistent(const PredictedLine& predicted, const LineFeature& observed,
                              const LineMatchCriteria& criteria);

struct LineMatch {
  int predicted = -1;  // index into the predicted lines
  int observed = -1;   // index into the observed lines
  int distance = 0;    // Hamming distance of the descriptors
};

/// For each predicted line, the observed line that passes the geometric tests with the least
/// descriptor distance (at most criteria.max_descriptor_distance); each observed line goes to at
/// most one predicted line (the closest in descriptor). Sorted by predicted index.
std::vector<LineMatch> match_lines(const std::vector<PredictedLine>& predicted,
                                   const std::vector<LineFeature>& observed,
                                   const LineMatchCriteria& criteria);

}  // namespace mcslam::features
