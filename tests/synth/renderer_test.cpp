#include "mcslam/synth/renderer.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <opencv2/core/utility.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "mcslam/core/error.hpp"
#include "mcslam/synth/sequence.hpp"

namespace mcslam::synth {
namespace {

/// Default options (640x480, kRich, seed 1): shared by the tests of this file.
const SyntheticSequence& rich_sequence() {
  static const SyntheticSequence sequence{SynthOptions{}};
  return sequence;
}

const SyntheticSequence& low_sequence() {
  static const SyntheticSequence sequence = [] {
    SynthOptions o;
    o.texture = TextureLevel::kLow;
    return SyntheticSequence(o);
  }();
  return sequence;
}

int fast_corners(const cv::Mat& bgr) {
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  std::vector<cv::KeyPoint> keypoints;
  cv::FAST(grey, keypoints, 20, true);
  return static_cast<int>(keypoints.size());
}

/// Distance of a world point from the room boundary surfaces.
double distance_to_room(const Scene& scene, const Eigen::Vector3d& p) {
  const Eigen::Vector3d a = (p - scene.room_min).cwiseAbs();
  const Eigen::Vector3d b = (scene.room_max - p).cwiseAbs();
  return std::min(a.minCoeff(), b.minCoeff());
}

/// Distance of a point (object frame) from the surface of a box with half extents h, for points
/// that are not inside it.
double distance_to_box_surface(const Eigen::Vector3d& q, const Eigen::Vector3d& h) {
  const Eigen::Vector3d e = q.cwiseAbs() - h;
  const double outside = e.cwiseMax(0.0).norm();
  return outside > 0.0 ? outside : -e.maxCoeff();
}

TEST(Renderer, FrameFormats) {
  const SyntheticSequence& seq = rich_sequence();
  const RenderedFrame f = seq.frame(0);
  EXPECT_EQ(f.rgb.type(), CV_8UC3);
  EXPECT_EQ(f.depth.type(), CV_32FC1);
  EXPECT_EQ(f.labels.type(), CV_16SC1);
  EXPECT_EQ(f.rgb.size(), cv::Size(640, 480));
  EXPECT_EQ(f.depth.size(), cv::Size(640, 480));
  // Noise-free depth: every pixel sees the room or an object.
  EXPECT_EQ(cv::countNonZero(f.depth > 0.0f), 640 * 480);
}

TEST(Renderer, DepthUnprojectsOntoTheHitSurface) {
  const SyntheticSequence& seq = rich_sequence();
  const Scene& scene = seq.scene();
  const PinholeCamera camera = seq.camera();
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> ux(0, camera.width - 1), uy(0, camera.height - 1);
  int on_objects = 0, on_room = 0;
  for (int i : {0, 110, 230}) {
    const RenderedFrame f = seq.frame(i);
    const SE3& T_w_c = seq.T_w_c(i);
    for (int k = 0; k < 3000; ++k) {
      const int x = ux(rng), y = uy(rng);
      const double z = f.depth.at<float>(y, x);
      ASSERT_GT(z, 0.0);
      const Eigen::Vector3d p_w = T_w_c * camera.unproject(Eigen::Vector2d(x, y), z);
      const int label = f.labels.at<std::int16_t>(y, x);
      if (label < 0) {
        EXPECT_LT(distance_to_room(scene, p_w), 1e-6) << "pixel " << x << "," << y;
        EXPECT_TRUE((p_w.array() >= scene.room_min.array() - 1e-6).all() &&
                    (p_w.array() <= scene.room_max.array() + 1e-6).all());
        ++on_room;
      } else {
        const SceneObject& object = scene.objects.at(label);
        const Eigen::Vector3d q = object.pose_at(seq.time(i)).inverse() * p_w;
        EXPECT_LT(distance_to_box_surface(q, object.half_extents), 1e-6)
            << "pixel " << x << "," << y << " object " << label;
        ++on_objects;
      }
    }
  }
  EXPECT_GT(on_objects, 1000);
  EXPECT_GT(on_room, 1000);
}

TEST(Renderer, BoxCornersProjectOntoSilhouetteEdges) {
  const SyntheticSequence& seq = rich_sequence();
  const Scene& scene = seq.scene();
  const PinholeCamera camera = seq.camera();
  int tested = 0;
  for (int i = 0; i < seq.size(); i += 50) {
    const RenderedFrame f = seq.frame(i);
    const SE3 T_c_w = seq.T_w_c(i).inverse();
    for (std::size_t o = 0; o < scene.objects.size(); ++o) {
      const auto corners = scene.objects[o].corners_at(seq.time(i));
      std::vector<cv::Point2f> projected;
      std::vector<double> depths;
      bool in_front = true;
      for (const Eigen::Vector3d& c : corners) {
        const Eigen::Vector3d p = T_c_w * c;
        in_front = in_front && p.z() > 0.3;
        const Eigen::Vector2d uv = camera.project(p);
        projected.emplace_back(static_cast<float>(uv.x()), static_cast<float>(uv.y()));
        depths.push_back(p.z());
      }
      if (!in_front) continue;
      std::vector<int> hull;
      cv::convexHull(projected, hull);
      cv::Point2f centroid(0, 0);
      for (int h : hull) centroid += projected[h] / static_cast<float>(hull.size());
      for (int h : hull) {
        const double top = corners[h].z();
        if (top < 0.1) continue;  // corners resting on the floor have no depth jump
        const Eigen::Vector2d uv(projected[h].x, projected[h].y);
        if (!camera.in_image(uv, 8.0)) continue;
        Eigen::Vector2d dir(uv.x() - centroid.x, uv.y() - centroid.y);
        if (dir.norm() < 20.0) continue;
        dir.normalize();
        const Eigen::Vector2d in = uv - 4.0 * dir, out = uv + 4.0 * dir;
        const int xi = static_cast<int>(std::lround(in.x())),
                  yi = static_cast<int>(std::lround(in.y()));
        const int xo = static_cast<int>(std::lround(out.x())),
                  yo = static_cast<int>(std::lround(out.y()));
        if (f.labels.at<std::int16_t>(yi, xi) != static_cast<int>(o)) continue;  // occluded
        const double z_out = f.depth.at<float>(yo, xo);
        if (z_out < depths[h]) continue;  // something in front of the corner
        // The corner is where the object ends: inside it, outside something farther away.
        EXPECT_EQ(f.labels.at<std::int16_t>(yi, xi), static_cast<int>(o));
        EXPECT_NE(f.labels.at<std::int16_t>(yo, xo), static_cast<int>(o))
            << "frame " << i << " object " << o << " corner " << h;
        EXPECT_GT(z_out - f.depth.at<float>(yi, xi), 0.05);
        // The RGB image shows an edge there too.
        cv::Mat grey;
        cv::cvtColor(
            f.rgb(cv::Rect(static_cast<int>(uv.x()) - 5, static_cast<int>(uv.y()) - 5, 11, 11)),
            grey, cv::COLOR_BGR2GRAY);
        cv::Mat gx, gy, mag;
        cv::Sobel(grey, gx, CV_32F, 1, 0);
        cv::Sobel(grey, gy, CV_32F, 0, 1);
        cv::magnitude(gx, gy, mag);
        double max_grad = 0.0;
        cv::minMaxLoc(mag, nullptr, &max_grad);
        EXPECT_GT(max_grad, 40.0);
        ++tested;
      }
    }
  }
  std::printf("%d silhouette corners checked\n", tested);
  EXPECT_GE(tested, 5);
}

TEST(Renderer, DeterministicNoisePerFrame) {
  const SyntheticSequence& seq = rich_sequence();
  const Renderer& renderer = seq.renderer();
  const RenderedFrame a = renderer.render(seq.T_w_c(3), 0.1);
  const RenderedFrame b = renderer.render(seq.T_w_c(3), 0.1);
  const RenderedFrame c = renderer.render(seq.T_w_c(3), 0.2);
  EXPECT_EQ(cv::norm(a.rgb, b.rgb, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(a.depth, c.depth, cv::NORM_INF), 0.0);  // static scene, exact depth
  // Same view, different time: only the noise differs (sigma 2 per image, so ~2.8 difference).
  cv::Mat diff;
  cv::absdiff(a.rgb, c.rgb, diff);
  diff.convertTo(diff, CV_32F);
  const double rms = std::sqrt(cv::mean(diff.mul(diff))[0]);
  EXPECT_GT(rms, 2.0);
  EXPECT_LT(rms, 3.6);
}

TEST(Renderer, RichTextureGivesManyFastCornersLowTextureFew) {
  const SyntheticSequence& rich = rich_sequence();
  const SyntheticSequence& low = low_sequence();
  for (int i : {0, 75, 150, 225, 299}) {
    const int n_rich = fast_corners(rich.frame(i).rgb);
    const int n_low = fast_corners(low.frame(i).rgb);
    std::printf("frame %3d: FAST corners (threshold 20) kRich %d, kLow %d\n", i, n_rich, n_low);
    EXPECT_GE(n_rich, 500) << "frame " << i;
    EXPECT_LT(4 * n_low, n_rich) << "frame " << i;
  }
}

TEST(Renderer, OrbMatchesAgreeWithGroundTruth) {
  // ORB features matched between frames reproject (depth + ground-truth pose) onto each other.
  const SyntheticSequence& seq = rich_sequence();
  const PinholeCamera camera = seq.camera();
  auto orb = cv::ORB::create(1000);
  for (const auto& [a, b] : {std::pair{100, 101}, std::pair{200, 206}}) {
    const RenderedFrame fa = seq.frame(a), fb = seq.frame(b);
    std::vector<cv::KeyPoint> ka, kb;
    cv::Mat da, db;
    orb->detectAndCompute(fa.rgb, cv::noArray(), ka, da);
    orb->detectAndCompute(fb.rgb, cv::noArray(), kb, db);
    std::vector<cv::DMatch> matches;
    cv::BFMatcher(cv::NORM_HAMMING, true).match(da, db, matches);
    const SE3 T_b_a = seq.T_w_c(b).inverse() * seq.T_w_c(a);
    int good = 0, total = 0;
    for (const cv::DMatch& m : matches) {
      if (m.distance > 50) continue;
      const cv::Point2f pa = ka[m.queryIdx].pt, pb = kb[m.trainIdx].pt;
      const float z = fa.depth.at<float>(cvRound(pa.y), cvRound(pa.x));
      const Eigen::Vector3d p_b = T_b_a * camera.unproject(Eigen::Vector2d(pa.x, pa.y), z);
      const Eigen::Vector2d uv = camera.project(p_b);
      ++total;
      good += (uv - Eigen::Vector2d(pb.x, pb.y)).norm() < 3.0;
    }
    std::printf("ORB frames %d-%d: %d of %d matches consistent with ground truth\n", a, b, good,
                total);
    EXPECT_GT(good, 300);
    EXPECT_GT(good, 0.85 * total);
  }
}

TEST(Renderer, KinectDepthNoiseMatchesModel) {
  const SyntheticSequence& seq = rich_sequence();
  RenderOptions options;
  options.depth_noise = true;
  const Renderer noisy(seq.scene(), seq.camera(), options);
  const Renderer& clean = seq.renderer();
  double sum = 0.0, sum2 = 0.0;
  int n = 0, invalid_far = 0, far = 0, jumps_valid = 0;
  for (int i : {0, 150}) {
    const RenderedFrame fn = noisy.render(seq.T_w_c(i), seq.time(i));
    const RenderedFrame fc = clean.render(seq.T_w_c(i), seq.time(i));
    for (int y = 1; y + 1 < fc.depth.rows; ++y)
      for (int x = 1; x + 1 < fc.depth.cols; ++x) {
        const float z = fc.depth.at<float>(y, x), zn = fn.depth.at<float>(y, x);
        if (z > 4.5f) {
          ++far;
          invalid_far += zn == 0.0f;
          continue;
        }
        const float right = fc.depth.at<float>(y, x + 1);
        if (std::abs(right - z) > 0.3f && zn != 0.0f) ++jumps_valid;
        if (zn == 0.0f) continue;
        // Quantised to 1/5000 m.
        EXPECT_NEAR(zn * 5000.0, std::round(zn * 5000.0), 0.02);
        const double r = (zn - z) / kinect_depth_sigma(z);
        sum += r;
        sum2 += r * r;
        ++n;
      }
  }
  ASSERT_GT(n, 200000);
  const double mean = sum / n, std_dev = std::sqrt(sum2 / n - mean * mean);
  std::printf("depth noise: normalised residual mean %.3f std %.3f over %d pixels\n", mean, std_dev,
              n);
  EXPECT_NEAR(mean, 0.0, 0.05);
  EXPECT_NEAR(std_dev, 1.0, 0.1);
  EXPECT_EQ(invalid_far, far);
  EXPECT_EQ(jumps_valid, 0);
  EXPECT_NEAR(kinect_depth_sigma(0.4), 0.0012, 1e-15);
  EXPECT_NEAR(kinect_depth_sigma(2.4), 0.0012 + 0.0019 * 4.0, 1e-15);
}

TEST(Renderer, FramesHaveContentInKinectRange) {
  // A long path at low resolution: most of every view is within 0.5-4.5 m.
  const SyntheticSequence& seq = rich_sequence();
  PinholeCamera small = seq.camera();
  small.width = 80;
  small.height = 60;
  small.fx = small.fy = 525.0 / 8.0;
  small.cx = 39.5;
  small.cy = 29.5;
  const Renderer renderer(seq.scene(), small);
  for (double t = 0.0; t < 150.0; t += 0.5) {
    const RenderedFrame f = renderer.render(camera_pose_at(t), t);
    const int in_range = cv::countNonZero((f.depth >= 0.5f) & (f.depth <= 4.5f));
    EXPECT_GT(in_range, 0.7 * 80 * 60) << "t = " << t;
    double min_z = 0.0;
    cv::minMaxLoc(f.depth, &min_z);
    EXPECT_GT(min_z, 0.8) << "t = " << t;
  }
}

/// Distance of the world point p_w from the surface a pixel with `label` sees at time t.
double distance_to_seen_surface(const Scene& scene, const Eigen::Vector3d& p_w, int label,
                                double t) {
  if (label < 0) return distance_to_room(scene, p_w);
  const SceneObject& object = scene.objects.at(label);
  return distance_to_box_surface(object.pose_at(t).inverse() * p_w, object.half_extents);
}

TEST(Renderer, RollingShutterRowsSeeTheSceneFromTheirRowTimePose) {
  const SyntheticSequence& seq = rich_sequence();
  const Renderer& renderer = seq.renderer();
  const Scene& scene = seq.scene();
  const PinholeCamera camera = seq.camera();
  constexpr double kSpeed = 3.0, kReadout = 0.03;
  const auto pose_at = [](double time) { return camera_pose_at(time, kSpeed); };
  const int h = camera.height;
  EXPECT_NEAR(renderer.row_time(1.0, 0, kReadout), 1.0 - 0.5 * kReadout + 0.5 * kReadout / h,
              1e-12);
  EXPECT_NEAR(renderer.row_time(1.0, h - 1, kReadout), 1.0 + 0.5 * kReadout - 0.5 * kReadout / h,
              1e-12);
  // A negative readout reads the rows bottom to top.
  EXPECT_NEAR(renderer.row_time(1.0, 0, -kReadout), 1.0 + 0.5 * kReadout - 0.5 * kReadout / h,
              1e-12);
  EXPECT_THROW(renderer.render(pose_at, 0.0, std::nan("")), InputError);

  for (const double t : {1.5, 3.3}) {  // rotating at about 90 deg/s
    const RenderedFrame rolling = renderer.render(pose_at, t, kReadout);
    const RenderedFrame global = renderer.render(pose_at(t), t);
    const SE3 T_c_w_mid = pose_at(t).inverse();
    for (const int row : {0, h / 2, h - 1}) {
      const double t_row = renderer.row_time(t, row, kReadout);
      const SE3 T_row = pose_at(t_row);
      double worst_distance = 0.0;
      Eigen::Vector2d shift_sum = Eigen::Vector2d::Zero();
      int n = 0;
      for (int x = 0; x < camera.width; x += 2, ++n) {
        const double z = rolling.depth.at<float>(row, x);
        ASSERT_GT(z, 0.0) << "row " << row << " x " << x;
        const Eigen::Vector2d uv(x, row);
        const Eigen::Vector3d p_w = T_row * camera.unproject(uv, z);
        const int label = rolling.labels.at<std::int16_t>(row, x);
        worst_distance =
            std::max(worst_distance, distance_to_seen_surface(scene, p_w, label, t_row));
        // Where the global-shutter (middle-row pose) image sees this point.
        shift_sum += camera.project(T_c_w_mid * p_w) - uv;
      }
      const Eigen::Vector2d shift = shift_sum / n;
      const double rgb_change =
          cv::norm(rolling.rgb.row(row), global.rgb.row(row), cv::NORM_L1) / (3.0 * camera.width);
      std::printf(
          "t %.1f row %3d: surface distance %.2g m with the row-time pose; mean shift to "
          "the global-shutter image (%.2f, %.2f) px; mean RGB change %.1f\n",
          t, row, worst_distance, shift.x(), shift.y(), rgb_change);
      EXPECT_LT(worst_distance, 1e-6) << "row " << row;
      if (row == h / 2) {
        EXPECT_LT(shift.norm(), 0.1);  // 1/960 of the readout from the middle: nearly global
      } else {
        EXPECT_GT(shift.norm(), 4.0) << "row " << row;
        EXPECT_GT(rgb_change, 5.0) << "row " << row;
      }
    }
  }
}

TEST(Renderer, ZeroReadoutTimeIsTheGlobalShutterRender) {
  const SyntheticSequence& seq = rich_sequence();
  const Renderer& renderer = seq.renderer();
  const auto pose_at = [](double time) { return camera_pose_at(time, 3.0); };
  const RenderedFrame a = renderer.render(pose_at, 0.7, 0.0);
  const RenderedFrame b = renderer.render(pose_at(0.7), 0.7);
  EXPECT_EQ(cv::norm(a.rgb, b.rgb, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(a.depth, b.depth, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(a.labels, b.labels, cv::NORM_INF), 0.0);
  // A static camera gives the global-shutter image whatever the readout time.
  const auto still = [&](double) { return seq.T_w_c(5); };
  const RenderedFrame c = renderer.render(still, 0.7, 0.05);
  const RenderedFrame d = renderer.render(seq.T_w_c(5), 0.7);
  EXPECT_EQ(cv::norm(c.rgb, d.rgb, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(c.depth, d.depth, cv::NORM_INF), 0.0);
}

TEST(Renderer, RenderTime) {
  const SyntheticSequence& seq = rich_sequence();
  const int threads = cv::getNumThreads();
  cv::setNumThreads(1);
  seq.frame(0);  // warm up
  const auto start = std::chrono::steady_clock::now();
  constexpr int kFrames = 4;
  for (int i = 0; i < kFrames; ++i) seq.frame(40 * i);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count() /
      kFrames;
  cv::setNumThreads(threads);
  std::printf("render time 640x480 single-threaded: %.1f ms/frame\n", ms);
  RecordProperty("render_ms", static_cast<int>(ms));
  EXPECT_LT(ms, 1000.0);  // generous: shared CI machines; typically ~50-100 ms
}

}  // namespace
}  // namespace mcslam::synth
