#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/ximgproc/fast_line_detector.hpp>
#include <optional>
#include <utility>
#include <vector>

#include "line_band_descriptor.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/features/lines.hpp"
#include "region_line_detector.hpp"

namespace mcslam::features {
namespace {

/// Fraction of the segment skipped at each end when sampling depth: LSD endpoints are the least
/// precise part of a segment and often touch the next surface (corners, occlusions).
constexpr double kEndMargin = 0.05;
/// Depth is also looked up this many pixels to each side of the segment, and across a depth
/// discontinuity the nearest depth wins: a segment on an occluding contour then takes the
/// occluder's depth (the surface the edge belongs to) even when depth and colour are a pixel
/// apart or the contour pixels lack depth (Kinect-type sensors drop both sides of a jump).
constexpr int kSideOffset = 3;
/// Depth differences above this fraction of the depth (or twice the fit tolerance) between
/// pixels a few apart are taken as a jump between two surfaces.
constexpr double kRelativeDepthJump = 0.05;
/// Typical error of a segment's position across its direction, in pixels.
constexpr double kSegmentPositionError = 0.5;
/// A fitted 3D line whose angle to an endpoint's viewing ray is below this is rejected: the
/// endpoint (ray/line intersection) is then ill-conditioned.
constexpr double kMinRayAngleDeg = 10.0;
/// Hypotheses from sample pairs less than 1/kMinPairGapDivisor of the valid samples apart are not
/// tried: their direction is poorly determined and the wider pairs already cover every layout.
constexpr int kMinPairGapDivisor = 4;
/// Larger detection images are refused: the detectors store coordinates in `float` and a frame
/// that size is not a camera's.
constexpr int kMaxDetectionImageSide = 32000;

/// Liang-Barsky clipping of the segment a-b to [0, w-1] x [0, h-1]; false when nothing is left.
bool clip_to_image(Eigen::Vector2d& a, Eigen::Vector2d& b, double w, double h) {
  const Eigen::Vector2d d = b - a;
  double t0 = 0.0;
  double t1 = 1.0;
  const std::array<double, 4> p{-d.x(), d.x(), -d.y(), d.y()};
  const std::array<double, 4> q{a.x(), w - 1.0 - a.x(), a.y(), h - 1.0 - a.y()};
  for (int k = 0; k < 4; ++k) {
    if (p[k] == 0.0) {
      if (q[k] < 0.0) return false;
      continue;
    }
    const double r = q[k] / p[k];
    if (p[k] < 0.0) {
      t0 = std::max(t0, r);
    } else {
      t1 = std::min(t1, r);
    }
    if (t0 > t1) return false;
  }
  const Eigen::Vector2d a0 = a;
  a = a0 + t0 * d;
  b = a0 + t1 * d;
  return true;
}

/// A 3D line through `point` with unit `direction`.
struct Line3 {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();

  double squared_distance(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d v = p - point;
    return (v - v.dot(direction) * direction).squaredNorm();
  }
};

/// Total least squares line (centroid + principal axis) through the points flagged in `use`.
bool pca_line(const std::vector<Eigen::Vector3d>& points, const std::vector<char>& use,
              Line3& line) {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  int count = 0;
  for (std::size_t k = 0; k < points.size(); ++k) {
    if (!use[k]) continue;
    centroid += points[k];
    ++count;
  }
  if (count < 2) return false;
  centroid /= count;
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (std::size_t k = 0; k < points.size(); ++k) {
    if (!use[k]) continue;
    const Eigen::Vector3d v = points[k] - centroid;
    scatter += v * v.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  if (solver.info() != Eigen::Success) return false;
  // Eigenvalues ascend: the last eigenvector is the principal axis.
  const Eigen::Vector3d direction = solver.eigenvectors().col(2);
  if (!direction.allFinite() || solver.eigenvalues()(2) <= 0.0) return false;
  line.point = centroid;
  line.direction = direction.normalized();
  return true;
}

/// Flags the inliers of `line` (distance below the per-point tolerance); returns their number.
int mark_inliers(const Line3& line, const std::vector<Eigen::Vector3d>& points,
                 const std::vector<double>& tolerance2, std::vector<char>& inlier) {
  int count = 0;
  for (std::size_t k = 0; k < points.size(); ++k) {
    inlier[k] = line.squared_distance(points[k]) < tolerance2[k] ? 1 : 0;
    count += inlier[k];
  }
  return count;
}

/// The point on the ray {lambda * ray, lambda > 0} closest to `line`, if the two are not nearly
/// parallel and that point lies in front of the camera within `max_miss` of the line.
std::optional<Eigen::Vector3d> ray_line_point(const Eigen::Vector3d& ray, const Line3& line,
                                              double min_sin_angle, double max_miss) {
  const Eigen::Vector3d r = ray.normalized();
  const Eigen::Vector3d& d = line.direction;
  const double b = r.dot(d);
  const double denom = 1.0 - b * b;  // sin^2 of the angle between the ray and the line
  if (!(denom > min_sin_angle * min_sin_angle)) return std::nullopt;
  // Minimise |lambda r - (p + mu d)|^2 over lambda, mu (unit r and d).
  const Eigen::Vector3d& p = line.point;
  const double rp = r.dot(p);
  const double dp = d.dot(p);
  const double lambda = (rp - b * dp) / denom;
  const double mu = (b * rp - dp) / denom;
  if (!(lambda > 0.0)) return std::nullopt;
  const Eigen::Vector3d on_ray = lambda * r;
  if ((on_ray - (p + mu * d)).norm() > max_miss) return std::nullopt;
  if (!(on_ray.z() > 0.0)) return std::nullopt;
  return on_ray;
}

/// Bilinear intensity of an 8-bit image (at least 2x2) at pixel-centre coordinates (x, y),
/// clamped to the image.
double intensity(const cv::Mat& image, double x, double y) {
  x = std::clamp(x, 0.0, image.cols - 1.0);
  y = std::clamp(y, 0.0, image.rows - 1.0);
  const int x0 = std::min(static_cast<int>(x), image.cols - 2);
  const int y0 = std::min(static_cast<int>(y), image.rows - 2);
  const double ax = x - x0;
  const double ay = y - y0;
  const std::uint8_t* r0 = image.ptr<std::uint8_t>(y0);
  const std::uint8_t* r1 = image.ptr<std::uint8_t>(y0 + 1);
  return (1.0 - ay) * ((1.0 - ax) * r0[x0] + ax * r0[x0 + 1]) +
         ay * ((1.0 - ax) * r1[x0] + ax * r1[x0 + 1]);
}

/// Samples taken along a segment to refine its position across its direction.
constexpr int kRefineSamples = 24;
/// The edge is searched this many pixels to each side of the segment (detection image): FLD's
/// edge pixels are within one pixel of the intensity step.
constexpr int kRefineReach = 2;
/// A refinement that would move the segment further than this (detection-image pixels) is
/// refused: it found another edge, not this one's sub-pixel position.
constexpr double kRefineMaxShift = 1.0;

/// Where an intensity step crosses the line through p along `normal`: the offset (pixels along
/// the normal) of the strongest directional derivative within kRefineReach, and the step's sign
/// (+1: brighter along the normal). The derivative is a central difference of the bilinear image,
/// one pixel apart, at whole-pixel offsets; the peak is that of a Gaussian through the strongest
/// response and its two neighbours (a blurred step's derivative is one), or of a parabola when a
/// neighbour has no response. Nothing when the strongest response is at the end of the reach.
std::optional<std::pair<double, int>> step_across(const cv::Mat& image, const Eigen::Vector2d& p,
                                                  const Eigen::Vector2d& normal) {
  std::array<double, 2 * kRefineReach + 1> response{};
  for (int t = -kRefineReach; t <= kRefineReach; ++t) {
    const Eigen::Vector2d plus = p + (t + 0.5) * normal;
    const Eigen::Vector2d minus = p + (t - 0.5) * normal;
    response[static_cast<std::size_t>(t + kRefineReach)] =
        intensity(image, plus.x(), plus.y()) - intensity(image, minus.x(), minus.y());
  }
  std::size_t best = 0;
  for (std::size_t i = 1; i < response.size(); ++i)
    if (std::abs(response[i]) > std::abs(response[best])) best = i;
  if (best == 0 || best + 1 == response.size()) return std::nullopt;
  const double l = std::abs(response[best - 1]);
  const double c = std::abs(response[best]);
  const double r = std::abs(response[best + 1]);
  const double curvature = l - 2.0 * c + r;
  if (!(curvature < 0.0) || !(c > 0.0)) return std::nullopt;
  double peak = 0.5 * (l - r) / curvature;
  if (l > 0.0 && r > 0.0) {
    const double log_curvature = std::log(l) - 2.0 * std::log(c) + std::log(r);
    if (log_curvature < 0.0) peak = 0.5 * (std::log(l) - std::log(r)) / log_curvature;
  }
  return std::pair{static_cast<double>(best) - kRefineReach + peak, response[best] > 0.0 ? 1 : -1};
}

/// Moves an FLD segment (detection-image coordinates) onto the sub-pixel position of its
/// intensity step. FLD fits its segments to Canny's edge pixels, which lie on one side of a step
/// edge, half a pixel off on average. The step is found across the segment at kRefineSamples
/// points along it (step_across), and a line fitted to the offsets (offset = a + b * position
/// along the segment) moves both endpoints. Samples of the other polarity than the majority are
/// left out; with fewer than a third of the samples left, or a shift beyond kRefineMaxShift,
/// the segment stays as it was.
void refine_segment(const cv::Mat& image, cv::Vec4f& segment) {
  const Eigen::Vector2d a(segment[0], segment[1]);
  const Eigen::Vector2d b(segment[2], segment[3]);
  const double length = (b - a).norm();
  if (!(length > 2.0)) return;
  const Eigen::Vector2d dir = (b - a) / length;
  const Eigen::Vector2d normal(-dir.y(), dir.x());
  struct Sample {
    double position, offset;
    int sign;
  };
  std::array<Sample, kRefineSamples> samples{};
  int found = 0;
  int positive = 0;
  for (int k = 0; k < kRefineSamples; ++k) {
    const double s = (k + 0.5) / kRefineSamples * length;
    if (const auto step = step_across(image, a + s * dir, normal)) {
      samples[static_cast<std::size_t>(found++)] = {s, step->first, step->second};
      positive += step->second > 0 ? 1 : 0;
    }
  }
  const int polarity = 2 * positive >= found ? 1 : -1;
  double sw = 0.0, ss = 0.0, so = 0.0, sss = 0.0, sso = 0.0;
  for (int k = 0; k < found; ++k) {
    const Sample& sample = samples[static_cast<std::size_t>(k)];
    if (sample.sign != polarity) continue;
    sw += 1.0;
    ss += sample.position;
    so += sample.offset;
    sss += sample.position * sample.position;
    sso += sample.position * sample.offset;
  }
  if (sw < kRefineSamples / 3.0) return;
  const double det = sw * sss - ss * ss;
  if (!(det > 1e-9)) return;
  const double slope = (sw * sso - ss * so) / det;
  const double shift_a = (so - slope * ss) / sw;
  const double shift_b = shift_a + slope * length;
  if (!(std::abs(shift_a) <= kRefineMaxShift) || !(std::abs(shift_b) <= kRefineMaxShift)) return;
  const Eigen::Vector2d a2 = a + shift_a * normal;
  const Eigen::Vector2d b2 = b + shift_b * normal;
  segment = cv::Vec4f(static_cast<float>(a2.x()), static_cast<float>(a2.y()),
                      static_cast<float>(b2.x()), static_cast<float>(b2.y()));
}

}  // namespace

std::optional<std::string> LineOptions::check() const {
  if (!std::isfinite(min_length) || min_length < 0.0)
    return "lines.min_length must be finite and >= 0";
  if (max_lines < 1 || max_lines > 100000) return "lines.max_lines must be in [1, 100000]";
  if (detector != "lsd" && detector != "fld" && detector != "region" && detector != "auto")
    return "lines.detector must be lsd, fld, region or auto, got '" + detector + "'";
  if (!std::isfinite(detection_scale) || detection_scale < 0.05 || detection_scale > 1.0)
    return "lines.detection_scale must be in [0.05, 1]";
  if (depth_samples < 4 || depth_samples > 256) return "lines.depth_samples must be in [4, 256]";
  if (!std::isfinite(min_valid_fraction) || min_valid_fraction <= 0.0 || min_valid_fraction > 1.0)
    return "lines.min_valid_fraction must be in (0, 1]";
  if (!std::isfinite(fit_tolerance) || fit_tolerance <= 0.0)
    return "lines.fit_tolerance must be finite and > 0";
  if (!std::isfinite(fit_tolerance_per_metre) || fit_tolerance_per_metre < 0.0)
    return "lines.fit_tolerance_per_metre must be finite and >= 0";
  if (!std::isfinite(min_inlier_fraction) || min_inlier_fraction <= 0.0 ||
      min_inlier_fraction > 1.0)
    return "lines.min_inlier_fraction must be in (0, 1]";
  return std::nullopt;
}

Eigen::Vector3d LineFeature::coefficients() const {
  // l = start_h x end_h, scaled so that (a, b) is the unit normal: (a, b) is the direction
  // end - start turned by +90 degrees, (-dy, dx) / |d|.
  const Eigen::Vector3d s(start.x(), start.y(), 1.0);
  const Eigen::Vector3d e(end.x(), end.y(), 1.0);
  const Eigen::Vector3d l = s.cross(e);
  const double n = l.head<2>().norm();
  if (!(n > 0.0)) return Eigen::Vector3d::Zero();
  return l / n;
}

struct LineExtractor::Impl {
  cv::Ptr<cv::LineSegmentDetector> lsd;
  cv::Ptr<cv::ximgproc::FastLineDetector> fld;
  std::unique_ptr<detail::RegionLineDetector> region;
  // Scratch buffers reused between frames (hence: one extractor per thread).
  detail::LineBandDescriber lbd;
  cv::Mat scaled;
  std::vector<cv::Vec4f> segments;

  /// Runs the detector on `gray` scaled to `size` (into `segments`); returns the detection
  /// image (`gray` itself or `scaled`), or nullptr when OpenCV refuses the image.
  const cv::Mat* detect(const cv::Mat& gray, const cv::Size& size);
};

LineExtractor::LineExtractor(const LineOptions& options) : options_(options) {
  if (auto problem = options_.check()) throw InputError(*problem);
  impl_ = std::make_unique<Impl>();
  if (options_.detector == "fld") {
    // Segments of at least 10 px of the detection image (min_length filters at full resolution
    // afterwards), edge pixels within 1.41 px of the fitted line (one diagonal pixel), Canny
    // hysteresis 50/50 with a 3x3 aperture: the detector's published defaults. Collinear pieces
    // are not merged: LSD does not merge either, and the map merges a line's views.
    impl_->fld = cv::ximgproc::createFastLineDetector(10, 1.414213562f, 50.0, 50.0, 3, false);
  } else if (options_.detector == "lsd") {
    // Standard refinement (regions are cut where the aligned-pixel density drops, which splits
    // curved edges) on an image we scale ourselves: LSD's own scale would blur the full image.
    impl_->lsd = cv::createLineSegmentDetector(cv::LSD_REFINE_STD, 1.0);
  } else {
    impl_->region = std::make_unique<detail::RegionLineDetector>();
  }
}

LineExtractor::~LineExtractor() = default;

namespace {

/// Pixel-centre coordinates between the full image and the detection image: cv::resize maps
/// pixel centres as x_scaled = (x + 0.5) * sx - 0.5.
struct DetectionScale {
  double sx = 1.0;
  double sy = 1.0;

  Eigen::Vector2d to_full(double x, double y) const {
    return {(x + 0.5) / sx - 0.5, (y + 0.5) / sy - 0.5};
  }
  Eigen::Vector2d to_scaled(const Eigen::Vector2d& p) const {
    return {(p.x() + 0.5) * sx - 0.5, (p.y() + 0.5) * sy - 0.5};
  }
};

/// A detected segment in full-resolution pixels, clipped to the image; `index` is its place in
/// the detector's output.
struct Candidate {
  Eigen::Vector2d start;
  Eigen::Vector2d end;
  double length;
  int index;
};

/// The detector's segments (detection-image coordinates) at least min_length long at full
/// resolution once clipped to the image, longest first, at most max_lines.
std::vector<Candidate> longest_segments(const std::vector<cv::Vec4f>& segments,
                                        const DetectionScale& scale, const cv::Size& full,
                                        const LineOptions& options) {
  std::vector<Candidate> candidates;
  candidates.reserve(segments.size());
  for (std::size_t i = 0; i < segments.size(); ++i) {
    const cv::Vec4f& s = segments[i];
    Eigen::Vector2d a = scale.to_full(s[0], s[1]);
    Eigen::Vector2d b = scale.to_full(s[2], s[3]);
    if (!a.allFinite() || !b.allFinite()) continue;
    if (!clip_to_image(a, b, full.width, full.height)) continue;
    const double length = (b - a).norm();
    if (!(length >= options.min_length) || length <= 0.0) continue;
    candidates.push_back({a, b, length, static_cast<int>(i)});
  }
  // Longest first; the detector's output order (deterministic) breaks ties.
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& x, const Candidate& y) {
    return x.length != y.length ? x.length > y.length : x.index < y.index;
  });
  if (candidates.size() > static_cast<std::size_t>(options.max_lines))
    candidates.resize(static_cast<std::size_t>(options.max_lines));
  return candidates;
}

/// Moves FLD's kept segments onto their edges' sub-pixel position (LSD's and the region
/// detector's already are there): by at most a pixel of the detection image each.
void refine_fld_candidates(const cv::Mat& image, const std::vector<cv::Vec4f>& segments,
                           const DetectionScale& scale, const cv::Size& full,
                           std::vector<Candidate>& candidates) {
  for (Candidate& c : candidates) {
    cv::Vec4f refined = segments[static_cast<std::size_t>(c.index)];
    refine_segment(image, refined);
    Eigen::Vector2d a = scale.to_full(refined[0], refined[1]);
    Eigen::Vector2d b = scale.to_full(refined[2], refined[3]);
    if (a.allFinite() && b.allFinite() && clip_to_image(a, b, full.width, full.height)) {
      c.start = a;
      c.end = b;
    }
  }
}

/// Depth-fit tolerance (metres) at depth z: the sensor's noise grows with z^2.
double fit_tolerance_at(const LineOptions& options, double z) {
  return std::max(options.fit_tolerance, options.fit_tolerance_per_metre * z * z);
}

/// The depths of the pixels across a segment at one sample point, kSideOffset pixels to each
/// side, and which of them belong to the foreground surface.
struct DepthProfile {
  /// Depth by offset (index o + kSideOffset); 0 where missing.
  std::array<double, 2 * kSideOffset + 1> depth{};
  /// Signed distance of each pixel centre from the segment.
  std::array<double, 2 * kSideOffset + 1> offset{};
  /// The nearest depth (infinite when no pixel has depth).
  double nearest = std::numeric_limits<double>::infinity();
  /// Depths more than this behind the nearest one are background.
  double jump = 0.0;

  /// The depth at offset o when it is a foreground pixel, else 0. Pixels beyond a depth jump
  /// behind the nearest one are background: the segment belongs to the foreground surface (an
  /// occluding contour is an edge of the occluder).
  double foreground(int o) const {
    if (o < -kSideOffset || o > kSideOffset) return 0.0;
    const double z = depth[static_cast<std::size_t>(o + kSideOffset)];
    return z > 0.0 && z - nearest <= jump ? z : 0.0;
  }
};

/// Depths across the segment (along `normal`) at its point uv, with the signed distance of their
/// pixel centres from the segment, the nearest depth and the jump threshold.
DepthProfile depth_across(const cv::Mat& depth, const Eigen::Vector2d& uv,
                          const Eigen::Vector2d& normal, const LineOptions& options) {
  DepthProfile profile;
  for (int o = -kSideOffset; o <= kSideOffset; ++o) {
    const Eigen::Vector2d q = uv + o * normal;
    const long x = std::lround(q.x());
    const long y = std::lround(q.y());
    double z = 0.0;
    if (x >= 0 && y >= 0 && x < depth.cols && y < depth.rows)
      z = depth.at<float>(static_cast<int>(y), static_cast<int>(x));
    if (!std::isfinite(z) || z <= 0.0) z = 0.0;
    const auto index = static_cast<std::size_t>(o + kSideOffset);
    profile.depth[index] = z;
    profile.offset[index] = normal.dot(Eigen::Vector2d(double(x), double(y)) - uv);
    if (z > 0.0) profile.nearest = std::min(profile.nearest, z);
  }
  if (std::isfinite(profile.nearest))
    profile.jump = std::max(2.0 * fit_tolerance_at(options, profile.nearest),
                            kRelativeDepthJump * profile.nearest);
  return profile;
}

/// A pixel across the segment: its offset and depth.
struct ProfilePixel {
  int offset = 0;
  double z = 0.0;
};

/// Of the foreground pixels, the one closest to the segment (the nearer one on a tie of
/// distance): the nearest depth alone would be biased towards the camera on surfaces seen at a
/// grazing angle. z is 0 when there is none.
ProfilePixel closest_foreground(const DepthProfile& profile) {
  ProfilePixel chosen;
  for (int r = 0; r <= kSideOffset && chosen.z == 0.0; ++r) {
    const double minus = profile.foreground(-r);
    const double plus = profile.foreground(r);
    if (minus > 0.0 && (plus == 0.0 || minus <= plus)) {
      chosen = {-r, minus};
    } else if (plus > 0.0) {
      chosen = {r, plus};
    }
  }
  return chosen;
}

/// Depth slope across the segment: a line fit z = a + b t over the run of foreground pixels that
/// starts at `from` and leaves the segment by `step` (several pixels average the depth noise).
/// False when the run is too short or degenerate.
bool fit_side(const DepthProfile& profile, int from, int step, double& a, double& b) {
  double st = 0.0, sz = 0.0, stt = 0.0, stz = 0.0;
  int count = 0;
  for (int o = from; profile.foreground(o) > 0.0; o += step) {
    const double t = profile.offset[static_cast<std::size_t>(o + kSideOffset)];
    const double zo = profile.foreground(o);
    st += t;
    sz += zo;
    stt += t * t;
    stz += t * zo;
    ++count;
  }
  const double det = count * stt - st * st;
  if (count < 2 || !(det > 1e-9)) return false;
  b = (count * stz - st * sz) / det;
  a = (sz - b * st) / count;
  return true;
}

/// The segment's depth at a sample from the depths across it, or nothing when the sample has no
/// reliable depth.
std::optional<double> sample_depth(const DepthProfile& profile, const LineOptions& options) {
  if (!std::isfinite(profile.nearest)) return std::nullopt;
  const ProfilePixel chosen = closest_foreground(profile);
  double z = chosen.z;
  double slope = 0.0;
  if (chosen.offset != 0) {
    // The nearest foreground pixel is off the segment (missing depth at the contour, or
    // colour and depth a pixel apart): extrapolate its surface to the segment when that
    // changes the depth by more than the noise (~ a third of the tolerance); otherwise the
    // extrapolation would only amplify the noise.
    double a = 0.0;
    double b = 0.0;
    if (fit_side(profile, chosen.offset, chosen.offset > 0 ? 1 : -1, a, b)) {
      slope = std::abs(b);
      if (a > 0.0 && std::abs(a - z) > fit_tolerance_at(options, z) / 3.0) z = a;
    }
  } else {
    for (int step : {-1, 1}) {
      double a = 0.0;
      double b = 0.0;
      if (fit_side(profile, 0, step, a, b)) slope = std::max(slope, std::abs(b));
    }
  }
  // On a surface seen at a grazing angle, LSD's own error in the segment position (about half
  // a pixel) makes a depth error beyond the tolerance: such samples are dropped.
  if (slope * kSegmentPositionError > fit_tolerance_at(options, z)) return std::nullopt;
  return z;
}

/// 3D samples of a segment and the square of each one's fit tolerance.
struct DepthSamples {
  std::vector<Eigen::Vector3d> points;
  std::vector<double> tolerance2;
};

/// Samples the depth along the segment s + t d (t in [kEndMargin, 1 - kEndMargin]). Samples are
/// back-projected at their position on the segment (not at the pixel whose depth they took), so
/// that all of them lie in the plane through the camera centre and the 2D line.
DepthSamples sample_segment(const PinholeCamera& camera, const cv::Mat& depth,
                            const Eigen::Vector2d& s, const Eigen::Vector2d& d,
                            const Eigen::Vector2d& normal, const LineOptions& options) {
  const int n = options.depth_samples;
  DepthSamples samples;
  samples.points.reserve(static_cast<std::size_t>(n));
  samples.tolerance2.reserve(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const double t = kEndMargin + (1.0 - 2.0 * kEndMargin) * k / (n - 1.0);
    const Eigen::Vector2d uv = s + t * d;
    const std::optional<double> z = sample_depth(depth_across(depth, uv, normal, options), options);
    if (!z) continue;
    const double tolerance = fit_tolerance_at(options, *z);
    samples.points.push_back(camera.unproject(uv, *z));
    samples.tolerance2.push_back(tolerance * tolerance);
  }
  return samples;
}

/// RANSAC over sample pairs, exhaustive and in a fixed order (deterministic), scored by the
/// truncated squared residual (MSAC). Most segments fit with the first, widest pair: stops as
/// soon as a hypothesis explains every sample. Nothing when no pair gives a line.
std::optional<Line3> ransac_line(const DepthSamples& samples) {
  const std::vector<Eigen::Vector3d>& points = samples.points;
  const int valid = static_cast<int>(points.size());
  Line3 best_line;
  double best_cost = std::numeric_limits<double>::infinity();
  const int min_gap = std::max(1, valid / kMinPairGapDivisor);
  bool done = false;
  for (int gap = valid - 1; gap >= min_gap && !done; --gap) {
    for (int i = 0; i + gap < valid && !done; ++i) {
      const Eigen::Vector3d& a = points[static_cast<std::size_t>(i)];
      const Eigen::Vector3d dir = points[static_cast<std::size_t>(i + gap)] - a;
      const double dir_norm = dir.norm();
      if (!(dir_norm > 1e-9)) continue;
      const Line3 hypothesis{a, dir / dir_norm};
      double cost = 0.0;
      int inliers = 0;
      for (int k = 0; k < valid && cost < best_cost; ++k) {
        const auto ks = static_cast<std::size_t>(k);
        const double r = hypothesis.squared_distance(points[ks]) / samples.tolerance2[ks];
        if (r < 1.0) ++inliers;
        cost += std::min(r, 1.0);
      }
      if (cost < best_cost) {
        best_cost = cost;
        best_line = hypothesis;
        done = inliers == valid;
      }
    }
  }
  if (!std::isfinite(best_cost)) return std::nullopt;
  return best_line;
}

/// A line fitted to depth samples, with its inlier flags and count.
struct LineFit {
  Line3 line;
  std::vector<char> inlier;
  int inliers = 0;
};

/// Refits `initial` on its inliers by PCA, then once more on the inliers of the refined line.
/// Nothing when a PCA fails.
std::optional<LineFit> refine_line(const Line3& initial, const DepthSamples& samples) {
  const std::vector<Eigen::Vector3d>& points = samples.points;
  LineFit fit{initial, std::vector<char>(points.size(), 0), 0};
  fit.inliers = mark_inliers(fit.line, points, samples.tolerance2, fit.inlier);
  for (int iteration = 0; iteration < 2; ++iteration) {
    Line3 refined;
    if (!pca_line(points, fit.inlier, refined)) return std::nullopt;
    std::vector<char> next(points.size(), 0);
    const int count = mark_inliers(refined, points, samples.tolerance2, next);
    // Keep the refined line unless it lost inliers (the PCA can drift on a two-layer set).
    if (count < fit.inliers) break;
    fit.line = refined;
    const bool same = next == fit.inlier;
    fit.inlier.swap(next);
    fit.inliers = count;
    if (same) break;
  }
  return fit;
}

/// The 3D endpoints of the segment s-e on the fitted line: where the viewing rays of the 2D
/// endpoints pass closest to the 3D line, taken on the rays so that they project exactly onto
/// the 2D endpoints. False when a ray misses the line or is nearly parallel to it.
bool line_endpoints(const PinholeCamera& camera, const Eigen::Vector2d& s, const Eigen::Vector2d& e,
                    const LineFit& fit, const DepthSamples& samples, LineFeature& line) {
  double max_tol2 = 0.0;
  for (std::size_t k = 0; k < samples.points.size(); ++k)
    if (fit.inlier[k]) max_tol2 = std::max(max_tol2, samples.tolerance2[k]);
  const double max_miss = 2.0 * std::sqrt(max_tol2);
  const double min_sin = std::sin(kMinRayAngleDeg * std::numbers::pi / 180.0);
  const auto start_c = ray_line_point(camera.unproject(s, 1.0), fit.line, min_sin, max_miss);
  const auto end_c = ray_line_point(camera.unproject(e, 1.0), fit.line, min_sin, max_miss);
  if (!start_c || !end_c) return false;
  line.start_c = *start_c;
  line.end_c = *end_c;
  return true;
}

}  // namespace

const cv::Mat* LineExtractor::Impl::detect(const cv::Mat& gray, const cv::Size& size) {
  // The scratch buffer never refers to the caller's image (a later resize would write into it).
  const bool rescale = size != gray.size();
  try {
    if (rescale) cv::resize(gray, scaled, size, 0.0, 0.0, cv::INTER_AREA);
    const cv::Mat& image = rescale ? scaled : gray;
    segments.clear();
    if (fld)
      fld->detect(image, segments);
    else if (region)
      region->detect(image, segments);
    else
      lsd->detect(image, segments);
    return &image;
  } catch (const cv::Exception&) {
    return nullptr;
  }
}

std::vector<LineFeature> LineExtractor::extract(const cv::Mat& gray) const {
  std::vector<LineFeature> result;
  if (gray.empty() || gray.type() != CV_8UC1 || gray.dims != 2) return result;
  Impl& impl = *impl_;
  const double scale = options_.detection_scale;
  const cv::Size size(std::max(1, static_cast<int>(std::lround(gray.cols * scale))),
                      std::max(1, static_cast<int>(std::lround(gray.rows * scale))));
  // The detectors need a few pixels for their gradients.
  if (size.width < 8 || size.height < 8) return result;
  if (size.width > kMaxDetectionImageSide || size.height > kMaxDetectionImageSide) return result;
  const cv::Mat* image = impl.detect(gray, size);
  if (image == nullptr) return result;

  const DetectionScale map{static_cast<double>(size.width) / gray.cols,
                           static_cast<double>(size.height) / gray.rows};
  std::vector<Candidate> candidates = longest_segments(impl.segments, map, gray.size(), options_);
  if (candidates.empty()) return result;
  if (impl.fld) refine_fld_candidates(*image, impl.segments, map, gray.size(), candidates);

  // LBD on the detection image, where the segments were found (so its 9 bands of 7 pixels are
  // detection-image pixels, 63 across: about 30 cm at 1 m in freiburg1's camera at 0.4), from
  // one gradient image (line_band_descriptor.hpp). The direction start -> end is the detector's:
  // each detector orients a segment by its gradient's polarity, so the descriptor (which depends
  // on it) is comparable between views.
  if (!impl.lbd.set_image(*image)) return result;
  result.reserve(candidates.size());
  for (const Candidate& c : candidates) {
    LineFeature f;
    f.start = c.start.cast<float>();
    f.end = c.end.cast<float>();
    f.descriptor = impl.lbd.describe(map.to_scaled(c.start), map.to_scaled(c.end));
    result.push_back(f);
  }
  return result;
}

bool LineExtractor::fit_depth(const PinholeCamera& camera, const cv::Mat& depth,
                              LineFeature& line) const {
  line.has_depth = false;
  if (depth.empty() || depth.type() != CV_32FC1 || depth.dims != 2) return false;
  if (depth.cols != camera.width || depth.rows != camera.height) return false;
  if (!(camera.fx > 0.0) || !(camera.fy > 0.0) || !std::isfinite(camera.cx) ||
      !std::isfinite(camera.cy))
    return false;
  const Eigen::Vector2d s = line.start.cast<double>();
  const Eigen::Vector2d e = line.end.cast<double>();
  if (!s.allFinite() || !e.allFinite()) return false;
  const Eigen::Vector2d d = e - s;
  const double length = d.norm();
  if (!(length >= 1.0)) return false;
  const Eigen::Vector2d normal(-d.y() / length, d.x() / length);

  const DepthSamples samples = sample_segment(camera, depth, s, d, normal, options_);
  const int valid = static_cast<int>(samples.points.size());
  if (valid < 3 || valid < options_.min_valid_fraction * options_.depth_samples) return false;
  const std::optional<Line3> initial = ransac_line(samples);
  if (!initial) return false;
  const std::optional<LineFit> fit = refine_line(*initial, samples);
  if (!fit) return false;
  if (fit->inliers < 2 || fit->inliers < options_.min_inlier_fraction * valid) return false;
  if (!line_endpoints(camera, s, e, *fit, samples, line)) return false;
  line.has_depth = true;
  return true;
}

}  // namespace mcslam::features
