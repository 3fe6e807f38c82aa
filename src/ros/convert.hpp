#pragma once
// sensor_msgs/Image <-> cv::Mat for the ROS module (private).

#include <ros/time.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "mcslam/io/frame_source.hpp"

namespace mcslam::ros::detail {

/// A stamp in seconds: the double nearest to its exact decimal value sec.nsec, as a TUM list's
/// "1305031229.528748" reads. ros::Time::toSec() (sec + 1e-9 nsec) can be one ulp off that, and
/// a run is not then the folder's bit for bit: the motion prediction scales with the frame's
/// interval.
double seconds_of(const ::ros::Time& stamp);

/// Colour image as 8-bit BGR (rgb8, bgr8, mono8, rgba8, bgra8). Throws InputError prefixed by
/// `where` for another encoding or a message whose data is shorter than its size says.
cv::Mat to_bgr(const sensor_msgs::Image& msg, const std::string& where);
/// Depth in metres, CV_32FC1 (16UC1 millimetres, 32FC1 metres; NaN and inf become 0).
cv::Mat to_depth_m(const sensor_msgs::Image& msg, const std::string& where);
/// Checks encoding and data size only (what to_bgr / to_depth_m would throw).
void check_image(const sensor_msgs::Image& msg, bool depth, const std::string& where);

/// The intrinsics of a CameraInfo: K, the size and, for the plumb_bob and rational_polynomial
/// models, the first five distortion coefficients (k1 k2 p1 p2 k3). Empty when K has no focal
/// length. `ignored_distortion`, when given, tells whether another model had non-zero
/// coefficients, which are then not used.
std::optional<io::CameraHints::Intrinsics> intrinsics_of(const sensor_msgs::CameraInfo& info,
                                                         bool* ignored_distortion = nullptr);

/// Fills msg (header left as is) from a CV_8UC3 BGR image ("bgr8" or "rgb8") or a CV_32FC1
/// depth image in metres ("32FC1", or "16UC1" in millimetres).
void fill_image(sensor_msgs::Image& msg, const cv::Mat& image, const std::string& encoding);

}  // namespace mcslam::ros::detail
