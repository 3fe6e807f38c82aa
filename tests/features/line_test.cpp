#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "mcslam/core/error.hpp"
#include "mcslam/features/lines.hpp"
#include "mcslam/synth/renderer.hpp"
#include "mcslam/synth/sequence.hpp"
#include "support/low_texture_sequence.hpp"

namespace mcslam::features {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
// Rendered views spread over the camera path (boxes, the table, room corners in sight).
constexpr int kViews[] = {0, 60, 120, 200, 260};

const synth::SyntheticSequence& sequence() { return test::low_texture_sequence(); }

cv::Mat to_gray(const cv::Mat& bgr) {
  cv::Mat gray;
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  return gray;
}

struct Segment3 {
  Eigen::Vector3d a;
  Eigen::Vector3d b;
};

/// Every straight geometric edge of the scene (world frame): the room's 12 and each box's 12.
std::vector<Segment3> true_edges(const synth::Scene& scene, double t) {
  std::vector<Eigen::Vector3d> room;
  for (int k = 0; k < 8; ++k) {
    room.emplace_back((k & 1) ? scene.room_max.x() : scene.room_min.x(),
                      (k & 2) ? scene.room_max.y() : scene.room_min.y(),
                      (k & 4) ? scene.room_max.z() : scene.room_min.z());
  }
  std::vector<std::vector<Eigen::Vector3d>> boxes{room};
  for (const synth::SceneObject& object : scene.objects) boxes.push_back(object.corners_at(t));
  std::vector<Segment3> edges;
  for (const auto& corners : boxes) {
    // corners_at numbers corner k by the sign bits of x (1), y (2), z (4): edges join corners
    // that differ in one bit.
    for (int k = 0; k < 8; ++k) {
      for (int bit : {1, 2, 4}) {
        if (k & bit) continue;
        edges.push_back(
            {corners[static_cast<std::size_t>(k)], corners[static_cast<std::size_t>(k | bit)]});
      }
    }
  }
  return edges;
}

/// The part of a camera-frame segment in front of the camera (z >= 0.05), projected.
std::optional<std::pair<Eigen::Vector2d, Eigen::Vector2d>> project_segment(
    const PinholeCamera& camera, Eigen::Vector3d a, Eigen::Vector3d b) {
  constexpr double kNear = 0.05;
  if (a.z() < kNear && b.z() < kNear) return std::nullopt;
  if (a.z() < kNear) a = a + (kNear - a.z()) / (b.z() - a.z()) * (b - a);
  if (b.z() < kNear) b = b + (kNear - b.z()) / (a.z() - b.z()) * (a - b);
  return std::make_pair(camera.project(a), camera.project(b));
}

double point_segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                              const Eigen::Vector2d& b) {
  const Eigen::Vector2d d = b - a;
  const double t = std::clamp((p - a).dot(d) / std::max(d.squaredNorm(), 1e-12), 0.0, 1.0);
  return (p - (a + t * d)).norm();
}

double point_line_distance(const Eigen::Vector3d& p, const Segment3& line) {
  const Eigen::Vector3d d = (line.b - line.a).normalized();
  const Eigen::Vector3d v = p - line.a;
  return (v - v.dot(d) * d).norm();
}

/// Whether a segment lies on a geometric edge of the rendered view (an occluding contour or a
/// crease) rather than on a texture edge of a flat surface, from the exact depth and labels on
/// both sides of it.
bool on_geometric_edge(const LineFeature& line, const synth::RenderedFrame& frame,
                       const PinholeCamera& camera) {
  const Eigen::Vector2d s = line.start.cast<double>();
  const Eigen::Vector2d e = line.end.cast<double>();
  const Eigen::Vector2d d = (e - s).normalized();
  const Eigen::Vector2d n(-d.y(), d.x());
  auto point_at = [&](const Eigen::Vector2d& uv, int* label) -> std::optional<Eigen::Vector3d> {
    const int x = static_cast<int>(std::lround(uv.x()));
    const int y = static_cast<int>(std::lround(uv.y()));
    if (x < 0 || y < 0 || x >= frame.depth.cols || y >= frame.depth.rows) return std::nullopt;
    if (label) *label = frame.labels.at<std::int16_t>(y, x);
    return camera.unproject(uv, frame.depth.at<float>(y, x));
  };
  int geometric = 0;
  int samples = 0;
  for (int k = 1; k <= 9; ++k) {
    const Eigen::Vector2d uv = s + (k / 10.0) * (e - s);
    int label_minus = 0;
    int label_plus = 0;
    const auto p0 = point_at(uv, nullptr);
    const auto pm = point_at(uv - 4.0 * n, &label_minus);
    const auto pp = point_at(uv + 4.0 * n, &label_plus);
    if (!p0 || !pm || !pp) continue;
    ++samples;
    if (label_minus != label_plus) {
      ++geometric;
      continue;
    }
    // Flat: the point on the segment lies on the chord between its two neighbours.
    const Segment3 chord{*pm, *pp};
    if (point_line_distance(*p0, chord) > 0.005 || ((*pp - *pm).norm() > 0.2)) ++geometric;
  }
  return samples > 0 && 2 * geometric >= samples;
}

struct EdgeMatch {
  int edge = -1;
  double image_distance = std::numeric_limits<double>::infinity();
};

/// The true edges whose projection passes within `tolerance` px of both endpoints of `line`.
std::vector<EdgeMatch> nearby_edges(const LineFeature& line, const std::vector<Segment3>& edges,
                                    const SE3& T_c_w, const PinholeCamera& camera,
                                    double tolerance) {
  std::vector<EdgeMatch> result;
  for (std::size_t i = 0; i < edges.size(); ++i) {
    const auto projected = project_segment(camera, T_c_w * edges[i].a, T_c_w * edges[i].b);
    if (!projected) continue;
    const double ds =
        point_segment_distance(line.start.cast<double>(), projected->first, projected->second);
    const double de =
        point_segment_distance(line.end.cast<double>(), projected->first, projected->second);
    const double worst = std::max(ds, de);
    if (worst <= tolerance) result.push_back({static_cast<int>(i), worst});
  }
  return result;
}

TEST(LineOptions, DefaultsAreValid) { EXPECT_FALSE(LineOptions{}.check().has_value()); }

TEST(LineOptions, CheckNamesTheBadField) {
  struct Case {
    std::string field;
    LineOptions options;
  };
  std::vector<Case> cases;
  auto add = [&](const std::string& field, auto mutate) {
    LineOptions o;
    mutate(o);
    cases.push_back({field, o});
  };
  add("min_length", [](LineOptions& o) { o.min_length = -1.0; });
  add("min_length", [](LineOptions& o) { o.min_length = std::nan(""); });
  add("max_lines", [](LineOptions& o) { o.max_lines = 0; });
  add("detector", [](LineOptions& o) { o.detector = "hough"; });
  add("detection_scale", [](LineOptions& o) { o.detection_scale = 0.0; });
  add("detection_scale", [](LineOptions& o) { o.detection_scale = 1.5; });
  add("depth_samples", [](LineOptions& o) { o.depth_samples = 2; });
  add("min_valid_fraction", [](LineOptions& o) { o.min_valid_fraction = 0.0; });
  add("min_valid_fraction", [](LineOptions& o) { o.min_valid_fraction = 1.1; });
  add("fit_tolerance", [](LineOptions& o) { o.fit_tolerance = 0.0; });
  add("fit_tolerance_per_metre", [](LineOptions& o) { o.fit_tolerance_per_metre = -0.1; });
  add("min_inlier_fraction", [](LineOptions& o) { o.min_inlier_fraction = 0.0; });
  add("min_inlier_fraction",
      [](LineOptions& o) { o.min_inlier_fraction = std::numeric_limits<double>::infinity(); });
  for (const Case& c : cases) {
    const auto problem = c.options.check();
    ASSERT_TRUE(problem.has_value()) << c.field;
    EXPECT_NE(problem->find("lines." + c.field), std::string::npos) << *problem;
    try {
      LineExtractor extractor(c.options);
      ADD_FAILURE() << "no throw for " << c.field;
    } catch (const InputError& error) {
      EXPECT_NE(std::string(error.what()).find(c.field), std::string::npos) << error.what();
    }
  }
}

TEST(LineFeature, CoefficientsAreNormalisedSignedDistances) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> coord(-50.0f, 700.0f);
  for (int k = 0; k < 100; ++k) {
    LineFeature line;
    line.start = {coord(rng), coord(rng)};
    line.end = {coord(rng), coord(rng)};
    if (line.length() < 1.0f) continue;
    const Eigen::Vector3d l = line.coefficients();
    EXPECT_NEAR(l.head<2>().norm(), 1.0, 1e-12);
    const Eigen::Vector2d s = line.start.cast<double>();
    const Eigen::Vector2d e = line.end.cast<double>();
    EXPECT_NEAR(l.dot(s.homogeneous()), 0.0, 1e-9);
    EXPECT_NEAR(l.dot(e.homogeneous()), 0.0, 1e-9);
    // Sign convention: (a, b) is the direction end - start turned by +90 degrees, (-dy, dx).
    const Eigen::Vector2d d = (e - s).normalized();
    const Eigen::Vector2d normal(-d.y(), d.x());
    EXPECT_NEAR((l.head<2>() - normal).norm(), 0.0, 1e-9);
    const Eigen::Vector2d p = 0.5 * (s + e) + 7.5 * normal + 20.0 * d;
    EXPECT_NEAR(l.dot(p.homogeneous()), 7.5, 1e-9);
  }
  LineFeature horizontal;
  horizontal.start = {10.0f, 20.0f};
  horizontal.end = {110.0f, 20.0f};
  EXPECT_TRUE(horizontal.coefficients().isApprox(Eigen::Vector3d(0.0, 1.0, -20.0)));
  // Reversing the segment flips the sign.
  std::swap(horizontal.start, horizontal.end);
  EXPECT_TRUE(horizontal.coefficients().isApprox(Eigen::Vector3d(0.0, -1.0, 20.0)));
}

TEST(LineExtractor, WrongInputGivesNoLines) {
  const LineExtractor extractor{LineOptions{}};
  const cv::Mat colour(480, 640, CV_8UC3, cv::Scalar(10, 20, 30));
  cv::rectangle(colour, cv::Rect(100, 100, 200, 150), cv::Scalar(200, 200, 200), cv::FILLED);
  EXPECT_TRUE(extractor.extract(colour).empty());
  EXPECT_TRUE(extractor.extract(cv::Mat()).empty());
  cv::Mat as_float;
  to_gray(colour).convertTo(as_float, CV_32F);
  EXPECT_TRUE(extractor.extract(as_float).empty());
  EXPECT_TRUE(extractor.extract(cv::Mat(3, 3, CV_8UC1, cv::Scalar(0))).empty());
  // Sanity: the same picture in grey does have lines.
  EXPECT_FALSE(extractor.extract(to_gray(colour)).empty());
}

TEST(LineExtractor, FitDepthRejectsBadDepthImages) {
  const LineExtractor extractor{LineOptions{}};
  PinholeCamera camera = sequence().camera();
  LineFeature line;
  line.start = {100.0f, 100.0f};
  line.end = {300.0f, 120.0f};
  const cv::Mat metres(camera.height, camera.width, CV_32FC1, cv::Scalar(2.0));
  EXPECT_TRUE(extractor.fit_depth(camera, metres, line));
  EXPECT_TRUE(line.has_depth);
  const cv::Mat raw(camera.height, camera.width, CV_16UC1, cv::Scalar(10000));
  EXPECT_FALSE(extractor.fit_depth(camera, raw, line));
  EXPECT_FALSE(line.has_depth);
  EXPECT_FALSE(extractor.fit_depth(camera, cv::Mat(), line));
  const cv::Mat small(camera.height / 2, camera.width / 2, CV_32FC1, cv::Scalar(2.0));
  EXPECT_FALSE(extractor.fit_depth(camera, small, line));
  const cv::Mat missing(camera.height, camera.width, CV_32FC1, cv::Scalar(0.0));
  EXPECT_FALSE(extractor.fit_depth(camera, missing, line));
  const cv::Mat nan(camera.height, camera.width, CV_32FC1,
                    cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  EXPECT_FALSE(extractor.fit_depth(camera, nan, line));
  LineFeature degenerate;
  degenerate.start = degenerate.end = {200.0f, 200.0f};
  EXPECT_FALSE(extractor.fit_depth(camera, metres, degenerate));
}

TEST(LineExtractor, RectangleEdgesAtSubpixelPositions) {
  // A bright rectangle covering columns 100..299 and rows 120..299: its edges lie on the pixel
  // boundaries x = 99.5, x = 299.5, y = 119.5, y = 299.5 (pixel-centre coordinates).
  cv::Mat gray(480, 640, CV_8UC1, cv::Scalar(60));
  gray(cv::Rect(100, 120, 200, 180)).setTo(180);
  for (const char* detector : {"lsd", "fld", "region"})
    for (double scale : {0.4, 0.5, 1.0}) {
      SCOPED_TRACE(detector);
      LineOptions options;
      options.detector = detector;
      options.detection_scale = scale;
      const LineExtractor extractor(options);
      const std::vector<LineFeature> lines = extractor.extract(gray);
      ASSERT_GE(lines.size(), 4u) << scale;
      // LSD fits its segments to the gradient field (sub-pixel); FLD to Canny's edge pixels, which
      // lie on one side of a step edge (half a pixel of the detection image off, 1.25 px at
      // scale 0.4) until the extractor moves them onto the step.
      const float tolerance = 0.5f;
      int vertical = 0;
      int horizontal = 0;
      for (const LineFeature& line : lines) {
        const Eigen::Vector2f d = line.end - line.start;
        if (std::abs(d.x()) < 0.02f * line.length()) {
          ++vertical;
          const float x = 0.5f * (line.start.x() + line.end.x());
          EXPECT_LT(std::min(std::abs(x - 99.5f), std::abs(x - 299.5f)), tolerance) << scale;
        } else if (std::abs(d.y()) < 0.02f * line.length()) {
          ++horizontal;
          const float y = 0.5f * (line.start.y() + line.end.y());
          EXPECT_LT(std::min(std::abs(y - 119.5f), std::abs(y - 299.5f)), tolerance) << scale;
        } else {
          ADD_FAILURE() << "oblique segment at scale " << scale;
        }
        EXPECT_GT(line.length(), 150.0f);
      }
      EXPECT_GE(vertical, 2);
      EXPECT_GE(horizontal, 2);
    }
}

TEST(LineExtractor, LongestFirstWithinLimitsAndDeterministic) {
  const synth::RenderedFrame frame = sequence().frame(kViews[0]);
  const cv::Mat gray = to_gray(frame.rgb);
  LineOptions options;
  options.min_length = 30.0;
  options.max_lines = 10;
  const LineExtractor extractor(options);
  const std::vector<LineFeature> lines = extractor.extract(gray);
  ASSERT_EQ(lines.size(), 10u);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    EXPECT_GE(lines[i].length(), 30.0f);
    if (i > 0) {
      EXPECT_GE(lines[i - 1].length(), lines[i].length());
    }
    EXPECT_FALSE(lines[i].has_depth);
    EXPECT_TRUE(lines[i].start.x() >= 0.0f && lines[i].start.x() <= 639.0f);
    EXPECT_TRUE(lines[i].end.y() >= 0.0f && lines[i].end.y() <= 479.0f);
  }
  const std::vector<LineFeature> again = extractor.extract(gray);
  ASSERT_EQ(again.size(), lines.size());
  for (std::size_t i = 0; i < lines.size(); ++i) {
    EXPECT_EQ(again[i].start, lines[i].start);
    EXPECT_EQ(again[i].end, lines[i].end);
    EXPECT_EQ(again[i].descriptor, lines[i].descriptor);
  }
  // A fresh extractor gives the same lines, and the longest lines do not depend on max_lines.
  options.max_lines = 80;
  const std::vector<LineFeature> more = LineExtractor(options).extract(gray);
  ASSERT_GE(more.size(), lines.size());
  for (std::size_t i = 0; i < lines.size(); ++i) {
    EXPECT_EQ(more[i].start, lines[i].start);
    EXPECT_EQ(more[i].descriptor, lines[i].descriptor);
  }
}

// Long segments on geometric edges (occluding contours, creases) run along projected true edges
// of the room and the boxes; texture edges (posters, the rug) are told apart with the exact depth.
TEST(LineExtractor, SegmentsFollowTrueEdges) {
  const synth::SyntheticSequence& seq = sequence();
  const PinholeCamera camera = seq.camera();
  const LineExtractor extractor{LineOptions{}};
  int on_edges = 0;
  for (int view : kViews) {
    const synth::RenderedFrame frame = seq.frame(view);
    const SE3 T_c_w = seq.T_w_c(view).inverse();
    const std::vector<Segment3> edges = true_edges(seq.scene(), seq.time(view));
    std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> projected;
    for (const Segment3& edge : edges) {
      if (const auto p = project_segment(camera, T_c_w * edge.a, T_c_w * edge.b)) {
        projected.push_back(*p);
      }
    }
    const std::vector<LineFeature> lines = extractor.extract(to_gray(frame.rgb));
    int view_on_edges = 0;
    for (const LineFeature& line : lines) {
      if (line.length() < 40.0f || !on_geometric_edge(line, frame, camera)) continue;
      // LSD may join two edges that are collinear in the image (e.g. a box's vertical edge and
      // the side edge of its top face): every point of the segment must be on some true edge.
      bool covered = true;
      for (int k = 0; k <= 10 && covered; ++k) {
        const Eigen::Vector2d p =
            (line.start + (k / 10.0f) * (line.end - line.start)).cast<double>();
        covered = std::any_of(projected.begin(), projected.end(), [&](const auto& edge) {
          return point_segment_distance(p, edge.first, edge.second) <= 3.0;
        });
      }
      EXPECT_TRUE(covered) << "view " << view << ": segment (" << line.start.transpose() << ") - ("
                           << line.end.transpose() << ") off the true edges";
      if (covered) ++view_on_edges;
    }
    EXPECT_GE(view_on_edges, 5) << "view " << view;
    on_edges += view_on_edges;
  }
  EXPECT_GE(on_edges, 40);
}

/// Runs fit_depth on the segments near true edges and checks the 3D endpoints against them;
/// returns {segments near an edge, of which fitted, fitted within tolerance}.
std::array<int, 3> check_fits_on_edges(bool noisy_depth, double min_tolerance,
                                       double tolerance_per_metre) {
  const synth::SyntheticSequence& seq = sequence();
  const PinholeCamera camera = seq.camera();
  const LineExtractor extractor{LineOptions{}};
  std::array<int, 3> counts{0, 0, 0};
  for (int view : kViews) {
    const synth::RenderedFrame frame = seq.frame(view);
    const cv::Mat depth =
        noisy_depth ? synth::apply_kinect_depth_noise(frame.depth, 1000 + view) : frame.depth;
    const SE3& T_w_c = seq.T_w_c(view);
    const SE3 T_c_w = T_w_c.inverse();
    const std::vector<Segment3> edges = true_edges(seq.scene(), seq.time(view));
    for (LineFeature line : extractor.extract(to_gray(frame.rgb))) {
      const auto near = nearby_edges(line, edges, T_c_w, camera, 3.0);
      if (near.empty() || line.length() < 40.0f) continue;
      ++counts[0];
      if (!extractor.fit_depth(camera, depth, line)) continue;
      ++counts[1];
      EXPECT_TRUE(line.has_depth);
      // The endpoints project back onto the 2D endpoints.
      EXPECT_LT((camera.project(line.start_c) - line.start.cast<double>()).norm(), 1e-6);
      EXPECT_LT((camera.project(line.end_c) - line.end.cast<double>()).norm(), 1e-6);
      // Several edges can project near the segment (e.g. a hidden back edge behind a contour):
      // the fit must lie on one of them.
      double best = std::numeric_limits<double>::infinity();
      for (const EdgeMatch& m : near) {
        const Segment3& edge = edges[static_cast<std::size_t>(m.edge)];
        best = std::min(best, std::max(point_line_distance(T_w_c * line.start_c, edge),
                                       point_line_distance(T_w_c * line.end_c, edge)));
      }
      const double z = std::max(line.start_c.z(), line.end_c.z());
      const double tolerance = std::max(min_tolerance, tolerance_per_metre * z * z);
      EXPECT_LT(best, tolerance) << "view " << view << " segment (" << line.start.transpose()
                                 << ") - (" << line.end.transpose() << ")";
      if (best < tolerance) ++counts[2];
    }
  }
  return counts;
}

TEST(LineExtractor, DepthEndpointsOnTrueEdgesExactDepth) {
  const auto [near, fitted, accurate] = check_fits_on_edges(false, 0.015, 0.0);
  EXPECT_GE(near, 40);
  EXPECT_GE(fitted, 0.8 * near);
  EXPECT_EQ(accurate, fitted);
}

TEST(LineExtractor, DepthEndpointsOnTrueEdgesKinectDepth) {
  const auto [near, fitted, accurate] = check_fits_on_edges(true, 0.025, 0.005);
  EXPECT_GE(near, 40);
  EXPECT_GE(fitted, 0.7 * near);
  EXPECT_EQ(accurate, fitted);
}

TEST(LineExtractor, DepthDiscontinuity) {
  const LineExtractor extractor{LineOptions{}};
  const PinholeCamera camera = sequence().camera();
  // Columns < 320 at 1 m, the rest at 2 m: the step lies on the boundary x = 319.5.
  cv::Mat depth(camera.height, camera.width, CV_32FC1, cv::Scalar(2.0));
  depth.colRange(0, 320).setTo(1.0);

  // Half the samples on each layer: no single 3D line.
  LineFeature across;
  across.start = {200.0f, 240.0f};
  across.end = {440.0f, 250.0f};
  EXPECT_FALSE(extractor.fit_depth(camera, depth, across));
  EXPECT_FALSE(across.has_depth);

  // Mostly on the near layer: fitted to that layer, the far samples being outliers.
  LineFeature mostly_near;
  mostly_near.start = {100.0f, 200.0f};
  mostly_near.end = {350.0f, 200.0f};
  ASSERT_TRUE(extractor.fit_depth(camera, depth, mostly_near));
  EXPECT_NEAR(mostly_near.start_c.z(), 1.0, 1e-3);
  EXPECT_NEAR(mostly_near.end_c.z(), 1.0, 1e-3);

  // Along the contour (and a pixel off it either way), with and without the Kinect-like hole
  // on both sides of the jump: always the occluding (near) side.
  cv::Mat holes = depth.clone();
  holes.colRange(319, 321).setTo(0.0);
  for (const cv::Mat& d : {depth, holes}) {
    for (float x : {318.6f, 319.5f, 320.4f}) {
      LineFeature contour;
      contour.start = {x, 60.0f};
      contour.end = {x + 0.3f, 420.0f};
      ASSERT_TRUE(extractor.fit_depth(camera, d, contour)) << x;
      EXPECT_NEAR(contour.start_c.z(), 1.0, 1e-3) << x;
      EXPECT_NEAR(contour.end_c.z(), 1.0, 1e-3) << x;
    }
  }
}

TEST(LineExtractor, DepthSlantedPlaneAndInvalidFraction) {
  const LineExtractor extractor{LineOptions{}};
  const PinholeCamera camera = sequence().camera();
  // The plane n . p = 2 (slanted about both image axes): z = 2 / (n . K^-1 (u, v, 1)).
  const Eigen::Vector3d n = Eigen::Vector3d(0.5, 0.2, 1.0).normalized();
  auto plane_depth = [&](const Eigen::Vector2d& uv) {
    return 2.0 / n.dot(camera.unproject(uv, 1.0));
  };
  cv::Mat depth(camera.height, camera.width, CV_32FC1);
  for (int v = 0; v < depth.rows; ++v)
    for (int u = 0; u < depth.cols; ++u)
      depth.at<float>(v, u) = static_cast<float>(plane_depth(Eigen::Vector2d(u, v)));
  LineFeature line;
  line.start = {150.0f, 100.0f};
  line.end = {480.0f, 380.0f};
  ASSERT_TRUE(extractor.fit_depth(camera, depth, line));
  EXPECT_NEAR(line.start_c.z(), plane_depth(line.start.cast<double>()), 0.002);
  EXPECT_NEAR(line.end_c.z(), plane_depth(line.end.cast<double>()), 0.002);
  EXPECT_NEAR(n.dot(line.start_c), 2.0, 0.002);
  EXPECT_NEAR(n.dot(line.end_c), 2.0, 0.002);

  // Missing depth on most of the segment.
  cv::Mat missing = depth.clone();
  missing.colRange(200, 640).setTo(0.0);
  LineFeature sparse = line;
  EXPECT_FALSE(extractor.fit_depth(camera, missing, sparse));
}

/// A depth image holding, around the projection of the 3D segment p0 + mu dir (mu in [0, 2]),
/// the depth of the segment point seen at the foot of each pixel on the 2D line; 0 elsewhere.
cv::Mat depth_of_3d_line(const PinholeCamera& camera, const Eigen::Vector3d& p0,
                         const Eigen::Vector3d& dir, LineFeature& line) {
  const Eigen::Vector2d a = camera.project(p0);
  const Eigen::Vector2d b = camera.project(p0 + 2.0 * dir);
  line.start = a.cast<float>();
  line.end = b.cast<float>();
  cv::Mat depth(camera.height, camera.width, CV_32FC1, cv::Scalar(0.0));
  const Eigen::Vector2d d = (b - a).normalized();
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) {
      const Eigen::Vector2d uv(u, v);
      const double t = (uv - a).dot(d);
      if ((uv - a - t * d).norm() > 4.0 || t < -5.0 || t > (b - a).norm() + 5.0) continue;
      // The 3D point on the line seen at the foot a + t d (closest point of its ray).
      const Eigen::Vector3d r = camera.unproject(a + t * d, 1.0).normalized();
      const double rd = r.dot(dir);
      const double mu = (rd * r.dot(p0) - dir.dot(p0)) / (1.0 - rd * rd);
      depth.at<float>(v, u) = static_cast<float>((p0 + mu * dir).z());
    }
  }
  return depth;
}

TEST(LineExtractor, RejectsLinesAlongViewingRays) {
  const LineExtractor extractor{LineOptions{}};
  const PinholeCamera camera = sequence().camera();
  const Eigen::Vector3d p0(0.2, 0.1, 1.0);
  const Eigen::Vector3d ray = p0.normalized();
  const Eigen::Vector3d side = ray.cross(Eigen::Vector3d::UnitY()).normalized();
  for (double angle : {3.0, 30.0}) {
    // A 3D line through p0 at `angle` to its viewing ray.
    const Eigen::Vector3d dir = (std::cos(angle * kDeg) * ray + std::sin(angle * kDeg) * side);
    LineFeature line;
    const cv::Mat depth = depth_of_3d_line(camera, p0, dir, line);
    ASSERT_GT(line.length(), 10.0f);
    EXPECT_EQ(extractor.fit_depth(camera, depth, line), angle > 10.0) << angle;
    if (line.has_depth) {
      EXPECT_LT((line.start_c - p0).norm(), 0.01);
      EXPECT_LT((line.end_c - (p0 + 2.0 * dir)).norm(), 0.03);
    }
  }
}

TEST(LineGeometry, EachTestFailsAlone) {
  LineMatchCriteria criteria;  // 10 deg, 20 px, overlap 0.3
  LineFeature observed;
  observed.start = {100.0f, 200.0f};
  observed.end = {200.0f, 200.0f};
  PredictedLine base;
  base.start = {105.0, 203.0};
  base.end = {195.0, 205.0};
  EXPECT_TRUE(line_geometry_consistent(base, observed, criteria));
  // Undirected: a reversed prediction is the same line.
  PredictedLine reversed = base;
  std::swap(reversed.start, reversed.end);
  EXPECT_TRUE(line_geometry_consistent(reversed, observed, criteria));

  // Rotated by 15 deg about its midpoint: endpoint distances ~12 px, overlap ~97%.
  auto rotate = [](const PredictedLine& line, double deg) {
    const Eigen::Vector2d m = 0.5 * (line.start + line.end);
    const Eigen::Rotation2Dd r(deg * kDeg);
    PredictedLine out = line;
    out.start = m + r * (line.start - m);
    out.end = m + r * (line.end - m);
    return out;
  };
  EXPECT_FALSE(line_geometry_consistent(rotate(base, 15.0), observed, criteria));
  EXPECT_TRUE(line_geometry_consistent(rotate(base, 8.0), observed, criteria));
  criteria.max_angle_deg = 20.0;
  EXPECT_TRUE(line_geometry_consistent(rotate(base, 15.0), observed, criteria));
  criteria = LineMatchCriteria{};

  // Parallel, 25 px away.
  PredictedLine far = base;
  far.start.y() += 22.0;
  far.end.y() += 22.0;
  EXPECT_FALSE(line_geometry_consistent(far, observed, criteria));
  criteria.max_distance = 30.0;
  EXPECT_TRUE(line_geometry_consistent(far, observed, criteria));
  criteria = LineMatchCriteria{};

  // Slid along the line: 20 px of overlap for the shorter (90 px) segment.
  PredictedLine slid = base;
  slid.start.x() += 75.0;
  slid.end.x() += 75.0;
  EXPECT_FALSE(line_geometry_consistent(slid, observed, criteria));
  criteria.min_overlap = 0.2;
  EXPECT_TRUE(line_geometry_consistent(slid, observed, criteria));
  criteria = LineMatchCriteria{};
  // Overlap is relative to the shorter segment: a short prediction inside a long observation.
  PredictedLine inside;
  inside.start = {140.0, 201.0};
  inside.end = {160.0, 201.0};
  EXPECT_TRUE(line_geometry_consistent(inside, observed, criteria));
  // Disjoint.
  PredictedLine beyond = base;
  beyond.start.x() += 200.0;
  beyond.end.x() += 200.0;
  EXPECT_FALSE(line_geometry_consistent(beyond, observed, criteria));

  // Degenerate segments never match.
  PredictedLine point;
  point.start = point.end = {150.0, 200.0};
  EXPECT_FALSE(line_geometry_consistent(point, observed, criteria));
  LineFeature empty;
  empty.start = empty.end = {150.0f, 200.0f};
  EXPECT_FALSE(line_geometry_consistent(base, empty, criteria));
}

/// A descriptor with bits [first, first + count) set.
LineDescriptor bits(int first, int count) {
  LineDescriptor d;
  for (int b = first; b < first + count; ++b)
    d.bytes[static_cast<std::size_t>(b / 8)] |= static_cast<std::uint8_t>(1u << (b % 8));
  return d;
}

TEST(MatchLines, UniqueObservedAndDescriptorLimit) {
  const LineMatchCriteria criteria;  // max descriptor distance 80
  std::vector<LineFeature> observed(3);
  observed[0].start = {100.0f, 100.0f};
  observed[0].end = {300.0f, 100.0f};
  observed[0].descriptor = bits(0, 0);
  observed[1].start = {100.0f, 108.0f};  // parallel, 8 px below
  observed[1].end = {300.0f, 108.0f};
  observed[1].descriptor = bits(0, 100);
  observed[2].start = {400.0f, 300.0f};
  observed[2].end = {400.0f, 400.0f};
  observed[2].descriptor = bits(0, 0);

  std::vector<PredictedLine> predicted(4);
  // 0 and 1 are geometrically consistent with observed 0 and 1 and both prefer observed 0:
  // 1 is closer to it in descriptor (20 against 30 bits).
  predicted[0].start = {110.0, 102.0};
  predicted[0].end = {290.0, 103.0};
  predicted[0].descriptor = bits(100, 30);
  predicted[1].start = {110.0, 104.0};
  predicted[1].end = {290.0, 104.0};
  predicted[1].descriptor = bits(0, 20);
  // 2 matches observed 2 geometrically but its descriptor is too far.
  predicted[2].start = {402.0, 310.0};
  predicted[2].end = {401.0, 390.0};
  predicted[2].descriptor = bits(0, 81);
  // 3: nothing nearby.
  predicted[3].start = {600.0, 50.0};
  predicted[3].end = {620.0, 150.0};

  const std::vector<LineMatch> matches = match_lines(predicted, observed, criteria);
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].predicted, 1);
  EXPECT_EQ(matches[0].observed, 0);
  EXPECT_EQ(matches[0].distance, 20);

  // Observed 1 now closest to predicted 0 (5 bits), predicted 2 just within the limit.
  observed[1].descriptor = bits(100, 25);
  predicted[2].descriptor = bits(0, 80);
  const std::vector<LineMatch> more = match_lines(predicted, observed, criteria);
  ASSERT_EQ(more.size(), 3u);
  EXPECT_EQ(more[0].predicted, 0);
  EXPECT_EQ(more[0].observed, 1);
  EXPECT_EQ(more[0].distance, 5);
  EXPECT_EQ(more[1].predicted, 1);
  EXPECT_EQ(more[1].observed, 0);
  EXPECT_EQ(more[1].distance, 20);
  EXPECT_EQ(more[2].predicted, 2);
  EXPECT_EQ(more[2].observed, 2);
  EXPECT_EQ(more[2].distance, 80);

  // Ties in descriptor distance go to the lower predicted index.
  predicted[0].descriptor = bits(0, 30);
  predicted[1].descriptor = bits(0, 30);
  observed[1].descriptor = bits(0, 200);
  const std::vector<LineMatch> tie = match_lines(predicted, observed, criteria);
  ASSERT_EQ(tie.size(), 2u);
  EXPECT_EQ(tie[0].predicted, 0);
  EXPECT_EQ(tie[0].observed, 0);
  EXPECT_EQ(tie[1].predicted, 2);

  // Without the spatial bound (no overlap required) the result is the same here.
  LineMatchCriteria no_overlap = criteria;
  no_overlap.min_overlap = 0.0;
  const std::vector<LineMatch> unbounded = match_lines(predicted, observed, no_overlap);
  ASSERT_EQ(unbounded.size(), tie.size());
  for (std::size_t k = 0; k < tie.size(); ++k) {
    EXPECT_EQ(unbounded[k].predicted, tie[k].predicted);
    EXPECT_EQ(unbounded[k].observed, tie[k].observed);
  }

  EXPECT_TRUE(match_lines({}, observed, criteria).empty());
  EXPECT_TRUE(match_lines(predicted, {}, criteria).empty());
}

// Lines of one rendered frame, lifted to 3D and projected into a later frame with the true
// motion, find their own segments there.
void round_trip(const synth::SyntheticSequence& seq, std::initializer_list<int> views, int step,
                double min_matched, double min_correct, const LineOptions& options = {}) {
  const PinholeCamera camera = seq.camera();
  const LineExtractor extractor{options};
  int total_matches = 0;
  int total_correct = 0;
  int total_predicted = 0;
  for (int view : views) {
    const int next = view + step;
    const synth::RenderedFrame a = seq.frame(view);
    const synth::RenderedFrame b = seq.frame(next);
    std::vector<LineFeature> lines_a = extractor.extract(to_gray(a.rgb));
    const std::vector<LineFeature> lines_b = extractor.extract(to_gray(b.rgb));
    const SE3 T_b_a = seq.T_w_c(next).inverse() * seq.T_w_c(view);
    std::vector<PredictedLine> predicted;
    for (LineFeature& line : lines_a) {
      if (!extractor.fit_depth(camera, a.depth, line)) continue;
      const Eigen::Vector3d s = T_b_a * line.start_c;
      const Eigen::Vector3d e = T_b_a * line.end_c;
      if (s.z() <= 0.1 || e.z() <= 0.1) continue;
      predicted.push_back({camera.project(s), camera.project(e), line.descriptor});
    }
    total_predicted += static_cast<int>(predicted.size());
    const std::vector<LineMatch> matches = match_lines(predicted, lines_b, LineMatchCriteria{});
    std::vector<int> used(lines_b.size(), 0);
    for (std::size_t k = 0; k < matches.size(); ++k) {
      const LineMatch& m = matches[k];
      if (k > 0) {
        EXPECT_LT(matches[k - 1].predicted, m.predicted);
      }
      EXPECT_EQ(used[static_cast<std::size_t>(m.observed)]++, 0);
      EXPECT_LE(m.distance, LineMatchCriteria{}.max_descriptor_distance);
      // Correct: the observed segment lies on the predicted line (the prediction is exact up to
      // the endpoint fit).
      const PredictedLine& p = predicted[static_cast<std::size_t>(m.predicted)];
      LineFeature as_feature;
      as_feature.start = p.start.cast<float>();
      as_feature.end = p.end.cast<float>();
      const Eigen::Vector3d l = as_feature.coefficients();
      const LineFeature& o = lines_b[static_cast<std::size_t>(m.observed)];
      const double d = 0.5 * (std::abs(l.dot(o.start.cast<double>().homogeneous())) +
                              std::abs(l.dot(o.end.cast<double>().homogeneous())));
      if (d < 3.0) ++total_correct;
    }
    total_matches += static_cast<int>(matches.size());
  }
  EXPECT_GE(total_predicted, 30);
  EXPECT_GE(total_matches, min_matched * total_predicted);
  EXPECT_GE(total_correct, min_correct * total_matches);
}

TEST(MatchLines, RoundTripBetweenRenderedFrames) {
  round_trip(sequence(), {0, 120, 200}, 3, 0.7, 0.9);
}

TEST(MatchLines, RoundTripWithTheFastLineDetector) {
  // The same criteria as LSD's: FLD's segments are as matchable between views, and as correct.
  LineOptions fld;
  fld.detector = "fld";
  round_trip(sequence(), {0, 120, 200}, 3, 0.7, 0.9, fld);
}

TEST(MatchLines, RoundTripRichTexture) {
  synth::SynthOptions o;
  o.texture = synth::TextureLevel::kRich;
  const synth::SyntheticSequence rich(o);
  round_trip(rich, {0, 120, 200}, 3, 0.5, 0.9);
  round_trip(rich, {0, 120, 200}, 6, 0.5, 0.9);
}

}  // namespace
}  // namespace mcslam::features
