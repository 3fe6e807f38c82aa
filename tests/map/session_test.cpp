// Session files (map/session.hpp): a hand-made map saved and read back field by field, and every
// kind of bad file ending in one InputError that names it.
#include "mcslam/map/session.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <memory>
#include <opencv2/core.hpp>
#include <random>
#include <string>
#include <vector>

#include "mcslam/place/vocabulary.hpp"
#include "support/temp_dir.hpp"
#include "support/test_camera.hpp"

namespace mcslam::map {
namespace {

constexpr int kPoints = 12;
constexpr int kLines = 4;
constexpr int kPlanes = 2;

std::shared_ptr<const features::ScalePyramid> session_pyramid() {
  static const auto p = std::make_shared<const features::ScalePyramid>(8, 1.2);
  return p;
}

SessionInfo make_info() {
  SessionInfo info;
  info.camera = test::make_camera(517.3, 516.5, 318.6, 255.3);
  info.camera.distortion = {0.26, -0.95, -0.005, 0.002, 1.16};
  info.camera.depth_factor = 5000.0;
  info.camera.bf = 40.5;
  info.camera.readout_time = 0.02;
  info.vocabulary_id = 0x0123456789ABCDEFULL;
  info.orb_levels = 8;
  info.orb_scale_factor = 1.2;
  return info;
}

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

Eigen::Vector3d random_vector(std::mt19937_64& rng, double scale) {
  return {uniform(rng, -scale, scale), uniform(rng, -scale, scale), uniform(rng, -scale, scale)};
}

features::OrbDescriptor random_descriptor(std::mt19937_64& rng) {
  features::OrbDescriptor d;
  for (auto& b : d.bytes) b = static_cast<std::uint8_t>(rng() & 0xFF);
  return d;
}

SE3 random_pose(std::mt19937_64& rng) {
  std::normal_distribution<double> n;
  const Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  return SE3(q, random_vector(rng, 2.0));
}

/// kPoints points (every third without depth, every fourth on a plane), kLines segments (every
/// other with depth), kPlanes planes with hulls; random values from `rng`.
std::shared_ptr<const features::FrameFeatures> random_features(std::mt19937_64& rng) {
  auto f = std::make_shared<features::FrameFeatures>();
  f->pyramid = session_pyramid();
  std::vector<features::Keypoint> keypoints;
  for (int i = 0; i < kPoints; ++i) {
    features::PointFeature p;
    p.keypoint.uv = Eigen::Vector2f(static_cast<float>(uniform(rng, 0, 639)),
                                    static_cast<float>(uniform(rng, 0, 479)));
    p.keypoint.level = static_cast<int>(rng() % 8);
    p.keypoint.angle_deg = static_cast<float>(uniform(rng, 0, 360));
    p.keypoint.response = static_cast<float>(uniform(rng, 0, 100));
    p.descriptor = random_descriptor(rng);
    if (i % 3 != 0) {
      p.depth = static_cast<float>(uniform(rng, 0.5, 4.0));
      p.u_right = p.keypoint.uv.x() - 40.5f / p.depth;
    }
    p.plane = i % 4 == 0 ? (i / 4) % kPlanes : -1;
    keypoints.push_back(p.keypoint);
    f->points.push_back(p);
  }
  for (int i = 0; i < kLines; ++i) {
    features::LineFeature l;
    l.start = Eigen::Vector2f(static_cast<float>(uniform(rng, 0, 639)),
                              static_cast<float>(uniform(rng, 0, 479)));
    l.end = Eigen::Vector2f(static_cast<float>(uniform(rng, 0, 639)),
                            static_cast<float>(uniform(rng, 0, 479)));
    l.descriptor = random_descriptor(rng);
    l.has_depth = i % 2 == 0;
    if (l.has_depth) {
      l.start_c = random_vector(rng, 3.0);
      l.end_c = random_vector(rng, 3.0);
    }
    f->lines.push_back(l);
  }
  for (int i = 0; i < kPlanes; ++i) {
    features::PlaneFeature p;
    p.normal = random_vector(rng, 1.0).normalized();
    p.d = uniform(rng, 0.5, 3.0);
    p.centroid = random_vector(rng, 2.0);
    p.num_pixels = static_cast<int>(rng() % 20000);
    p.rms = uniform(rng, 0.0, 0.02);
    for (int h = 0; h < 4 + i; ++h) p.hull.push_back(random_vector(rng, 2.0));
    f->planes.push_back(p);
  }
  f->grid = features::KeypointGrid(keypoints, 640, 480);
  return f;
}

/// Keyframes 0, 1, 2, 3 and 7 (3 culled at the end), points, lines and planes observed by several
/// of them, covisibility, statistics, colours, exclusions, and an erased point.
void build_map(Map& map, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const std::vector<KeyFrameId> ids{0, 1, 2, 3, 7};
  for (const KeyFrameId id : ids) {
    KeyFrame kf;
    kf.id = id;
    kf.frame_id = 10 * id + 3;
    kf.timestamp = 1305031102.175304 + 0.1 * static_cast<double>(id);
    kf.T_c_w = random_pose(rng);
    kf.features = random_features(rng);
    if (id == 1) {
      kf.excluded_points.assign(kPoints, 0);
      kf.excluded_points[5] = 1;
      kf.excluded_lines = {0, 1, 0, 0};
    }
    map.add_keyframe(std::move(kf));
  }
  // Point p is feature p of keyframe 0 and feature (p + k) % kPoints of keyframe k.
  for (int p = 0; p < kPoints; ++p) {
    const PointId id = map.add_point(random_vector(rng, 3.0) + Eigen::Vector3d(0, 0, 4), 0, p);
    for (const KeyFrameId k : {1u, 2u, 3u, 7u})
      if ((p + static_cast<int>(k)) % 3 != 0)
        map.add_observation(id, k, (p + static_cast<int>(k)) % kPoints);
    map.update_point_appearance(id);
    map.set_point_color(id,
                        {static_cast<std::uint8_t>(p), 200, static_cast<std::uint8_t>(255 - p)});
    map.add_tracking_statistics(id, 5 + p, 3 + p % 4);
  }
  for (int l = 0; l < kLines; ++l) {
    const LineId id = map.add_line(random_vector(rng, 2.0), random_vector(rng, 2.0), 1, l);
    map.add_line_observation(id, 2, (l + 1) % kLines);
    if (l % 2 == 0) map.add_line_observation(id, 3, l);
    map.add_line_statistics(id, 4, 2);
  }
  for (int p = 0; p < kPlanes; ++p) {
    const Eigen::Vector3d n = random_vector(rng, 1.0).normalized();
    const Eigen::Vector4d plane(n.x(), n.y(), n.z(), uniform(rng, 0.5, 2.0));
    std::vector<Eigen::Vector3d> hull;
    for (int h = 0; h < 5; ++h) hull.push_back(random_vector(rng, 2.0));
    const PlaneId id = map.add_plane(plane, hull, 0, p);
    map.add_plane_observation(id, 7, (p + 1) % kPlanes);
  }
  for (const KeyFrameId id : ids) map.update_covisibility(id);
  map.add_loop_edge(0, 7);
  map.erase_point(4);
  map.erase_keyframe(3);
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Success when the two files hold the same bytes; otherwise their sizes and the first offset
/// where they differ (not the whole binary content).
::testing::AssertionResult same_bytes(const std::string& path_a, const std::string& path_b) {
  const std::string a = read_bytes(path_a);
  const std::string b = read_bytes(path_b);
  if (a == b) return ::testing::AssertionSuccess();
  std::size_t at = 0;
  while (at < a.size() && at < b.size() && a[at] == b[at]) ++at;
  return ::testing::AssertionFailure() << path_a << " (" << a.size() << " bytes) and " << path_b
                                       << " (" << b.size() << " bytes) differ from offset " << at;
}

void expect_same_pose(const SE3& a, const SE3& b) {
  EXPECT_EQ(a.quaternion().coeffs(), b.quaternion().coeffs());
  EXPECT_EQ(a.translation(), b.translation());
}

void expect_same_features(const features::FrameFeatures& a, const features::FrameFeatures& b) {
  ASSERT_EQ(a.points.size(), b.points.size());
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    const auto& p = a.points[i];
    const auto& q = b.points[i];
    EXPECT_EQ(p.keypoint.uv, q.keypoint.uv);
    EXPECT_EQ(p.keypoint.level, q.keypoint.level);
    EXPECT_EQ(p.keypoint.angle_deg, q.keypoint.angle_deg);
    EXPECT_EQ(p.keypoint.response, q.keypoint.response);
    EXPECT_EQ(p.descriptor, q.descriptor);
    EXPECT_EQ(p.depth, q.depth);
    EXPECT_EQ(p.u_right, q.u_right);
    EXPECT_EQ(p.plane, q.plane);
  }
  ASSERT_EQ(a.lines.size(), b.lines.size());
  for (std::size_t i = 0; i < a.lines.size(); ++i) {
    const auto& l = a.lines[i];
    const auto& m = b.lines[i];
    EXPECT_EQ(l.start, m.start);
    EXPECT_EQ(l.end, m.end);
    EXPECT_EQ(l.descriptor, m.descriptor);
    EXPECT_EQ(l.has_depth, m.has_depth);
    EXPECT_EQ(l.start_c, m.start_c);
    EXPECT_EQ(l.end_c, m.end_c);
  }
  ASSERT_EQ(a.planes.size(), b.planes.size());
  for (std::size_t i = 0; i < a.planes.size(); ++i) {
    const auto& p = a.planes[i];
    const auto& q = b.planes[i];
    EXPECT_EQ(p.normal, q.normal);
    EXPECT_EQ(p.d, q.d);
    EXPECT_EQ(p.centroid, q.centroid);
    EXPECT_EQ(p.num_pixels, q.num_pixels);
    EXPECT_EQ(p.rms, q.rms);
    EXPECT_EQ(p.hull, q.hull);
  }
  // The rebuilt grid finds the same keypoints, the rebuilt pyramid has the same scales.
  ASSERT_EQ(a.grid.size(), b.grid.size());
  for (float u = 0.0f; u < 640.0f; u += 80.0f)
    for (float v = 0.0f; v < 480.0f; v += 60.0f)
      EXPECT_EQ(a.grid.query(u, v, 70.0f), b.grid.query(u, v, 70.0f)) << u << "," << v;
  ASSERT_NE(b.pyramid, nullptr);
  EXPECT_EQ(a.pyramid->scale, b.pyramid->scale);
  EXPECT_EQ(a.pyramid->sigma2, b.pyramid->sigma2);
  EXPECT_EQ(a.pyramid->inv_sigma2, b.pyramid->inv_sigma2);
  EXPECT_EQ(a.pyramid->log_scale_factor, b.pyramid->log_scale_factor);
}

void expect_same_map(const Map& a, const Map& b) {
  const Map::Counters ca = a.counters();
  const Map::Counters cb = b.counters();
  EXPECT_EQ(ca.next_keyframe, cb.next_keyframe);
  EXPECT_EQ(ca.next_point, cb.next_point);
  EXPECT_EQ(ca.next_line, cb.next_line);
  EXPECT_EQ(ca.next_plane, cb.next_plane);
  EXPECT_EQ(ca.last_keyframe, cb.last_keyframe);
  EXPECT_EQ(ca.version, cb.version);

  ASSERT_EQ(a.num_keyframes(), b.num_keyframes());
  for (const auto& [id, kf] : a.keyframes()) {
    SCOPED_TRACE("keyframe " + std::to_string(id));
    const KeyFrame* other = b.keyframe(id);
    ASSERT_NE(other, nullptr);
    EXPECT_EQ(other->id, kf.id);
    EXPECT_EQ(other->frame_id, kf.frame_id);
    EXPECT_EQ(other->timestamp, kf.timestamp);
    expect_same_pose(other->T_c_w, kf.T_c_w);
    expect_same_features(*kf.features, *other->features);
    EXPECT_EQ(other->landmarks, kf.landmarks);
    EXPECT_EQ(other->line_landmarks, kf.line_landmarks);
    EXPECT_EQ(other->plane_landmarks, kf.plane_landmarks);
    EXPECT_EQ(other->excluded_points, kf.excluded_points);
    EXPECT_EQ(other->excluded_lines, kf.excluded_lines);
    EXPECT_EQ(other->covisibility, kf.covisibility);
    EXPECT_EQ(other->loop_edges, kf.loop_edges);
  }
  ASSERT_EQ(a.num_points(), b.num_points());
  for (const auto& [id, p] : a.points()) {
    SCOPED_TRACE("point " + std::to_string(id));
    const MapPoint* q = b.point(id);
    ASSERT_NE(q, nullptr);
    EXPECT_EQ(q->id, p.id);
    EXPECT_EQ(q->p_w, p.p_w);
    EXPECT_EQ(q->descriptor, p.descriptor);
    EXPECT_EQ(q->observations, p.observations);
    EXPECT_EQ(q->normal, p.normal);
    EXPECT_EQ(q->min_distance, p.min_distance);
    EXPECT_EQ(q->max_distance, p.max_distance);
    EXPECT_EQ(q->first_keyframe, p.first_keyframe);
    EXPECT_EQ(q->color, p.color);
    EXPECT_EQ(q->visible, p.visible);
    EXPECT_EQ(q->found, p.found);
  }
  ASSERT_EQ(a.num_lines(), b.num_lines());
  for (const auto& [id, l] : a.lines()) {
    SCOPED_TRACE("line " + std::to_string(id));
    const MapLine* m = b.line(id);
    ASSERT_NE(m, nullptr);
    EXPECT_EQ(m->id, l.id);
    EXPECT_EQ(m->start_w, l.start_w);
    EXPECT_EQ(m->end_w, l.end_w);
    EXPECT_EQ(m->descriptor, l.descriptor);
    EXPECT_EQ(m->observations, l.observations);
    EXPECT_EQ(m->first_keyframe, l.first_keyframe);
    EXPECT_EQ(m->visible, l.visible);
    EXPECT_EQ(m->found, l.found);
  }
  ASSERT_EQ(a.num_planes(), b.num_planes());
  for (const auto& [id, p] : a.planes()) {
    SCOPED_TRACE("plane " + std::to_string(id));
    const MapPlane* q = b.plane(id);
    ASSERT_NE(q, nullptr);
    EXPECT_EQ(q->id, p.id);
    EXPECT_EQ(q->normal, p.normal);
    EXPECT_EQ(q->d, p.d);
    EXPECT_EQ(q->observations, p.observations);
    EXPECT_EQ(q->hull, p.hull);
    EXPECT_EQ(q->first_keyframe, p.first_keyframe);
  }
  ASSERT_EQ(a.erased_keyframes().size(), b.erased_keyframes().size());
  for (const auto& [id, e] : a.erased_keyframes()) {
    SCOPED_TRACE("culled keyframe " + std::to_string(id));
    const auto it = b.erased_keyframes().find(id);
    ASSERT_NE(it, b.erased_keyframes().end());
    EXPECT_EQ(it->second.parent, e.parent);
    expect_same_pose(it->second.T_this_parent, e.T_this_parent);
  }
}

TEST(SessionFile, RoundTripRestoresEveryFieldAndTheSameBytes) {
  Map map;
  build_map(map, 11);
  // The hand-made map holds everything a session stores.
  ASSERT_EQ(map.num_keyframes(), 4u);
  ASSERT_EQ(map.erased_keyframes().size(), 1u);
  ASSERT_EQ(map.erased_keyframes().begin()->first, 3u);
  ASSERT_EQ(map.num_points(), static_cast<std::size_t>(kPoints - 1));
  ASSERT_EQ(map.num_lines(), static_cast<std::size_t>(kLines));
  ASSERT_EQ(map.num_planes(), static_cast<std::size_t>(kPlanes));
  ASSERT_FALSE(map.keyframe(0)->covisibility.empty());

  const SessionInfo info = make_info();
  const test::TempDir dir("mcslam_session_test");
  const std::string path = dir.file("map.session");
  save_session(path, map, info);
  // Written atomically: no temporary file is left next to it.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()),
                          std::filesystem::directory_iterator()),
            1);

  const Session session = load_session(path);
  ASSERT_NE(session.map, nullptr);
  const SessionInfo& back = session.info;
  EXPECT_EQ(back.camera.fx, info.camera.fx);
  EXPECT_EQ(back.camera.fy, info.camera.fy);
  EXPECT_EQ(back.camera.cx, info.camera.cx);
  EXPECT_EQ(back.camera.cy, info.camera.cy);
  EXPECT_EQ(back.camera.width, info.camera.width);
  EXPECT_EQ(back.camera.height, info.camera.height);
  EXPECT_EQ(back.camera.distortion, info.camera.distortion);
  EXPECT_EQ(back.camera.depth_factor, info.camera.depth_factor);
  EXPECT_EQ(back.camera.bf, info.camera.bf);
  EXPECT_EQ(back.camera.readout_time, info.camera.readout_time);
  EXPECT_EQ(back.vocabulary_id, info.vocabulary_id);
  EXPECT_EQ(back.orb_levels, info.orb_levels);
  EXPECT_EQ(back.orb_scale_factor, info.orb_scale_factor);
  expect_same_map(map, *session.map);

  // Saving the loaded map gives the same bytes.
  const std::string again = dir.file("again.session");
  save_session(again, *session.map, session.info);
  EXPECT_TRUE(same_bytes(again, path));

  // The loaded map goes on as the original would: same answers, same next ids.
  Map& loaded = *session.map;
  EXPECT_EQ(loaded.best_covisible(0, 10), map.best_covisible(0, 10));
  const auto culled_pose = loaded.keyframe_pose_T_c_w(3);
  ASSERT_TRUE(culled_pose.has_value());
  expect_same_pose(*culled_pose, *map.keyframe_pose_T_c_w(3));
  EXPECT_EQ(loaded.add_point(Eigen::Vector3d(0, 0, 2), 0, 4), static_cast<PointId>(kPoints));
  KeyFrame kf;
  kf.features = loaded.keyframe(0)->features;
  EXPECT_EQ(loaded.add_keyframe(std::move(kf)), 8u);
}

/// Dense-map keyframe samples as OccupancyMap keeps them (camera 32 x 24, step 4).
std::vector<mapping::KeyframeSamples> make_dense(int n, bool colour) {
  std::vector<mapping::KeyframeSamples> out;
  cv::setRNGSeed(17);
  for (int k = 0; k < n; ++k) {
    mapping::KeyframeSamples s;
    s.id = static_cast<mapping::KeyframeId>(3 * k + 1);
    s.T_w_c = SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * k, Eigen::Vector3d::UnitY())),
                  Eigen::Vector3d(0.1 * k, 0.0, 0.2));
    s.camera = test::make_camera(30.0, 30.0, 15.5, 11.5);
    s.camera.width = 32;
    s.camera.height = 24;
    s.step = 4;
    s.depth_mm.create(6, 8, CV_16UC1);
    cv::randu(s.depth_mm, 0, 5000);
    s.kind = cv::Mat::zeros(6, 8, CV_8UC1);
    s.kind.at<std::uint8_t>(2, 3) = mapping::KeyframeSamples::kDynamic;
    s.kind.at<std::uint8_t>(4, 1) = mapping::KeyframeSamples::kMover;
    if (colour) {
      s.colour.create(6, 8, CV_8UC3);
      cv::randu(s.colour, 0, 256);
    }
    out.push_back(std::move(s));
  }
  return out;
}

TEST(SessionFile, DenseMapSamplesRoundTripExactly) {
  Map map;
  build_map(map, 4);
  const test::TempDir dir("mcslam_session_test");
  std::vector<mapping::KeyframeSamples> dense = make_dense(3, true);
  dense[1].colour.release();  // a keyframe without colour
  save_session(dir.file("dense.session"), map, make_info(), dense);
  const Session session = load_session(dir.file("dense.session"));
  expect_same_map(map, *session.map);
  ASSERT_EQ(session.dense.size(), dense.size());
  for (std::size_t k = 0; k < dense.size(); ++k) {
    SCOPED_TRACE(k);
    const auto& a = dense[k];
    const auto& b = session.dense[k];
    EXPECT_EQ(b.id, a.id);
    expect_same_pose(b.T_w_c, a.T_w_c);
    EXPECT_EQ(b.camera.fx, a.camera.fx);
    EXPECT_EQ(b.camera.cy, a.camera.cy);
    EXPECT_EQ(b.camera.width, a.camera.width);
    EXPECT_EQ(b.step, a.step);
    EXPECT_EQ(cv::norm(b.depth_mm, a.depth_mm, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(b.kind, a.kind, cv::NORM_INF), 0.0);
    ASSERT_EQ(b.colour.empty(), a.colour.empty());
    if (!a.colour.empty()) {
      EXPECT_EQ(cv::norm(b.colour, a.colour, cv::NORM_INF), 0.0);
    }
  }
  // The same bytes again from what was loaded.
  save_session(dir.file("again.session"), *session.map, session.info, session.dense);
  EXPECT_TRUE(same_bytes(dir.file("again.session"), dir.file("dense.session")));
  // Samples that could not be read back are refused before anything is written.
  std::vector<mapping::KeyframeSamples> bad = make_dense(2, false);
  bad[1].id = bad[0].id;
  const std::string path = dir.file("bad.session");
  test::expect_input_error([&] { save_session(path, map, make_info(), bad); },
                           {path, "dense map keyframe", "increasing order"});
  bad = make_dense(1, false);
  bad[0].kind = cv::Mat::zeros(5, 8, CV_8UC1);
  test::expect_input_error([&] { save_session(path, map, make_info(), bad); },
                           {path, "dense map keyframe 1", "do not fit"});
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(SessionFile, OneMapAlwaysGivesTheSameBytes) {
  const test::TempDir dir("mcslam_session_test");
  Map a;
  Map b;
  build_map(a, 5);
  build_map(b, 5);
  save_session(dir.file("a"), a, make_info());
  save_session(dir.file("b"), b, make_info());
  save_session(dir.file("a2"), a, make_info());
  EXPECT_TRUE(same_bytes(dir.file("b"), dir.file("a")));
  EXPECT_TRUE(same_bytes(dir.file("a2"), dir.file("a")));
  // Another map gives other bytes.
  Map c;
  build_map(c, 6);
  save_session(dir.file("c"), c, make_info());
  EXPECT_FALSE(same_bytes(dir.file("c"), dir.file("a")));
}

TEST(SessionFile, EmptyMapRoundTrips) {
  const test::TempDir dir("mcslam_session_test");
  const Map map;
  save_session(dir.file("empty.session"), map, make_info());
  // Header (12), info (124), counters (48), six empty lists (48), checksum (8).
  EXPECT_EQ(std::filesystem::file_size(dir.file("empty.session")), 240u);
  const Session session = load_session(dir.file("empty.session"));
  expect_same_map(map, *session.map);
  EXPECT_EQ(session.map->last_keyframe_id(), kNoId);
}

TEST(SessionFile, SaveRefusesWhatCouldNotBeReadBack) {
  const test::TempDir dir("mcslam_session_test");
  const std::string path = dir.file("map.session");
  Map map;
  build_map(map, 3);
  SessionInfo info = make_info();
  info.camera.fx = 0.0;
  test::expect_input_error([&] { save_session(path, map, info); }, {path, "camera"});
  info = make_info();
  info.orb_levels = 4;  // the keyframes' pyramids have 8
  test::expect_input_error([&] { save_session(path, map, info); }, {path, "pyramid"});
  info = make_info();
  info.orb_scale_factor = 1.0;
  test::expect_input_error([&] { save_session(path, map, info); }, {path, "scale factor"});
  KeyFrame kf;
  kf.id = 20;
  kf.timestamp = std::numeric_limits<double>::quiet_NaN();
  kf.features = map.keyframe(0)->features;
  map.add_keyframe(std::move(kf));
  test::expect_input_error([&] { save_session(path, map, make_info()); },
                           {path, "keyframe 20", "non-finite timestamp"});
  EXPECT_FALSE(std::filesystem::exists(path));
  const std::string nowhere = dir.file("missing/folder/map.session");
  test::expect_input_error([&] { save_session(nowhere, Map(), make_info()); },
                           {nowhere, "cannot write"});
}

class SessionFileErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    Map map;
    build_map(map, 7);
    save_session(dir_.file("good.session"), map, make_info());
    bytes_ = read_bytes(dir_.file("good.session"));
    ASSERT_GT(bytes_.size(), 1000u);
  }
  void expect_error(const std::string& name, const std::string& content,
                    const std::vector<std::string>& problem) {
    const std::string path = dir_.write(name, content);
    std::vector<std::string> parts = problem;
    parts.push_back(path);
    test::expect_input_error([&] { load_session(path); }, parts);
  }

  test::TempDir dir_{"mcslam_session_test"};
  std::string bytes_;
};

TEST_F(SessionFileErrors, MissingEmptyForeignAndNewerFiles) {
  const std::string missing = dir_.file("missing.session");
  test::expect_input_error([&] { load_session(missing); }, {missing, "cannot open"});
  test::expect_input_error([&] { load_session(dir_.str()); }, {dir_.str(), "is a directory"});
  expect_error("empty.session", "", {"empty file"});
  expect_error("foreign.session", "PK\x03\x04 not a session at all, just some bytes",
               {"not an mcslam session"});
  expect_error("vocabulary.session", "MCSLVOC" + std::string(1, '\0') + bytes_.substr(8),
               {"not an mcslam session"});
  std::string version = bytes_;
  version[8] = 4;
  expect_error("version.session", version, {"version 4", "reads version 3"});
  version[8] = 2;
  expect_error("dense.session", version,
               {"version 2", "before sessions kept the dense map", "--save-session"});
  version[8] = 1;
  expect_error("old.session", version, {"version 1", "reads version 3"});
}

TEST_F(SessionFileErrors, TruncatedFilesAreOneErrorNamingTheFile) {
  const std::size_t n = bytes_.size();
  for (const std::size_t length :
       {std::size_t{1}, std::size_t{7}, std::size_t{8}, std::size_t{11}, std::size_t{12},
        std::size_t{19}, std::size_t{20}, std::size_t{100}, n / 3, n / 2, n - 9, n - 8, n - 1}) {
    SCOPED_TRACE(length);
    expect_error("truncated.session", bytes_.substr(0, length), {});
  }
  expect_error("short.session", bytes_.substr(0, 10), {"truncated"});
  expect_error("half.session", bytes_.substr(0, n / 2), {"checksum mismatch"});
}

TEST_F(SessionFileErrors, FlippedBitsAreReportedByTheChecksum) {
  const std::size_t n = bytes_.size();
  int bit = 0;
  for (const std::size_t offset : {std::size_t{12}, std::size_t{20}, std::size_t{140},
                                   std::size_t{200}, n / 3, n / 2, n - 20, n - 8, n - 1}) {
    SCOPED_TRACE(offset);
    std::string flipped = bytes_;
    flipped[offset] = static_cast<char>(flipped[offset] ^ (1 << (bit++ % 8)));
    expect_error("flipped.session", flipped, {"corrupt", "checksum mismatch"});
  }
  std::string appended = bytes_ + "x";
  expect_error("appended.session", appended, {"checksum mismatch"});
}

// --- files with a valid checksum but content that does not hold together ---

/// Little-endian bytes, as the session format writes them.
class Bytes {
 public:
  template <typename T>
  Bytes& put(T value) {
    char raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));
    s_.append(raw, sizeof(T));
    return *this;
  }
  Bytes& u64(std::uint64_t v) { return put(v); }
  Bytes& i32(std::int32_t v) { return put(v); }
  Bytes& f32(float v) { return put(v); }
  Bytes& f64(double v) { return put(v); }
  Bytes& zeros(std::size_t n) {
    s_.append(n, '\0');
    return *this;
  }
  Bytes& raw(const std::string& bytes) {
    s_ += bytes;
    return *this;
  }
  /// The bytes so far followed by their checksum.
  std::string sealed() const {
    std::string out = s_;
    const std::uint64_t sum = place::file_checksum(out);
    out.append(reinterpret_cast<const char*>(&sum), sizeof(sum));
    return out;
  }

 private:
  std::string s_;
};

/// A session built byte by byte: one keyframe (id 0) with one point feature, observed by map
/// point 0. Each field below can be set to something inconsistent.
struct Handmade {
  double fx = 525.0;
  double qw = 1.0;
  std::uint64_t announced_features = 1;
  std::int32_t level = 0;
  std::int32_t plane = -1;
  std::uint64_t landmark_slots = 1;
  std::uint64_t landmark = 0;
  std::uint64_t covisible = 0;  // 1: an edge to keyframe 5
  double point_x = 0.5;
  std::uint64_t observing_keyframe = 0;
  std::int32_t observed_feature = 0;
  std::uint64_t next_point = 1;
  std::uint64_t keyframes = 1;  // 2: keyframe 0 twice
  // One dense-map keyframe (id 4) of a 16 x 8 camera sampled at step 4: 4 x 2 samples.
  std::uint64_t dense = 1;            // records written
  std::uint64_t dense_announced = 0;  // the count written before them (0: `dense`)
  std::int32_t dense_step = 4;
  std::uint8_t dense_kind = 2;
  std::uint8_t dense_colour = 1;
  std::string trailing;

  std::string bytes() const {
    Bytes b;
    b.raw(std::string("MCSLSES") + '\0').put<std::uint32_t>(3);  // format version
    // Session info: camera, vocabulary, ORB pyramid.
    b.f64(fx).f64(525.0).f64(319.5).f64(239.5).i32(640).i32(480);
    for (int i = 0; i < 5; ++i) b.f64(0.0);
    b.f64(5000.0).f64(40.0).f64(0.0).u64(0).i32(8).f64(1.2);
    // Counters: next keyframe, point, line, plane; last keyframe; version.
    b.u64(1).u64(next_point).u64(0).u64(0).u64(0).u64(3);
    b.u64(keyframes);
    for (std::uint64_t k = 0; k < keyframes; ++k) {
      b.u64(0).u64(17).f64(2.5);                              // id, frame id, timestamp
      b.f64(qw).f64(0).f64(0).f64(0).f64(0.1).f64(0).f64(0);  // pose
      b.u64(announced_features);
      b.f32(100.0f).f32(200.0f).i32(level).f32(45.0f).f32(30.0f).zeros(32);  // keypoint, descriptor
      b.f32(1.5f).f32(73.0f).i32(plane);  // depth, u_right, plane
      b.u64(0).u64(0);                    // no lines, no planes
      b.u64(landmark_slots);
      for (std::uint64_t i = 0; i < landmark_slots; ++i) b.u64(landmark);
      b.u64(0).u64(0).u64(0).u64(0);  // line and plane landmarks, exclusions
      b.u64(covisible);
      if (covisible != 0) b.u64(5).i32(10);
      b.u64(0);  // no loop edges
    }
    // One map point.
    b.u64(1).u64(0).f64(point_x).f64(0.2).f64(3.0).zeros(32);
    b.u64(1).u64(observing_keyframe).i32(observed_feature);  // observations
    b.f64(0).f64(0).f64(1).f64(1.0).f64(4.0).u64(0);         // normal, distances, first keyframe
    b.put<std::uint8_t>(1).put<std::uint8_t>(2).put<std::uint8_t>(3).i32(2).i32(1);
    b.u64(0).u64(0).u64(0);  // no lines, planes, culled keyframes
    b.u64(dense_announced != 0 ? dense_announced : dense);
    for (std::uint64_t k = 0; k < dense; ++k) {
      b.u64(4).f64(1).f64(0).f64(0).f64(0).f64(0).f64(0).f64(0.5);  // id, pose
      b.f64(10.0).f64(10.0).f64(7.5).f64(3.5).i32(16).i32(8);       // camera
      b.i32(dense_step).i32(2).i32(4);                              // step, rows, cols
      for (int i = 0; i < 8; ++i) b.put<std::uint16_t>(static_cast<std::uint16_t>(1000 + i));
      for (int i = 0; i < 8; ++i) b.put<std::uint8_t>(i == 5 ? dense_kind : 0);
      b.put<std::uint8_t>(dense_colour);
      if (dense_colour == 1) b.zeros(8 * 3);
    }
    b.raw(trailing);
    return b.sealed();
  }
};

TEST_F(SessionFileErrors, HandmadeFileLoadsAsTheFormatSays) {
  const std::string path = dir_.write("handmade.session", Handmade{}.bytes());
  const Session session = load_session(path);
  const Map& map = *session.map;
  ASSERT_EQ(map.num_keyframes(), 1u);
  ASSERT_EQ(map.num_points(), 1u);
  EXPECT_EQ(map.keyframe(0)->frame_id, 17u);
  EXPECT_EQ(map.keyframe(0)->features->points[0].keypoint.uv, Eigen::Vector2f(100.0f, 200.0f));
  EXPECT_EQ(map.keyframe(0)->landmarks, std::vector<PointId>{0});
  EXPECT_EQ(map.point(0)->observations, (std::map<KeyFrameId, int>{{0, 0}}));
  EXPECT_EQ(map.point(0)->color, (std::array<std::uint8_t, 3>{1, 2, 3}));
  EXPECT_EQ(map.counters().version, 3u);
  EXPECT_EQ(session.info.camera.fx, 525.0);
  ASSERT_EQ(session.dense.size(), 1u);
  const mapping::KeyframeSamples& dense = session.dense[0];
  EXPECT_EQ(dense.id, 4u);
  EXPECT_EQ(dense.T_w_c.translation(), Eigen::Vector3d(0.0, 0.0, 0.5));
  EXPECT_EQ(dense.camera.width, 16);
  EXPECT_EQ(dense.camera.cx, 7.5);
  EXPECT_EQ(dense.step, 4);
  ASSERT_EQ(dense.depth_mm.size(), cv::Size(4, 2));
  EXPECT_EQ(dense.depth_mm.at<std::uint16_t>(1, 1), 1005);
  EXPECT_EQ(dense.kind.at<std::uint8_t>(1, 1), mapping::KeyframeSamples::kMover);
  EXPECT_EQ(dense.colour.size(), cv::Size(4, 2));
}

TEST_F(SessionFileErrors, ValidChecksumButInconsistentContent) {
  const auto expect_inconsistent = [&](const Handmade& h, const std::vector<std::string>& what) {
    std::vector<std::string> parts = what;
    parts.push_back("inconsistent session file");
    expect_error("inconsistent.session", h.bytes(), parts);
  };
  Handmade h;
  h.observing_keyframe = 9;
  expect_inconsistent(h, {"point 0", "keyframe 9", "not in the map"});
  h = Handmade{};
  h.observed_feature = 1;
  expect_inconsistent(h, {"point 0", "feature 1 of keyframe 0"});
  h = Handmade{};
  h.observed_feature = -1;
  expect_inconsistent(h, {"feature -1"});
  h = Handmade{};
  h.landmark = 4;
  expect_inconsistent(h, {"keyframe 0 links point 4"});
  h = Handmade{};
  h.landmark_slots = 2;
  expect_inconsistent(h, {"keyframe 0", "landmark slots"});
  h = Handmade{};
  h.covisible = 1;
  expect_inconsistent(h, {"covisibility", "keyframe 5"});
  h = Handmade{};
  h.level = 8;
  expect_inconsistent(h, {"pyramid level 8"});
  h = Handmade{};
  h.plane = 0;
  expect_inconsistent(h, {"lies on plane 0", "has 0 planes"});
  h = Handmade{};
  h.point_x = std::numeric_limits<double>::infinity();
  expect_inconsistent(h, {"point 0", "non-finite"});
  h = Handmade{};
  h.qw = 0.5;
  expect_inconsistent(h, {"non-unit rotation"});
  h = Handmade{};
  h.fx = -1.0;
  expect_inconsistent(h, {"camera"});
  h = Handmade{};
  h.next_point = 0;
  expect_inconsistent(h, {"next point id 0 is in use"});
  h = Handmade{};
  h.keyframes = 2;
  expect_inconsistent(h, {"keyframe ids are not in increasing order"});
  h = Handmade{};
  h.announced_features = std::uint64_t{1} << 60;
  expect_inconsistent(h, {"point feature count", "does not fit"});
  h = Handmade{};
  h.announced_features = 3;
  expect_inconsistent(h, {});
  h = Handmade{};
  h.trailing = "abc";
  expect_inconsistent(h, {"3 unexpected bytes"});
  h = Handmade{};
  h.dense_step = 3;  // 16 x 8 at step 3 is 5 x 2 samples, not 4 x 2
  expect_inconsistent(h, {"dense map keyframe 4", "do not fit"});
  h = Handmade{};
  h.dense_step = 0;
  expect_inconsistent(h, {"dense map keyframe 4", "do not fit"});
  h = Handmade{};
  h.dense_kind = 7;
  expect_inconsistent(h, {"dense map keyframe 4", "kind 7"});
  h = Handmade{};
  h.dense_colour = 2;
  expect_inconsistent(h, {"dense map keyframe 4", "colour flag"});
  h = Handmade{};
  h.dense = 2;  // keyframe 4 twice
  expect_inconsistent(h, {"increasing id order"});
  h = Handmade{};
  h.dense_announced = std::uint64_t{1} << 58;
  expect_inconsistent(h, {"dense map keyframe count", "does not fit"});
}

}  // namespace
}  // namespace mcslam::map
