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

}  // namespace
}  // namespace mcslam::slam
