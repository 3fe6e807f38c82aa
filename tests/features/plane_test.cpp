#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "mcslam/core/error.hpp"
#include "mcslam/features/planes.hpp"
#include "mcslam/synth/renderer.hpp"
#include "mcslam/synth/sequence.hpp"
#include "support/low_texture_sequence.hpp"
#include "support/test_camera.hpp"

namespace mcslam::features {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
// Rendered views spread over the camera path (floor, walls, boxes and the table in sight).
constexpr int kViews[] = {0, 50, 100, 150, 200, 250};

/// A true planar surface of the scene in the camera frame of one view: a room surface or a box
/// face, normal towards the camera (d > 0).
struct TruePlane {
  std::string name;
  Eigen::Vector3d normal;
  double d = 0.0;
  int object = -1;  ///< index into Scene::objects, -1 for the room
};

struct View {
  int index = 0;
  synth::RenderedFrame frame;  ///< noise-free depth
  cv::Mat noisy_depth;         ///< the same depth made Kinect-like
  std::vector<TruePlane> truth;
  /// Per pixel (row-major): the index in truth of the surface the pixel sees, -1 for none.
  std::vector<int> surface;
  /// Visible pixels per true surface (valid in both depth images).
  std::vector<int> visible;
};

const synth::SyntheticSequence& sequence() { return test::low_texture_sequence(); }

TruePlane to_camera(const std::string& name, const Eigen::Vector3d& n_w, const Eigen::Vector3d& p_w,
                    const SE3& T_c_w, int object) {
  TruePlane plane;
  plane.name = name;
  plane.object = object;
  plane.normal = T_c_w.rotation() * n_w;
  plane.d = -plane.normal.dot(T_c_w * p_w);
  if (plane.d < 0.0) {
    plane.normal = -plane.normal;
    plane.d = -plane.d;
  }
  return plane;
}

std::vector<TruePlane> true_planes(const synth::Scene& scene, const SE3& T_w_c, double t) {
  const SE3 T_c_w = T_w_c.inverse();
  std::vector<TruePlane> planes;
  for (const synth::Surface& s : scene.surfaces)
    planes.push_back(to_camera(s.name, s.normal(), s.origin, T_c_w, -1));
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const synth::SceneObject& object = scene.objects[o];
    const SE3 T_w_o = object.pose_at(t);
    for (int f = 0; f < 6; ++f) {
      const int axis = f / 2;
      const double sign = f % 2 == 1 ? 1.0 : -1.0;
      const Eigen::Vector3d n_o = sign * Eigen::Vector3d::Unit(axis);
      const Eigen::Vector3d p_o = object.half_extents[axis] * n_o;
      planes.push_back(
          to_camera(object.class_name + std::to_string(o) + ".face" + std::to_string(f),
                    T_w_o.rotation() * n_o, T_w_o * p_o, T_c_w, static_cast<int>(o)));
    }
  }
  return planes;
}

Eigen::Vector3d point_at(const PinholeCamera& camera, const cv::Mat& depth, int u, int v) {
  return camera.unproject(Eigen::Vector2d(u, v), depth.at<float>(v, u));
}

const std::vector<View>& views() {
  static const std::vector<View> all = [] {
    const synth::SyntheticSequence& seq = sequence();
    const PinholeCamera camera = seq.camera();
    std::vector<View> out;
    for (int i : kViews) {
      View view;
      view.index = i;
      view.frame = seq.frame(i);
      view.noisy_depth = synth::apply_kinect_depth_noise(view.frame.depth, 1000 + i);
      view.truth = true_planes(seq.scene(), seq.T_w_c(i), seq.time(i));
      view.visible.assign(view.truth.size(), 0);
      view.surface.assign(static_cast<std::size_t>(camera.width * camera.height), -1);
      for (int v = 0; v < camera.height; ++v) {
        for (int u = 0; u < camera.width; ++u) {
          const Eigen::Vector3d p = point_at(camera, view.frame.depth, u, v);
          const int object = view.frame.labels.at<std::int16_t>(v, u);
          int best = -1;
          double best_distance = 1e-3;
          for (std::size_t j = 0; j < view.truth.size(); ++j) {
            if (view.truth[j].object != object) continue;
            const double distance = std::abs(view.truth[j].normal.dot(p) + view.truth[j].d);
            if (distance < best_distance) {
              best_distance = distance;
              best = static_cast<int>(j);
            }
          }
          view.surface[static_cast<std::size_t>(v * camera.width + u)] = best;
          if (best >= 0 && view.noisy_depth.at<float>(v, u) > 0.0f)
            ++view.visible[static_cast<std::size_t>(best)];
        }
      }
      out.push_back(std::move(view));
    }
    return out;
  }();
  return all;
}

/// The cell tolerance of the default PlaneOptions at depth z.
double cell_tolerance(double z) {
  const PlaneOptions o;
  return std::max(o.cell_tolerance, o.cell_tolerance_per_metre * z * z);
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) / kDeg;
}

/// Checks every extracted plane against the surface most of its pixels see (no spurious planes,
/// normal and distance accuracy), the labels against the planes, and that every big visible
/// surface was found (counted in big_surfaces, so that the check cannot pass vacuously).
/// min_within_1cm: the share of a plane's labelled pixels whose true point lies within 1 cm of
/// it (see the rendered-room tests).
void check_view(const View& view, const cv::Mat& depth, const PlaneExtraction& extraction,
                int& big_surfaces, double min_within_1cm = 0.98) {
  const PinholeCamera camera = sequence().camera();
  SCOPED_TRACE("view " + std::to_string(view.index));
  ASSERT_EQ(extraction.labels.type(), CV_8SC1);
  ASSERT_EQ(extraction.labels.size(), depth.size());
  const auto num_planes = extraction.planes.size();
  ASSERT_GE(num_planes, 1u);

  // Votes of each plane's pixels for the true surfaces.
  std::vector<std::map<int, int>> votes(num_planes);
  std::vector<int> labelled(num_planes, 0);
  std::vector<int> within_1cm(num_planes, 0);
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) {
      const int k = extraction.labels.at<std::int8_t>(v, u);
      ASSERT_GE(k, -1);
      ASSERT_LT(k, static_cast<int>(num_planes));
      if (k < 0) continue;
      ASSERT_GT(depth.at<float>(v, u), 0.0f) << "label on a pixel without depth";
      ++labelled[static_cast<std::size_t>(k)];
      ++votes[static_cast<std::size_t>(k)]
             [view.surface[static_cast<std::size_t>(v * depth.cols + u)]];
      // The pixel's point lies within the extractor's inlier band of its plane (at most 1.5 cell
      // tolerances with the default options, from the plane before its final fit), and its true
      // point is almost always within a centimetre.
      const PlaneFeature& plane = extraction.planes[static_cast<std::size_t>(k)];
      const Eigen::Vector3d measured = point_at(camera, depth, u, v);
      ASSERT_LT(std::abs(plane.distance(measured)), 0.01 + 1.5 * cell_tolerance(measured.z()))
          << "pixel " << u << "," << v << " plane " << k;
      const double distance = std::abs(plane.distance(point_at(camera, view.frame.depth, u, v)));
      if (distance < 0.01) ++within_1cm[static_cast<std::size_t>(k)];
    }
  }

  std::vector<int> found(view.truth.size(), 0);
  for (std::size_t k = 0; k < num_planes; ++k) {
    const PlaneFeature& plane = extraction.planes[k];
    SCOPED_TRACE("plane " + std::to_string(k));
    EXPECT_NEAR(plane.normal.norm(), 1.0, 1e-9);
    EXPECT_GT(plane.d, 0.0);
    EXPECT_EQ(plane.num_pixels, labelled[k]);
    EXPECT_GT(within_1cm[k], min_within_1cm * labelled[k]);
    if (k > 0) {
      EXPECT_LE(plane.num_pixels, extraction.planes[k - 1].num_pixels);
    }
    EXPECT_NEAR(plane.distance(plane.centroid), 0.0, 1e-9);
    int majority = -1, majority_votes = 0;
    for (const auto& [surface, count] : votes[k]) {
      if (count > majority_votes) {
        majority = surface;
        majority_votes = count;
      }
    }
    ASSERT_GE(majority, 0) << "plane " << k << " sees no true surface";
    // A few percent of a plane's pixels may lie on a neighbouring surface, near a crease or an
    // occluding edge, within the depth noise of both.
    EXPECT_GT(majority_votes, 0.9 * labelled[k]) << "plane " << k << " mixes surfaces";
    const TruePlane& truth = view.truth[static_cast<std::size_t>(majority)];
    EXPECT_LT(angle_deg(plane.normal, truth.normal), 1.0) << truth.name;
    EXPECT_LT(std::abs(plane.d - truth.d), 0.01) << truth.name;
    ++found[static_cast<std::size_t>(majority)];

    // Hull: on the plane, convex and counter-clockwise seen from the normal side.
    ASSERT_GE(plane.hull.size(), 3u);
    double area = 0.0;
    for (std::size_t h = 0; h < plane.hull.size(); ++h) {
      const Eigen::Vector3d& a = plane.hull[h];
      const Eigen::Vector3d& b = plane.hull[(h + 1) % plane.hull.size()];
      const Eigen::Vector3d& c = plane.hull[(h + 2) % plane.hull.size()];
      EXPECT_LT(std::abs(plane.distance(a)), 1e-5);
      // The hull spans the plane's pixels, so its corners project into the image (a few pixels
      // out at most: the noisy points are projected onto the plane).
      EXPECT_TRUE(camera.in_image(camera.project(a), -10.0)) << a.transpose();
      // Convex turn (float rounding of the hull's in-plane coordinates allows a tiny negative).
      EXPECT_GT((b - a).cross(c - b).dot(plane.normal), -1e-6);
      area += (a - plane.centroid).cross(b - plane.centroid).dot(plane.normal) / 2.0;
    }
    EXPECT_GT(area, 0.0);
  }

  // Big surfaces (>= 4% of the image: the walls and floor in view, the table and the large
  // boxes when close) are found.
  const double big = 0.04 * depth.rows * depth.cols;
  for (std::size_t j = 0; j < view.truth.size(); ++j) {
    if (view.visible[j] < big) continue;
    ++big_surfaces;
    EXPECT_GE(found[j], 1) << view.truth[j].name << " (" << view.visible[j] << " px) missed";
  }
}

PlaneExtractor make_extractor(const PlaneOptions& options = {}) {
  return PlaneExtractor(sequence().camera(), options);
}

// Every pixel (pixel_step 1) and the default sampling (every 3rd pixel of every 3rd row). The
// planes are fitted to the samples there, 1/9 of the pixels, and the labels of the full image
// follow those fits: in these views the worst plane has 98.2 % of its labelled pixels' true
// points within 1 cm of it at the default sampling, 99.3 % at 1.
struct Sampling {
  int pixel_step;
  double min_within_1cm;
};
constexpr Sampling kSamplings[] = {{1, 0.98}, {0, 0.97}};

/// Extracts the planes of every rendered view at each sampling and checks them (check_view);
/// max_rms: the bound on each plane's RMS fit (0: none).
void check_rendered_room(bool noisy, double max_rms) {
  for (const Sampling sampling : kSamplings) {
    SCOPED_TRACE("pixel_step " + std::to_string(sampling.pixel_step));
    PlaneOptions options;
    options.pixel_step = sampling.pixel_step;
    const PlaneExtractor extractor = make_extractor(options);
    int big_surfaces = 0;
    for (const View& view : views()) {
      const cv::Mat& depth = noisy ? view.noisy_depth : view.frame.depth;
      const PlaneExtraction extraction = extractor.extract(depth);
      check_view(view, depth, extraction, big_surfaces, sampling.min_within_1cm);
      if (max_rms > 0.0) {
        for (const PlaneFeature& plane : extraction.planes) EXPECT_LT(plane.rms, max_rms);
      }
    }
    std::printf("[ info     ] %d big surfaces checked\n", big_surfaces);
    EXPECT_GE(big_surfaces, 20);
  }
}

TEST(PlaneExtractor, RenderedRoomNoiseFree) { check_rendered_room(false, 0.002); }

TEST(PlaneExtractor, RenderedRoomKinectNoise) { check_rendered_room(true, 0.0); }

TEST(PlaneExtractor, SinglePlaneFillsTheImage) {
  const PinholeCamera camera = test::make_camera();
  // A tilted plane n . p + d = 0 in front of the camera.
  const Eigen::Vector3d n = Eigen::Vector3d(0.2, -0.3, -1.0).normalized();
  const double d = 2.0;
  cv::Mat depth(camera.height, camera.width, CV_32FC1);
  for (int v = 0; v < camera.height; ++v)
    for (int u = 0; u < camera.width; ++u)
      depth.at<float>(v, u) =
          static_cast<float>(-d / n.dot(camera.unproject(Eigen::Vector2d(u, v), 1.0)));
  const PlaneExtraction extraction = PlaneExtractor(camera, {}).extract(depth);
  ASSERT_EQ(extraction.planes.size(), 1u);
  const PlaneFeature& plane = extraction.planes[0];
  EXPECT_LT(angle_deg(plane.normal, n), 1e-3);
  EXPECT_NEAR(plane.d, d, 1e-4);
  EXPECT_EQ(plane.num_pixels, camera.width * camera.height);
  EXPECT_EQ(cv::countNonZero(extraction.labels == 0), camera.width * camera.height);
  EXPECT_LT(plane.rms, 1e-4);
  // The hull is the image of the frame's corners: four vertices (up to float rounding, a few
  // nearly collinear extra ones).
  EXPECT_GE(plane.hull.size(), 4u);
}

TEST(PlaneExtractor, CoplanarPiecesSplitByAnObjectAreOnePlane) {
  const PinholeCamera camera = test::make_camera();
  // A wall at z = 2 m, cut in two by a full-height pillar at z = 1 m in the middle third; its
  // right piece is measured 5 mm further (depth noise), within coplanar_distance.
  cv::Mat depth(camera.height, camera.width, CV_32FC1, cv::Scalar(2.0f));
  depth.colRange(camera.width / 3, 2 * camera.width / 3).setTo(1.0f);
  depth.colRange(2 * camera.width / 3, camera.width).setTo(2.005f);
  const PlaneExtraction merged = PlaneExtractor(camera, {}).extract(depth);
  ASSERT_EQ(merged.planes.size(), 2u);
  // The wall (two thirds of the image) first, labelled on both sides of the pillar.
  EXPECT_NEAR(merged.planes[0].d, 2.0025, 1e-3);
  EXPECT_NEAR(merged.planes[1].d, 1.0, 1e-3);
  EXPECT_EQ(merged.labels.at<std::int8_t>(10, 5), 0);
  EXPECT_EQ(merged.labels.at<std::int8_t>(10, camera.width - 5), 0);
  EXPECT_EQ(merged.labels.at<std::int8_t>(10, camera.width / 2), 1);
  EXPECT_EQ(cv::countNonZero(merged.labels == 0), merged.planes[0].num_pixels);
  // Its hull spans both pieces.
  double min_x = 1e9, max_x = -1e9;
  for (const auto& h : merged.planes[0].hull) {
    min_x = std::min(min_x, h.x());
    max_x = std::max(max_x, h.x());
  }
  EXPECT_LT(min_x, camera.unproject(Eigen::Vector2d(20, 0), 2.0).x());
  EXPECT_GT(max_x, camera.unproject(Eigen::Vector2d(camera.width - 20, 0), 2.0).x());
  // Without the merge the two pieces stay apart.
  PlaneOptions apart;
  apart.coplanar_distance = 0.002;
  EXPECT_EQ(PlaneExtractor(camera, apart).extract(depth).planes.size(), 3u);
}

TEST(PlaneExtractor, RandomDepthHasNoPlanes) {
  const PinholeCamera camera = test::make_camera();
  cv::Mat depth(camera.height, camera.width, CV_32FC1);
  std::mt19937 rng(42);
  std::uniform_real_distribution<float> z(1.0f, 3.0f);
  for (int v = 0; v < camera.height; ++v)
    for (int u = 0; u < camera.width; ++u) depth.at<float>(v, u) = z(rng);
  const PlaneExtraction extraction = PlaneExtractor(camera, {}).extract(depth);
  EXPECT_TRUE(extraction.planes.empty());
  EXPECT_EQ(cv::countNonZero(extraction.labels != -1), 0);
}

TEST(PlaneExtractor, InvalidInputGivesNoPlanes) {
  const PinholeCamera camera = test::make_camera();
  const PlaneExtractor extractor(camera, {});
  const cv::Size size(camera.width, camera.height);
  const PlaneExtraction empty = extractor.extract(cv::Mat());
  EXPECT_TRUE(empty.planes.empty());
  EXPECT_TRUE(empty.labels.empty());
  const std::vector<cv::Mat> inputs = {
      cv::Mat(size, CV_16UC1, cv::Scalar(5000)),               // raw depth, not metres
      cv::Mat(size, CV_64FC1, cv::Scalar(1.0)),                // wrong depth type
      cv::Mat(size, CV_32FC3, cv::Scalar::all(1.0)),           // not single-channel
      cv::Mat(cv::Size(320, 240), CV_32FC1, cv::Scalar(1.0)),  // not the camera's size
      cv::Mat(size, CV_32FC1, cv::Scalar(0.0)),                // no valid depth
      cv::Mat(size, CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN())),
      cv::Mat(size, CV_32FC1, cv::Scalar(std::numeric_limits<float>::infinity())),
      cv::Mat(size, CV_32FC1, cv::Scalar(-2.0)),
  };
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    const PlaneExtraction extraction = extractor.extract(inputs[i]);
    EXPECT_TRUE(extraction.planes.empty()) << "input " << i;
    EXPECT_EQ(extraction.labels.type(), CV_8SC1) << "input " << i;
    EXPECT_EQ(extraction.labels.size(), inputs[i].size()) << "input " << i;
    EXPECT_EQ(cv::countNonZero(extraction.labels != -1), 0) << "input " << i;
  }
}

TEST(PlaneOptions, CheckNamesTheBadField) {
  EXPECT_FALSE(PlaneOptions{}.check().has_value());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  struct Case {
    std::string field;
    void (*apply)(PlaneOptions&, double);
    double value;
  };
  const std::vector<Case> cases = {
      {"cell_size", [](PlaneOptions& o, double x) { o.cell_size = static_cast<int>(x); }, 2},
      {"cell_size", [](PlaneOptions& o, double x) { o.cell_size = static_cast<int>(x); }, 0},
      // 5 pixels at a step of 2: cells of 2x2 samples cannot show a plane's noise.
      {"cell_size",
       [](PlaneOptions& o, double x) {
         o.pixel_step = 2;
         o.cell_size = static_cast<int>(x);
       },
       5},
      {"pixel_step", [](PlaneOptions& o, double x) { o.pixel_step = static_cast<int>(x); }, -1},
      {"pixel_step", [](PlaneOptions& o, double x) { o.pixel_step = static_cast<int>(x); }, 5},
      {"cell_tolerance", [](PlaneOptions& o, double x) { o.cell_tolerance = x; }, 0.0},
      {"cell_tolerance", [](PlaneOptions& o, double x) { o.cell_tolerance = x; }, nan},
      {"cell_tolerance_per_metre",
       [](PlaneOptions& o, double x) { o.cell_tolerance_per_metre = x; }, -0.001},
      {"merge_angle_deg", [](PlaneOptions& o, double x) { o.merge_angle_deg = x; }, 0.0},
      {"merge_angle_deg", [](PlaneOptions& o, double x) { o.merge_angle_deg = x; }, 90.0},
      {"merge_distance", [](PlaneOptions& o, double x) { o.merge_distance = x; }, -0.01},
      {"merge_distance", [](PlaneOptions& o, double x) { o.merge_distance = x; }, nan},
      {"min_area_fraction", [](PlaneOptions& o, double x) { o.min_area_fraction = x; }, 1.5},
      {"min_area_fraction", [](PlaneOptions& o, double x) { o.min_area_fraction = x; }, -0.1},
      {"max_fit_rms", [](PlaneOptions& o, double x) { o.max_fit_rms = x; }, 0.0},
      {"max_planes", [](PlaneOptions& o, double x) { o.max_planes = static_cast<int>(x); }, 0},
      {"max_planes", [](PlaneOptions& o, double x) { o.max_planes = static_cast<int>(x); }, 128},
  };
  for (const Case& c : cases) {
    PlaneOptions options;
    c.apply(options, c.value);
    const auto problem = options.check();
    ASSERT_TRUE(problem.has_value()) << c.field << " = " << c.value;
    EXPECT_NE(problem->find("planes." + c.field + " "), std::string::npos) << *problem;
    EXPECT_THROW(PlaneExtractor(test::make_camera(), options), InputError) << c.field;
  }
  PinholeCamera bad_camera = test::make_camera();
  bad_camera.width = 0;
  EXPECT_THROW(PlaneExtractor(bad_camera, PlaneOptions{}), InputError);
}

TEST(PlaneExtractor, MaxPlanesKeepsTheLargest) {
  const View& view = views().front();
  PlaneOptions options;
  for (int step : {1, 2}) {
    SCOPED_TRACE(step);
    options = PlaneOptions{};
    options.pixel_step = step;
    const PlaneExtraction all = make_extractor(options).extract(view.frame.depth);
    ASSERT_GE(all.planes.size(), 2u);
    options.max_planes = 1;
    const PlaneExtraction one = make_extractor(options).extract(view.frame.depth);
    ASSERT_EQ(one.planes.size(), 1u);
    EXPECT_EQ(one.planes[0].normal, all.planes[0].normal);
    if (step == 1) {
      EXPECT_EQ(one.planes[0].num_pixels, all.planes[0].num_pixels);
    } else {
      // The full image's pixels are labelled after the selection: where the lost planes met
      // the kept one, a few of their pixels now fit the kept plane within its band.
      EXPECT_GE(one.planes[0].num_pixels, all.planes[0].num_pixels);
      EXPECT_LT(one.planes[0].num_pixels, 1.01 * all.planes[0].num_pixels);
    }
    EXPECT_EQ(cv::countNonZero(one.labels == 0), one.planes[0].num_pixels);
    EXPECT_EQ(cv::countNonZero(one.labels > 0), 0);
  }

  options = PlaneOptions{};
  options.min_area_fraction = 0.9;
  EXPECT_TRUE(make_extractor(options).extract(view.frame.depth).planes.empty());
}

TEST(PlaneOptions, AutoPixelStepLeavesCellsThreeSamplesWide) {
  PlaneOptions options;  // cell_size 12, pixel_step 0 (auto)
  EXPECT_EQ(options.effective_pixel_step(), 3);
  for (auto [cell_size, step] : {std::pair{10, 3}, std::pair{9, 3}, std::pair{8, 2},
                                 std::pair{5, 1}, std::pair{3, 1}, std::pair{100, 3}}) {
    options.cell_size = cell_size;
    EXPECT_EQ(options.effective_pixel_step(), step) << cell_size;
    EXPECT_FALSE(options.check().has_value()) << cell_size;
  }
  options.pixel_step = 2;  // a chosen step is kept
  options.cell_size = 12;
  EXPECT_EQ(options.effective_pixel_step(), 2);
}

TEST(PlaneExtractor, OtherCellSizes) {
  // Cell sizes that do not divide the image (partial cells at the right and bottom borders).
  // Also every other pixel (pixel_step 2) and every third, with cells of 3x3 to 8x8 samples.
  for (auto [cell_size, step] :
       {std::pair{7, 1}, std::pair{16, 1}, std::pair{7, 2}, std::pair{16, 2}, std::pair{10, 3}}) {
    SCOPED_TRACE("cell_size " + std::to_string(cell_size) + " step " + std::to_string(step));
    PlaneOptions options;
    options.cell_size = cell_size;
    options.pixel_step = step;
    const PlaneExtractor extractor = make_extractor(options);
    int big_surfaces = 0;
    for (std::size_t i = 0; i < 2; ++i) {
      const View& view = views()[i];
      check_view(view, view.noisy_depth, extractor.extract(view.noisy_depth), big_surfaces);
    }
    EXPECT_GE(big_surfaces, 5);
  }
}

TEST(PlaneExtractor, WithoutLabelsTheSamePlanes) {
  // The frame asks for the planes only: the same planes, without labelling the image (at
  // pixel_step 2 their sizes are then counted on the samples).
  for (int step : {1, 2, 3}) {
    SCOPED_TRACE(step);
    PlaneOptions options;
    options.pixel_step = step;
    const PlaneExtractor extractor = make_extractor(options);
    for (std::size_t i = 0; i < 3; ++i) {
      const cv::Mat& depth = views()[i].noisy_depth;
      const PlaneExtraction full = extractor.extract(depth);
      const PlaneExtraction bare = extractor.extract(depth, PlaneExtractor::Labels::kNone);
      EXPECT_TRUE(bare.labels.empty());
      ASSERT_EQ(full.planes.size(), bare.planes.size());
      for (const PlaneFeature& plane : bare.planes) {
        // Matched by normal and offset, as planes of nearly equal size may swap places.
        const auto same = std::find_if(full.planes.begin(), full.planes.end(), [&](const auto& p) {
          return p.normal == plane.normal && p.d == plane.d && p.centroid == plane.centroid;
        });
        ASSERT_NE(same, full.planes.end());
        EXPECT_EQ(same->hull.size(), plane.hull.size());
        if (step == 1) {
          EXPECT_EQ(same->num_pixels, plane.num_pixels);
        } else {
          EXPECT_NEAR(plane.num_pixels, same->num_pixels, 0.1 * same->num_pixels);
        }
      }
    }
  }
}

TEST(PlaneExtractor, NonContinuousInput) {
  const View& view = views().front();
  cv::Mat padded(view.noisy_depth.rows + 20, view.noisy_depth.cols + 30, CV_32FC1, cv::Scalar(0.0));
  const cv::Rect roi(cv::Point(17, 9), view.noisy_depth.size());
  view.noisy_depth.copyTo(padded(roi));
  ASSERT_FALSE(padded(roi).isContinuous());
  const PlaneExtractor extractor = make_extractor();
  const PlaneExtraction a = extractor.extract(view.noisy_depth);
  const PlaneExtraction b = extractor.extract(padded(roi));
  ASSERT_EQ(a.planes.size(), b.planes.size());
  for (std::size_t k = 0; k < a.planes.size(); ++k) {
    EXPECT_EQ(a.planes[k].normal, b.planes[k].normal);
    EXPECT_EQ(a.planes[k].num_pixels, b.planes[k].num_pixels);
  }
  EXPECT_EQ(cv::norm(a.labels, b.labels, cv::NORM_INF), 0.0);
}

TEST(PlaneExtractor, Deterministic) {
  const View& view = views()[2];
  const PlaneExtraction a = make_extractor().extract(view.noisy_depth);
  const PlaneExtraction b = make_extractor().extract(view.noisy_depth);
  ASSERT_EQ(a.planes.size(), b.planes.size());
  for (std::size_t k = 0; k < a.planes.size(); ++k) {
    EXPECT_EQ(a.planes[k].normal, b.planes[k].normal);
    EXPECT_EQ(a.planes[k].d, b.planes[k].d);
    EXPECT_EQ(a.planes[k].centroid, b.planes[k].centroid);
    EXPECT_EQ(a.planes[k].num_pixels, b.planes[k].num_pixels);
    EXPECT_EQ(a.planes[k].rms, b.planes[k].rms);
    EXPECT_EQ(a.planes[k].hull, b.planes[k].hull);
  }
  EXPECT_EQ(cv::norm(a.labels, b.labels, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace mcslam::features
