// Helper of the ROS tests (not installed):
//   ros_test_tool mutate IN.bag OUT.bag encoding|depth-size|stamps-back
//     writes a broken copy of a bag made by `mcslam export-bag` (TUM topic names);
//   ros_test_tool play IN.bag POSES.txt TOPICS.txt EXPECTED_POSES TIMEOUT_S
//     publishes the bag's colour, depth and camera_info at their recorded rate, collects the
//     node's poses (/mcslam/pose, TUM format) and the names of the /mcslam topics and /tf
//     frames that delivered messages, until EXPECTED_POSES poses arrived or the timeout.
#include <geometry_msgs/PoseStamped.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

namespace {

const std::string kRgb = "/camera/rgb/image_color";
const std::string kDepth = "/camera/depth/image";
const std::string kInfo = "/camera/rgb/camera_info";

int mutate(const std::string& in, const std::string& out, const std::string& what) {
  rosbag::Bag src(in, rosbag::bagmode::Read);
  rosbag::Bag dst(out, rosbag::bagmode::Write);
  rosbag::View view(src);
  int rgb_count = 0;
  ros::Time previous;
  for (const rosbag::MessageInstance& m : view) {
    if (m.getTopic() == kRgb) {
      auto msg = m.instantiate<sensor_msgs::Image>();
      if (what == "encoding" && rgb_count == 3) msg->encoding = "yuv422";
      if (what == "stamps-back") {
        if (rgb_count == 5) previous = msg->header.stamp;
        if (rgb_count == 6) msg->header.stamp = previous - ros::Duration(0.01);
      }
      ++rgb_count;
      dst.write(m.getTopic(), m.getTime(), *msg);
    } else if (m.getTopic() == kDepth && what == "depth-size") {
      auto msg = m.instantiate<sensor_msgs::Image>();
      msg->width /= 2;
      msg->height /= 2;
      msg->data.resize(static_cast<std::size_t>(msg->step / 2) * msg->height);
      msg->step /= 2;
      dst.write(m.getTopic(), m.getTime(), *msg);
    } else {
      dst.write(m.getTopic(), m.getTime(), m);
    }
  }
  dst.close();
  return 0;
}

int play(const std::string& bag_path, const std::string& poses_path, const std::string& topics_path,
         std::size_t expected, double timeout_s) {
  int argc = 0;
  ros::init(argc, nullptr, "mcslam_test_player", ros::init_options::AnonymousName);
  ros::NodeHandle nh;
  std::mutex mutex;
  std::vector<geometry_msgs::PoseStamped> poses;
  std::set<std::string> seen;
  const auto mark = [&](const std::string& name) {
    std::lock_guard lock(mutex);
    seen.insert(name);
  };
  auto pose_sub = nh.subscribe<geometry_msgs::PoseStamped>(
      "/mcslam/pose", 1000, [&](const geometry_msgs::PoseStampedConstPtr& p) {
        std::lock_guard lock(mutex);
        poses.push_back(*p);
        seen.insert("/mcslam/pose");
      });
  auto path_sub = nh.subscribe<nav_msgs::Path>(
      "/mcslam/path", 10, [&](const nav_msgs::PathConstPtr&) { mark("/mcslam/path"); });
  auto cloud_sub = nh.subscribe<sensor_msgs::PointCloud2>(
      "/mcslam/map_points", 10,
      [&](const sensor_msgs::PointCloud2ConstPtr&) { mark("/mcslam/map_points"); });
  auto image_sub = nh.subscribe<sensor_msgs::Image>(
      "/mcslam/image", 10, [&](const sensor_msgs::ImageConstPtr&) { mark("/mcslam/image"); });
  auto tf_sub =
      nh.subscribe<tf2_msgs::TFMessage>("/tf", 100, [&](const tf2_msgs::TFMessageConstPtr& tf) {
        for (const auto& x : tf->transforms)
          mark("/tf:" + x.header.frame_id + "->" + x.child_frame_id);
      });
  auto rgb_pub = nh.advertise<sensor_msgs::Image>(kRgb, 1000);
  auto depth_pub = nh.advertise<sensor_msgs::Image>(kDepth, 1000);
  auto info_pub = nh.advertise<sensor_msgs::CameraInfo>(kInfo, 100, true);
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const auto start = std::chrono::steady_clock::now();
  const auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  while (rgb_pub.getNumSubscribers() == 0 || depth_pub.getNumSubscribers() == 0 ||
         info_pub.getNumSubscribers() == 0) {
    if (elapsed() > timeout_s) {
      std::cerr << "ros_test_tool: no subscriber to the input topics\n";
      return 2;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  rosbag::View view(bag, rosbag::TopicQuery(std::vector<std::string>{kRgb, kDepth, kInfo}));
  std::optional<double> first_bag, first_wall;
  for (const rosbag::MessageInstance& m : view) {
    const double t = m.getTime().toSec();
    if (!first_bag) {
      first_bag = t;
      first_wall = elapsed();
    }
    const double due = *first_wall + (t - *first_bag);
    while (elapsed() < due) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    if (m.getTopic() == kRgb) rgb_pub.publish(m.instantiate<sensor_msgs::Image>());
    if (m.getTopic() == kDepth) depth_pub.publish(m.instantiate<sensor_msgs::Image>());
    if (m.getTopic() == kInfo) info_pub.publish(m.instantiate<sensor_msgs::CameraInfo>());
  }
  for (;;) {
    {
      std::lock_guard lock(mutex);
      if (poses.size() >= expected) break;
    }
    if (elapsed() > timeout_s) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // the last path and cloud
  std::lock_guard lock(mutex);
  std::ofstream out(poses_path);
  out.precision(9);
  out << std::fixed;
  for (const auto& p : poses)
    out << p.header.stamp.toSec() << ' ' << p.pose.position.x << ' ' << p.pose.position.y << ' '
        << p.pose.position.z << ' ' << p.pose.orientation.x << ' ' << p.pose.orientation.y << ' '
        << p.pose.orientation.z << ' ' << p.pose.orientation.w << '\n';
  std::ofstream topics(topics_path);
  for (const auto& name : seen) topics << name << '\n';
  std::cerr << "ros_test_tool: " << poses.size() << " poses received (expected " << expected
            << ")\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> a(argv + 1, argv + argc);
  try {
    if (a.size() == 4 && a[0] == "mutate") return mutate(a[1], a[2], a[3]);
    if (a.size() == 6 && a[0] == "play")
      return play(a[1], a[2], a[3], std::stoul(a[4]), std::stod(a[5]));
  } catch (const std::exception& e) {
    std::cerr << "ros_test_tool: " << e.what() << "\n";
    return 2;
  }
  std::cerr << "usage: ros_test_tool mutate IN OUT encoding|depth-size|stamps-back\n"
               "       ros_test_tool play BAG POSES TOPICS EXPECTED TIMEOUT_S\n";
  return 2;
}
