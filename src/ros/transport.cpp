#include "transport.hpp"

#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/synchronizer.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/transform_broadcaster.h>

#include <chrono>
#include <cstring>
#include <thread>

#include "convert.hpp"
#include "mcslam/core/error.hpp"

namespace mcslam::ros::detail {

using Image = sensor_msgs::Image;
using Policy = message_filters::sync_policies::ApproximateTime<Image, Image>;

struct Transport::Impl {
  NodeOptions options;
  Callbacks callbacks;
  ::ros::NodeHandle nh;
  message_filters::Subscriber<Image> rgb_sub, depth_sub;
  std::unique_ptr<message_filters::Synchronizer<Policy>> sync;
  ::ros::Subscriber info_sub;
  ::ros::Publisher pose_pub, path_pub, cloud_pub, image_pub;
  std::unique_ptr<tf2_ros::TransformBroadcaster> broadcaster;
  std::unique_ptr<::ros::AsyncSpinner> spinner;
  nav_msgs::Path path;

  void on_pair(const sensor_msgs::ImageConstPtr& rgb, const sensor_msgs::ImageConstPtr& depth) {
    try {
      TransportFrame frame;
      frame.rgb_timestamp = detail::seconds_of(rgb->header.stamp);
      frame.depth_timestamp = detail::seconds_of(depth->header.stamp);
      frame.rgb = to_bgr(*rgb, options.topics.rgb);
      frame.depth = to_depth_m(*depth, options.topics.depth);
      if (frame.depth.size() != frame.rgb.size())
        throw InputError(options.topics.depth + ": depth image is " +
                         std::to_string(frame.depth.cols) + "x" + std::to_string(frame.depth.rows) +
                         " but the colour image is " + std::to_string(frame.rgb.cols) + "x" +
                         std::to_string(frame.rgb.rows));
      callbacks.frame(std::move(frame));
    } catch (const InputError& e) {
      callbacks.error(e.what());
    }
  }
  void on_info(const sensor_msgs::CameraInfoConstPtr& info) {
    if (const auto k = intrinsics_of(*info)) callbacks.camera_info(*k, options.topics.camera_info);
  }
};

bool Transport::init(const NodeOptions& options, const std::function<bool()>& stop) {
  ::ros::init(::ros::M_string{}, "mcslam",
              ::ros::init_options::NoSigintHandler | ::ros::init_options::AnonymousName);
  const auto start = std::chrono::steady_clock::now();
  while (!::ros::master::check()) {
    if (stop()) return false;
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() >
        options.master_timeout_s)
      return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return true;
}

std::string Transport::master_uri() { return ::ros::master::getURI(); }
bool Transport::ok() { return ::ros::ok(); }

Transport::Transport(const NodeOptions& options, Callbacks callbacks)
    : impl_(std::make_unique<Impl>()) {
  Impl& d = *impl_;
  d.options = options;
  d.callbacks = std::move(callbacks);
  const std::uint32_t queue = options.keep_all ? 100 : 2;
  d.rgb_sub.subscribe(d.nh, options.topics.rgb, queue);
  d.depth_sub.subscribe(d.nh, options.topics.depth, queue);
  d.sync = std::make_unique<message_filters::Synchronizer<Policy>>(
      Policy(static_cast<std::uint32_t>(options.sync_queue)), d.rgb_sub, d.depth_sub);
  d.sync->registerCallback(&Impl::on_pair, &d);
  if (!options.topics.camera_info.empty())
    d.info_sub = d.nh.subscribe(options.topics.camera_info, 1, &Impl::on_info, &d);
  d.pose_pub = d.nh.advertise<geometry_msgs::PoseStamped>(options.prefix + "/pose", 50);
  d.path_pub = d.nh.advertise<nav_msgs::Path>(options.prefix + "/path", 2, true);
  d.cloud_pub = d.nh.advertise<sensor_msgs::PointCloud2>(options.prefix + "/map_points", 1, true);
  d.image_pub = d.nh.advertise<Image>(options.prefix + "/image", 2);
  d.broadcaster = std::make_unique<tf2_ros::TransformBroadcaster>();
  d.path.header.frame_id = options.map_frame;
  d.spinner = std::make_unique<::ros::AsyncSpinner>(2);
  d.spinner->start();
}

Transport::~Transport() { shutdown(); }

void Transport::shutdown() {
  if (!impl_->spinner) return;
  impl_->spinner->stop();
  impl_->spinner.reset();
  impl_->sync.reset();
  impl_->rgb_sub.unsubscribe();
  impl_->depth_sub.unsubscribe();
  impl_->info_sub.shutdown();
  ::ros::shutdown();
}

void Transport::publish_pose(double timestamp, const SE3& T) {
  Impl& d = *impl_;
  geometry_msgs::PoseStamped pose;
  pose.header.stamp = ::ros::Time(timestamp);
  pose.header.frame_id = d.options.map_frame;
  pose.pose.position.x = T.translation().x();
  pose.pose.position.y = T.translation().y();
  pose.pose.position.z = T.translation().z();
  pose.pose.orientation.x = T.quaternion().x();
  pose.pose.orientation.y = T.quaternion().y();
  pose.pose.orientation.z = T.quaternion().z();
  pose.pose.orientation.w = T.quaternion().w();
  d.pose_pub.publish(pose);
  geometry_msgs::TransformStamped tf;
  tf.header = pose.header;
  tf.child_frame_id = d.options.camera_frame;
  tf.transform.translation.x = pose.pose.position.x;
  tf.transform.translation.y = pose.pose.position.y;
  tf.transform.translation.z = pose.pose.position.z;
  tf.transform.rotation = pose.pose.orientation;
  d.broadcaster->sendTransform(tf);
  d.path.poses.push_back(pose);
  d.path.header.stamp = pose.header.stamp;
}

void Transport::publish_path() {
  if (!impl_->path.poses.empty()) impl_->path_pub.publish(impl_->path);
}

bool Transport::image_wanted() const { return impl_->image_pub.getNumSubscribers() > 0; }

void Transport::publish_image(double timestamp, const cv::Mat& bgr) {
  Image msg;
  msg.header.stamp = ::ros::Time(timestamp);
  msg.header.frame_id = impl_->options.camera_frame;
  fill_image(msg, bgr, "bgr8");
  impl_->image_pub.publish(msg);
}

void Transport::publish_cloud(double timestamp, const std::vector<CloudPoint>& points) {
  sensor_msgs::PointCloud2 cloud;
  cloud.header.frame_id = impl_->options.map_frame;
  cloud.header.stamp = ::ros::Time(timestamp);
  const char* names[] = {"x", "y", "z", "rgb"};
  for (std::uint32_t i = 0; i < 4; ++i) {
    sensor_msgs::PointField f;
    f.name = names[i];
    f.offset = 4 * i;
    f.datatype = sensor_msgs::PointField::FLOAT32;
    f.count = 1;
    cloud.fields.push_back(f);
  }
  cloud.point_step = 16;
  cloud.is_bigendian = false;
  cloud.is_dense = true;
  cloud.height = 1;
  cloud.width = static_cast<std::uint32_t>(points.size());
  cloud.row_step = cloud.point_step * cloud.width;
  cloud.data.resize(cloud.row_step);
  std::uint8_t* out = cloud.data.data();
  for (const CloudPoint& p : points) {
    const float xyz[3] = {p.x, p.y, p.z};
    const std::uint32_t packed =
        (std::uint32_t{p.rgb[0]} << 16) | (std::uint32_t{p.rgb[1]} << 8) | p.rgb[2];
    std::memcpy(out, xyz, 12);
    std::memcpy(out + 12, &packed, 4);
    out += 16;
  }
  impl_->cloud_pub.publish(cloud);
}

}  // namespace mcslam::ros::detail
