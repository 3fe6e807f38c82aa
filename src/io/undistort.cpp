#include "mcslam/io/undistort.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "mcslam/core/error.hpp"

namespace mcslam::io {

Undistorter::Undistorter(const PinholeCamera& camera)
    : active_(camera.has_distortion()), width_(camera.width), height_(camera.height) {
  if (!active_) return;
  if (const auto problem = camera.check()) throw InputError("camera: " + *problem);
  const cv::Matx33d K(camera.fx, 0.0, camera.cx, 0.0, camera.fy, camera.cy, 0.0, 0.0, 1.0);
  const auto& d = camera.distortion;
  const cv::Matx<double, 1, 5> distortion(d[0], d[1], d[2], d[3], d[4]);
  cv::Mat map_x, map_y;
  cv::initUndistortRectifyMap(K, distortion, cv::noArray(), K, cv::Size(width_, height_), CV_32FC1,
                              map_x, map_y);
  // Fixed-point tables remap several times faster than float ones (1/32 px interpolation
  // steps for the colour image; whole pixels for the nearest-neighbour depth).
  cv::convertMaps(map_x, map_y, linear_map_, linear_weights_, CV_16SC2, false);
  cv::Mat unused;
  cv::convertMaps(map_x, map_y, nearest_map_, unused, CV_16SC2, true);
}

void Undistorter::check_size(const cv::Mat& image, const char* what) const {
  if (image.cols != width_ || image.rows != height_)
    throw InputError(std::string(what) + " image size " + std::to_string(image.cols) + "x" +
                     std::to_string(image.rows) + " differs from the camera's " +
                     std::to_string(width_) + "x" + std::to_string(height_));
}

cv::Mat Undistorter::apply_rgb(const cv::Mat& rgb) const {
  if (!active_) return rgb;
  check_size(rgb, "RGB");
  cv::Mat out;
  cv::remap(rgb, out, linear_map_, linear_weights_, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
            cv::Scalar::all(0));
  return out;
}

cv::Mat Undistorter::apply_depth(const cv::Mat& depth) const {
  if (!active_) return depth;
  if (depth.type() != CV_32FC1) throw InputError("depth image must be CV_32FC1 (metres)");
  check_size(depth, "depth");
  cv::Mat out;
  cv::remap(depth, out, nearest_map_, cv::noArray(), cv::INTER_NEAREST, cv::BORDER_CONSTANT,
            cv::Scalar::all(0));
  return out;
}

}  // namespace mcslam::io
