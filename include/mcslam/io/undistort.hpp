#pragma once
// Removes the radial-tangential lens distortion of raw images. The output keeps the camera's
// own K (fx, fy, cx, cy), so the PinholeCamera intrinsics hold for undistorted images.

#include <opencv2/core.hpp>

#include "mcslam/core/camera.hpp"

namespace mcslam::io {

class Undistorter {
 public:
  /// Precomputes the remap tables once. Throws InputError when the camera has distortion but
  /// invalid parameters (see PinholeCamera::check()).
  explicit Undistorter(const PinholeCamera& camera);

  /// False when the camera has no distortion: then apply_* return their input unchanged
  /// (sharing its data, no copy).
  bool active() const { return active_; }

  /// Bilinear resampling of an image of the camera's size (any type OpenCV's remap supports).
  /// Pixels whose source lies outside the raw image become 0. Throws InputError for an image
  /// whose size differs from the camera's.
  cv::Mat apply_rgb(const cv::Mat& rgb) const;

  /// Nearest-neighbour resampling of a CV_32FC1 depth image (depths are never blended across
  /// edges); pixels whose source lies outside the raw image get 0 (no depth). Throws InputError
  /// for a wrong size or type.
  cv::Mat apply_depth(const cv::Mat& depth) const;

 private:
  void check_size(const cv::Mat& image, const char* what) const;

  bool active_ = false;
  int width_ = 0;
  int height_ = 0;
  cv::Mat linear_map_;      // CV_16SC2: raw-image pixel of each undistorted pixel
  cv::Mat linear_weights_;  // CV_16UC1: its bilinear interpolation weights
  cv::Mat nearest_map_;     // CV_16SC2: nearest raw-image pixel
};

}  // namespace mcslam::io
