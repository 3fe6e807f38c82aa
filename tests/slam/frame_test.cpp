#include "mcslam/slam/frame.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "synthetic_fixture.hpp"

namespace mcslam::slam {
namespace {

// Depth per keypoint against the rendered depth at the colour image's time.
double median_depth_error(const FrameBuilder& builder, const cv::Mat& gray, const cv::Mat& depth,
                          const cv::Mat& true_depth, const std::optional<SE3>& T_rgb_depth,
                          int* with_depth) {
  FrameMotion motion;
  motion.T_rgb_depth = T_rgb_depth;
  const Frame frame = builder.build(0, 1.0, gray, depth, motion);
  std::vector<double> errors;
  for (const auto& p : frame.features->points) {
    if (!p.has_depth()) continue;
    const float truth = true_depth.at<float>(static_cast<int>(std::lround(p.keypoint.uv.y())),
                                             static_cast<int>(std::lround(p.keypoint.uv.x())));
    if (truth > 0) errors.push_back(std::abs(p.depth - truth));
  }
  *with_depth = static_cast<int>(errors.size());
  std::sort(errors.begin(), errors.end());
  return errors.empty() ? 1e9 : errors[errors.size() / 2];
}

TEST(FrameBuilder, DepthPerKeypointAndTimeOffsetCompensation) {
  synth::SynthOptions synth_options;
  synth_options.frames = 2;
  synth_options.speed = 3.0;
  synth::SyntheticSequence seq(synth_options);
  const double t = 0.5;
  const double offset = 0.02;  // depth taken 20 ms before the colour image
  const SE3 T_w_rgb = synth::camera_pose_at(t, synth_options.speed);
  const SE3 T_w_depth = synth::camera_pose_at(t - offset, synth_options.speed);
  const auto rgb_frame = seq.renderer().render(T_w_rgb, t);
  const auto depth_frame = seq.renderer().render(T_w_depth, t - offset);
  cv::Mat gray;
  cv::cvtColor(rgb_frame.rgb, gray, cv::COLOR_BGR2GRAY);
  SystemOptions options;
  options.use.lines = false;
  options.use.planes = false;
  FrameBuilder builder(seq.camera(), options);

  int n_aligned = 0, n_raw = 0, n_comp = 0;
  const double aligned =
      median_depth_error(builder, gray, rgb_frame.depth, rgb_frame.depth, std::nullopt, &n_aligned);
  EXPECT_LT(aligned, 1e-4);
  EXPECT_GT(n_aligned, 800);
  const double raw =
      median_depth_error(builder, gray, depth_frame.depth, rgb_frame.depth, std::nullopt, &n_raw);
  const SE3 T_rgb_depth = T_w_rgb.inverse() * T_w_depth;
  const double compensated =
      median_depth_error(builder, gray, depth_frame.depth, rgb_frame.depth, T_rgb_depth, &n_comp);
  EXPECT_LT(compensated, 0.5 * raw) << "raw " << raw << " compensated " << compensated;
  EXPECT_GT(n_comp, n_raw / 2);  // edge rejection drops some, not most
}

TEST(FrameBuilder, FeaturesFoundAheadFinishAsTheFrameWouldBuildThem) {
  // System::extract_features runs detect() on another thread (another builder) before the
  // motion is known; finish() then must give the very frame build() gives, motion included.
  synth::SynthOptions synth_options;
  synth_options.frames = 2;
  synth::SyntheticSequence seq(synth_options);
  const auto rendered = seq.renderer().render(synth::camera_pose_at(0.5, synth_options.speed), 0.5);
  cv::Mat gray;
  cv::cvtColor(rendered.rgb, gray, cv::COLOR_BGR2GRAY);
  const SystemOptions options;
  const FrameBuilder builder(seq.camera(), options);
  const FrameBuilder ahead(seq.camera(), options);
  FrameMotion motion;
  motion.T_rgb_depth =
      SE3(so3_exp(Eigen::Vector3d(0.002, -0.001, 0.003)), Eigen::Vector3d(0.004, 0.001, -0.002));
  motion.angular_velocity = Eigen::Vector3d(0.3, -0.5, 0.2);
  motion.readout_time = 0.02;

  StageTimes built_times, finished_times;
  const Frame built = builder.build(7, 0.5, gray, rendered.depth, motion, &built_times);
  DetectedFeatures detected = ahead.detect(gray, rendered.depth);
  EXPECT_EQ(detected.size, gray.size());
  const Frame finished =
      builder.finish(7, 0.5, std::move(detected), gray, rendered.depth, motion, &finished_times);

  const auto& a = *built.features;
  const auto& b = *finished.features;
  ASSERT_GT(a.points.size(), 500u);
  ASSERT_GT(a.lines.size(), 10u);
  ASSERT_GE(a.planes.size(), 2u);
  ASSERT_EQ(a.points.size(), b.points.size());
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    EXPECT_EQ(a.points[i].keypoint.uv, b.points[i].keypoint.uv) << i;
    EXPECT_EQ(a.points[i].depth, b.points[i].depth) << i;
    EXPECT_EQ(a.points[i].plane, b.points[i].plane) << i;
    EXPECT_EQ(a.points[i].descriptor, b.points[i].descriptor) << i;
  }
  ASSERT_EQ(a.lines.size(), b.lines.size());
  for (std::size_t i = 0; i < a.lines.size(); ++i) {
    EXPECT_EQ(a.lines[i].start, b.lines[i].start) << i;
    EXPECT_EQ(a.lines[i].end, b.lines[i].end) << i;
    EXPECT_EQ(a.lines[i].has_depth, b.lines[i].has_depth) << i;
    EXPECT_EQ(a.lines[i].start_c, b.lines[i].start_c) << i;
    EXPECT_EQ(a.lines[i].descriptor, b.lines[i].descriptor) << i;
  }
  ASSERT_EQ(a.planes.size(), b.planes.size());
  for (std::size_t i = 0; i < a.planes.size(); ++i) {
    EXPECT_EQ(a.planes[i].normal, b.planes[i].normal) << i;
    EXPECT_EQ(a.planes[i].d, b.planes[i].d) << i;
  }
  // The grid answers for the moved keypoints in both.
  const auto near_a = a.grid.query(320.0f, 240.0f, 40.0f);
  const auto near_b = b.grid.query(320.0f, 240.0f, 40.0f);
  EXPECT_EQ(near_a, near_b);
  EXPECT_FALSE(near_a.empty());
  // Only the finishing is the loop's own work when the features came ahead.
  const auto has = [](const StageTimes& t, const std::string& name) {
    return std::any_of(t.stages.begin(), t.stages.end(),
                       [&](const auto& s) { return s.first == name; });
  };
  EXPECT_TRUE(has(built_times, "orb_extract"));
  EXPECT_TRUE(has(built_times, "feature_finish"));
  EXPECT_FALSE(has(finished_times, "orb_extract"));
  EXPECT_TRUE(has(finished_times, "feature_finish"));
}

}  // namespace
}  // namespace mcslam::slam
