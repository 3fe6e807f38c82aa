#include "transport.hpp"

#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/synchronizer.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2/exceptions.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/MarkerArray.h>

#include <chrono>
#include <cstring>
#include <optional>
#include <thread>

#include "convert.hpp"
#include "mcslam/core/error.hpp"

namespace mcslam::ros::detail {

using Image = sensor_msgs::Image;
using Policy = message_filters::sync_policies::ApproximateTime<Image, Image>;

namespace {

geometry_msgs::Point point_of(const Eigen::Vector3d& p) {
  geometry_msgs::Point out;
  out.x = p.x();
  out.y = p.y();
  out.z = p.z();
  return out;
}

geometry_msgs::Quaternion quaternion_of(const Eigen::Quaterniond& q) {
  geometry_msgs::Quaternion out;
  out.x = q.x();
  out.y = q.y();
  out.z = q.z();
  out.w = q.w();
  return out;
}

geometry_msgs::Pose pose_of(const SE3& T) {
  geometry_msgs::Pose out;
  out.position = point_of(T.translation());
  out.orientation = quaternion_of(T.quaternion());
  return out;
}

geometry_msgs::PoseStamped stamped_pose(double timestamp, const SE3& T, const std::string& frame) {
  geometry_msgs::PoseStamped pose;
  pose.header.stamp = ::ros::Time(timestamp);
  pose.header.frame_id = frame;
  pose.pose = pose_of(T);
  return pose;
}

geometry_msgs::Transform transform_of(const SE3& T) {
  geometry_msgs::Transform out;
  out.translation.x = T.translation().x();
  out.translation.y = T.translation().y();
  out.translation.z = T.translation().z();
  out.rotation = quaternion_of(T.quaternion());
  return out;
}

SE3 se3_of(const geometry_msgs::Transform& t) {
  return SE3(Eigen::Quaterniond(t.rotation.w, t.rotation.x, t.rotation.y, t.rotation.z),
             Eigen::Vector3d(t.translation.x, t.translation.y, t.translation.z));
}

/// x, y, z (float32) and rgb (a float32 field holding 0x00RRGGBB, as PCL and rviz read it).
sensor_msgs::PointCloud2 cloud_message(const std::string& frame, const ::ros::Time& stamp,
                                       const std::vector<CloudPoint>& points) {
  sensor_msgs::PointCloud2 cloud;
  cloud.header.frame_id = frame;
  cloud.header.stamp = stamp;
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
  return cloud;
}

}  // namespace

struct Transport::Impl {
  NodeOptions options;
  Callbacks callbacks;
  ::ros::NodeHandle nh;
  message_filters::Subscriber<Image> rgb_sub, depth_sub;
  std::unique_ptr<message_filters::Synchronizer<Policy>> sync;
  ::ros::Subscriber info_sub;
  ::ros::Publisher pose_pub, lagged_pub, path_pub, cloud_pub, voxel_pub, image_pub, grid_pub,
      people_pub;
  std::unique_ptr<tf2_ros::TransformBroadcaster> broadcaster;
  std::unique_ptr<tf2_ros::StaticTransformBroadcaster> static_broadcaster;
  std::optional<SE3> sent_T_map_floor;  // the static tf map -> floor last sent
  // With an odom frame: the robot's tf (odom -> camera), heard on a thread of the listener's own.
  std::unique_ptr<tf2_ros::Buffer> tf_buffer;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener;
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
  // Advertised in every run, so that a subscriber is connected before the first lagged pose (a
  // ROS 1 publisher drops what it sends before a subscriber's connection is made); messages
  // come only with tracker.pose_filter.lag > 0.
  d.lagged_pub = d.nh.advertise<geometry_msgs::PoseStamped>(options.prefix + "/pose_lagged", 50);
  d.path_pub = d.nh.advertise<nav_msgs::Path>(options.prefix + "/path", 2, true);
  d.cloud_pub = d.nh.advertise<sensor_msgs::PointCloud2>(options.prefix + "/map_points", 1, true);
  d.voxel_pub =
      d.nh.advertise<sensor_msgs::PointCloud2>(options.prefix + "/occupied_voxels", 1, true);
  d.grid_pub = d.nh.advertise<nav_msgs::OccupancyGrid>(options.prefix + "/grid", 1, true);
  d.people_pub = d.nh.advertise<visualization_msgs::MarkerArray>(options.prefix + "/people", 5);
  d.image_pub = d.nh.advertise<Image>(options.prefix + "/image", 2);
  d.broadcaster = std::make_unique<tf2_ros::TransformBroadcaster>();
  d.static_broadcaster = std::make_unique<tf2_ros::StaticTransformBroadcaster>();
  if (!options.odom_frame.empty()) {
    d.tf_buffer = std::make_unique<tf2_ros::Buffer>();
    d.tf_listener = std::make_unique<tf2_ros::TransformListener>(*d.tf_buffer);
  }
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
  impl_->tf_listener.reset();
  ::ros::shutdown();
}

std::string Transport::publish_pose(double timestamp, const SE3& T) {
  Impl& d = *impl_;
  const geometry_msgs::PoseStamped pose = stamped_pose(timestamp, T, d.options.map_frame);
  d.pose_pub.publish(pose);
  d.path.poses.push_back(pose);
  d.path.header.stamp = pose.header.stamp;
  geometry_msgs::TransformStamped tf;
  tf.header = pose.header;
  if (d.options.odom_frame.empty()) {
    tf.child_frame_id = d.options.camera_frame;
    tf.transform = transform_of(T);
  } else {
    SE3 T_odom_camera;
    try {
      T_odom_camera =
          se3_of(d.tf_buffer
                     ->lookupTransform(d.options.odom_frame, d.options.camera_frame,
                                       pose.header.stamp, ::ros::Duration(d.options.odom_timeout_s))
                     .transform);
    } catch (const tf2::TransformException& e) {
      return e.what();
    }
    tf.child_frame_id = d.options.odom_frame;
    tf.transform = transform_of(map_to_odom(T, T_odom_camera));
  }
  d.broadcaster->sendTransform(tf);
  return {};
}

void Transport::publish_lagged_pose(double timestamp, const SE3& T) {
  impl_->lagged_pub.publish(stamped_pose(timestamp, T, impl_->options.map_frame));
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

void Transport::publish_cloud(Cloud which, double timestamp,
                              const std::vector<CloudPoint>& points) {
  const sensor_msgs::PointCloud2 cloud =
      cloud_message(impl_->options.map_frame, ::ros::Time(timestamp), points);
  (which == Cloud::kMapPoints ? impl_->cloud_pub : impl_->voxel_pub).publish(cloud);
}

void Transport::publish_grid(double timestamp, const GridMessage& grid) {
  Impl& d = *impl_;
  const ::ros::Time stamp(timestamp);
  const auto same = [](const SE3& a, const SE3& b) {
    return a.translation() == b.translation() && a.quaternion().coeffs() == b.quaternion().coeffs();
  };
  if (!d.sent_T_map_floor || !same(*d.sent_T_map_floor, grid.T_map_floor)) {
    geometry_msgs::TransformStamped tf;
    tf.header.stamp = stamp;
    tf.header.frame_id = d.options.map_frame;
    tf.child_frame_id = d.options.floor_frame;
    tf.transform = transform_of(grid.T_map_floor);
    d.static_broadcaster->sendTransform(tf);
    d.sent_T_map_floor = grid.T_map_floor;
  }
  nav_msgs::OccupancyGrid msg;
  msg.header.stamp = stamp;
  msg.header.frame_id = d.options.floor_frame;
  msg.info.map_load_time = stamp;
  msg.info.resolution = static_cast<float>(grid.resolution);
  msg.info.width = static_cast<std::uint32_t>(grid.width);
  msg.info.height = static_cast<std::uint32_t>(grid.height);
  msg.info.origin.position.x = grid.origin.x();
  msg.info.origin.position.y = grid.origin.y();
  msg.info.origin.orientation.w = 1.0;
  msg.data = grid.cells;
  d.grid_pub.publish(msg);
}

bool Transport::people_wanted() const { return impl_->people_pub.getNumSubscribers() > 0; }

void Transport::publish_people(double timestamp, const std::vector<MarkerSpec>& markers) {
  using visualization_msgs::Marker;
  visualization_msgs::MarkerArray array;
  Marker clear;
  clear.header.stamp = ::ros::Time(timestamp);
  clear.header.frame_id = impl_->options.map_frame;
  clear.action = Marker::DELETEALL;
  clear.pose.orientation.w = 1.0;
  array.markers.push_back(clear);
  for (const MarkerSpec& spec : markers) {
    Marker m;
    m.header = clear.header;
    m.ns = spec.ns;
    m.id = spec.id;
    m.action = Marker::ADD;
    m.pose.orientation.w = 1.0;
    m.scale.x = spec.scale.x();
    m.scale.y = spec.scale.y();
    m.scale.z = spec.scale.z();
    m.color.r = spec.rgba[0];
    m.color.g = spec.rgba[1];
    m.color.b = spec.rgba[2];
    m.color.a = spec.rgba[3];
    if (spec.shape == MarkerSpec::Shape::kCube) {
      m.type = Marker::CUBE;
      m.pose.position = point_of(spec.position);
    } else {
      m.type = Marker::ARROW;
      m.points = {point_of(spec.start), point_of(spec.end)};
    }
    array.markers.push_back(std::move(m));
  }
  impl_->people_pub.publish(array);
}

}  // namespace mcslam::ros::detail
