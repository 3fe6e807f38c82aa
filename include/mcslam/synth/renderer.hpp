#pragma once
// Ray-casting renderer of a synth::Scene: exact depth, anti-aliased procedural textures.
//
// Each pixel (u, v) casts the ray through its centre, direction ((u - cx) / fx, (v - cy) / fy, 1)
// in the camera frame, against the room rectangles and the object boxes (analytic ray/plane and
// slab intersections, nearest hit). depth is the z of the hit in the camera frame (not the ray
// length), so camera.unproject({u, v}, depth) is the hit point exactly (up to float rounding).
// Colour: the surface albedo, sampled trilinearly from the texture's mip pyramid at the level
// matching the pixel footprint (ray differentials), times a view-independent Lambertian shade;
// pixels on geometric edges (a neighbour sees another face) average four rotated-grid subsamples.
//
// Rolling shutter: render(T_w_c_at, t, readout_time) renders each image row with its own exposure
// time (see Renderer::row_time), like a Kinect-type sensor whose colour image and registered depth
// share the row timing: row r of the RGB, depth and label images all see the scene from the camera
// pose (and with the object poses) at that row's time.

#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/synth/scene.hpp"

namespace mcslam::synth {

struct RenderOptions {
  /// Gaussian-like (sum of four uniforms) RGB noise per channel, in grey levels; 0 disables it.
  double rgb_noise_sigma = 2.0;
  /// Kinect-like depth: see apply_kinect_depth_noise().
  bool depth_noise = false;
  /// Noise is seeded from this and the scene time t, so every frame gets its own noise and the
  /// same (pose, t) always renders the same image.
  std::uint64_t noise_seed = 1;
};

struct RenderedFrame {
  cv::Mat rgb;    ///< CV_8UC3, BGR
  cv::Mat depth;  ///< CV_32FC1, metres (z in the camera frame), 0 where invalid
  cv::Mat
      labels;  ///< CV_16SC1: index into Scene::objects seen at the pixel centre, -1 for the room
};

/// Kinect-like depth noise standard deviation (metres) at depth z: 0.0012 + 0.0019 (z - 0.4)^2.
double kinect_depth_sigma(double z);

/// Makes an exact depth image (CV_32FC1) Kinect-like, deterministically from the seed:
///  - 0 (invalid) where z < 0.4 m or z > 4.5 m, and where a 4-neighbour's depth differs by more
///    than 0.1 m (both sides of a depth discontinuity);
///  - otherwise z + N(0, kinect_depth_sigma(z)), rounded to a multiple of 1/5000 m (the 16-bit
///    PNG quantisation of TUM depth).
cv::Mat apply_kinect_depth_noise(const cv::Mat& depth, std::uint64_t seed);

class Renderer {
 public:
  /// The scene is copied (textures are shared).
  Renderer(const Scene& scene, const PinholeCamera& camera, const RenderOptions& options = {});

  /// Renders the view of camera pose T_w_c at scene time t (object poses are taken at t).
  /// Thread-safe; uses cv::parallel_for_ over rows (the result does not depend on threading).
  RenderedFrame render(const SE3& T_w_c, double t) const;

  /// Rolling-shutter render of the frame whose middle is at scene time t: image row r (RGB, depth
  /// and labels alike) is rendered with the camera pose T_w_c_at(t_r) and object poses at t_r,
  /// t_r = row_time(t, r, readout_time); so camera.unproject({u, r}, depth) is the hit point in
  /// the camera frame T_w_c_at(t_r). Noise is seeded from t, as in render(T_w_c, t). With
  /// readout_time == 0 this is exactly render(T_w_c_at(t), t). T_w_c_at is called once per row
  /// (serially); a negative readout_time reads the rows bottom to top. Throws InputError when
  /// readout_time is not finite.
  RenderedFrame render(const std::function<SE3(double)>& T_w_c_at, double t,
                       double readout_time) const;

  /// Exposure time of image row `row` (its centre) in a frame whose middle is at time t, with
  /// rows read top to bottom over readout_time seconds (bottom to top when negative):
  /// t + (row + 0.5 - H/2) / H * readout_time.
  double row_time(double t, int row, double readout_time) const;

  const Scene& scene() const { return scene_; }
  const PinholeCamera& camera() const { return camera_; }
  const RenderOptions& options() const { return options_; }

 private:
  Scene scene_;
  PinholeCamera camera_;
  RenderOptions options_;
};

}  // namespace mcslam::synth
