// Helper of the ROS tests (not installed):
//   ros_test_tool mutate IN.bag OUT.bag encoding|depth-size|stamps-back
//     writes a broken copy of a bag made by `mcslam export-bag` (TUM topic names);
//   ros_test_tool play IN.bag POSES.txt TOPICS.txt EXPECTED_POSES TIMEOUT_S [ODOM_CAMERA
//   MAP_ODOM.txt]
//     publishes the bag's colour, depth and camera_info at their recorded rate, collects the
//     node's poses (/mcslam/pose, TUM format) and the names of the /mcslam topics and /tf and
//     /tf_static transforms (parent->child) that delivered messages, with some facts about them
//     (TOPIC:fact: /mcslam/occupied_voxels:points, /mcslam/people:deleteall-first and
//     /mcslam/people:cube), until EXPECTED_POSES poses arrived or the timeout. With
//     ODOM_CAMERA ("x,y,z,qx,qy,qz,qw"), it also broadcasts that constant transform odom ->
//     camera on /tf, stamped with each colour image's stamp just before the image, and writes
//     the node's map -> odom transforms to MAP_ODOM.txt (TUM format).
//   ros_test_tool grid TOPIC TIMEOUT_S
//     subscribes to a nav_msgs/OccupancyGrid topic and prints the first message's frame, width,
//     height, resolution and its occupied, free and unknown cells; exit 1 when none arrives.
#include <geometry_msgs/PoseStamped.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>
#include <tf2_ros/transform_broadcaster.h>
#include <visualization_msgs/MarkerArray.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iostream>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
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

/// What the node publishes, as the player receives it (callbacks on the spinner's thread).
struct Recorder {
  std::mutex mutex;
  std::vector<geometry_msgs::PoseStamped> poses, lagged;
  std::vector<geometry_msgs::TransformStamped> map_odom;
  std::set<std::string> seen;
  std::vector<ros::Subscriber> subs;

  void mark(const std::string& name) {
    std::lock_guard lock(mutex);
    seen.insert(name);
  }
  template <class M>
  void mark_on(ros::NodeHandle& nh, const std::string& topic) {
    subs.push_back(
        nh.subscribe<M>(topic, 10, [this, topic](const typename M::ConstPtr&) { mark(topic); }));
  }
  void on_tf(const tf2_msgs::TFMessageConstPtr& tf, const std::string& topic) {
    std::lock_guard lock(mutex);
    for (const auto& x : tf->transforms) {
      seen.insert(topic + ":" + x.header.frame_id + "->" + x.child_frame_id);
      if (x.header.frame_id == "map" && x.child_frame_id == "odom") map_odom.push_back(x);
    }
  }
  void on_people(const visualization_msgs::MarkerArrayConstPtr& array) {
    using visualization_msgs::Marker;
    std::lock_guard lock(mutex);
    seen.insert("/mcslam/people");
    if (!array->markers.empty() && array->markers.front().action == Marker::DELETEALL)
      seen.insert("/mcslam/people:deleteall-first");
    for (const Marker& m : array->markers)
      if (m.type == Marker::CUBE && m.action == Marker::ADD) seen.insert("/mcslam/people:cube");
  }

  /// Every subscription hears the node, so that nothing it sends from its first frame on is
  /// missed. /tf has a second publisher, this process's own (the player's broadcaster advertises
  /// it): one publisher there may be the player alone, and the node's first transforms were lost
  /// (CI, stop 63: 52 of 60 map -> odom received).
  bool connected() const {
    for (const ros::Subscriber& sub : subs)
      if (sub.getNumPublishers() < (sub.getTopic() == "/tf" ? 2u : 1u)) return false;
    return true;
  }
  void subscribe(ros::NodeHandle& nh) {
    subs.push_back(nh.subscribe<geometry_msgs::PoseStamped>(
        "/mcslam/pose", 1000, [this](const geometry_msgs::PoseStampedConstPtr& p) {
          std::lock_guard lock(mutex);
          poses.push_back(*p);
          seen.insert("/mcslam/pose");
        }));
    subs.push_back(nh.subscribe<geometry_msgs::PoseStamped>(
        "/mcslam/pose_lagged", 1000, [this](const geometry_msgs::PoseStampedConstPtr& p) {
          std::lock_guard lock(mutex);
          lagged.push_back(*p);
          seen.insert("/mcslam/pose_lagged");
        }));
    mark_on<nav_msgs::Path>(nh, "/mcslam/path");
    mark_on<sensor_msgs::PointCloud2>(nh, "/mcslam/map_points");
    mark_on<sensor_msgs::Image>(nh, "/mcslam/image");
    mark_on<nav_msgs::OccupancyGrid>(nh, "/mcslam/grid");
    subs.push_back(nh.subscribe<sensor_msgs::PointCloud2>(
        "/mcslam/occupied_voxels", 10, [this](const sensor_msgs::PointCloud2ConstPtr& c) {
          mark("/mcslam/occupied_voxels");
          if (c->width * c->height > 0) mark("/mcslam/occupied_voxels:points");
        }));
    subs.push_back(nh.subscribe<visualization_msgs::MarkerArray>(
        "/mcslam/people", 100,
        [this](const visualization_msgs::MarkerArrayConstPtr& a) { on_people(a); }));
    for (const std::string topic : {"/tf", "/tf_static"})
      subs.push_back(nh.subscribe<tf2_msgs::TFMessage>(
          topic, 100, [this, topic](const tf2_msgs::TFMessageConstPtr& tf) { on_tf(tf, topic); }));
  }

  static void write_poses(const std::string& path,
                          const std::vector<geometry_msgs::PoseStamped>& list) {
    std::ofstream out(path);
    out.precision(9);
    out << std::fixed;
    for (const auto& p : list)
      out << p.header.stamp.toSec() << ' ' << p.pose.position.x << ' ' << p.pose.position.y << ' '
          << p.pose.position.z << ' ' << p.pose.orientation.x << ' ' << p.pose.orientation.y << ' '
          << p.pose.orientation.z << ' ' << p.pose.orientation.w << '\n';
  }

  /// Writes the files (the lagged poses, if any, to POSES.lagged); returns the number of poses
  /// received.
  std::size_t write(const std::string& poses_path, const std::string& topics_path,
                    const std::string& map_odom_path) {
    std::lock_guard lock(mutex);
    write_poses(poses_path, poses);
    if (!lagged.empty()) write_poses(poses_path + ".lagged", lagged);
    std::ofstream topics(topics_path);
    for (const auto& name : seen) topics << name << '\n';
    if (map_odom_path.empty()) return poses.size();
    std::ofstream tf(map_odom_path);
    tf.precision(9);
    tf << std::fixed;
    for (const auto& x : map_odom) {
      const auto& t = x.transform;
      tf << x.header.stamp.toSec() << ' ' << t.translation.x << ' ' << t.translation.y << ' '
         << t.translation.z << ' ' << t.rotation.x << ' ' << t.rotation.y << ' ' << t.rotation.z
         << ' ' << t.rotation.w << '\n';
    }
    return poses.size();
  }
};

/// "x,y,z,qx,qy,qz,qw" as the transform parent -> child.
geometry_msgs::TransformStamped parse_transform(const std::string& text, const std::string& parent,
                                                const std::string& child) {
  std::vector<double> v;
  std::stringstream in(text);
  for (std::string item; std::getline(in, item, ',');) v.push_back(std::stod(item));
  if (v.size() != 7) throw std::runtime_error("ODOM_CAMERA: give x,y,z,qx,qy,qz,qw");
  geometry_msgs::TransformStamped t;
  t.header.frame_id = parent;
  t.child_frame_id = child;
  t.transform.translation.x = v[0];
  t.transform.translation.y = v[1];
  t.transform.translation.z = v[2];
  t.transform.rotation.x = v[3];
  t.transform.rotation.y = v[4];
  t.transform.rotation.z = v[5];
  t.transform.rotation.w = v[6];
  return t;
}

/// Options of `play` beyond the bag and the output files.
struct PlayOptions {
  std::size_t expected = 0;
  double timeout_s = 0.0;
  std::optional<geometry_msgs::TransformStamped> odom_camera;
  std::string map_odom_path;
};

/// Publishes the bag's images and camera info at their recorded rate (and the odom -> camera
/// transform before each colour image, when given). Its publishers live as long as it does: a
/// publisher that goes right after its last message may drop it.
struct Player {
  ros::Publisher rgb_pub, depth_pub, info_pub;
  tf2_ros::TransformBroadcaster broadcaster;

  explicit Player(ros::NodeHandle& nh)
      : rgb_pub(nh.advertise<sensor_msgs::Image>(kRgb, 1000)),
        depth_pub(nh.advertise<sensor_msgs::Image>(kDepth, 1000)),
        info_pub(nh.advertise<sensor_msgs::CameraInfo>(kInfo, 100, true)) {}

  bool subscribed() const {
    return rgb_pub.getNumSubscribers() > 0 && depth_pub.getNumSubscribers() > 0 &&
           info_pub.getNumSubscribers() > 0;
  }

  void publish(const std::string& bag_path, const PlayOptions& options,
               const std::function<double()>& elapsed) {
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
      if (m.getTopic() == kRgb) {
        const auto image = m.instantiate<sensor_msgs::Image>();
        if (options.odom_camera) {
          geometry_msgs::TransformStamped tf = *options.odom_camera;
          tf.header.stamp = image->header.stamp;
          broadcaster.sendTransform(tf);
        }
        rgb_pub.publish(image);
      }
      if (m.getTopic() == kDepth) depth_pub.publish(m.instantiate<sensor_msgs::Image>());
      if (m.getTopic() == kInfo) info_pub.publish(m.instantiate<sensor_msgs::CameraInfo>());
    }
  }
};

int play(const std::string& bag_path, const std::string& poses_path, const std::string& topics_path,
         const PlayOptions& options) {
  int argc = 0;
  ros::init(argc, nullptr, "mcslam_test_player", ros::init_options::AnonymousName);
  ros::NodeHandle nh;
  Recorder recorder;
  recorder.subscribe(nh);
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const auto start = std::chrono::steady_clock::now();
  const auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  // The node subscribes to the player, and the recorder hears every topic of the node.
  Player player(nh);
  while (!player.subscribed() || !recorder.connected()) {
    if (elapsed() > options.timeout_s) {
      std::cerr << "ros_test_tool: no subscriber to the input topics, or not every output "
                   "topic connected\n";
      return 2;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  player.publish(bag_path, options, elapsed);
  for (;;) {
    {
      std::lock_guard lock(recorder.mutex);
      if (recorder.poses.size() >= options.expected) break;
    }
    if (elapsed() > options.timeout_s) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // the last path and cloud
  const std::size_t received = recorder.write(poses_path, topics_path, options.map_odom_path);
  std::cerr << "ros_test_tool: " << received << " poses received (expected " << options.expected
            << ")\n";
  return 0;
}

/// The first grid on `topic`: its frame, size, resolution and cells by value.
int grid(const std::string& topic, double timeout_s) {
  int argc = 0;
  ros::init(argc, nullptr, "mcslam_test_grid", ros::init_options::AnonymousName);
  ros::NodeHandle nh;
  std::mutex mutex;
  std::optional<nav_msgs::OccupancyGrid> received;
  auto sub = nh.subscribe<nav_msgs::OccupancyGrid>(topic, 1,
                                                   [&](const nav_msgs::OccupancyGridConstPtr& g) {
                                                     std::lock_guard lock(mutex);
                                                     if (!received) received = *g;
                                                   });
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    {
      std::lock_guard lock(mutex);
      if (received) break;
    }
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() >
        timeout_s) {
      std::cerr << "ros_test_tool: no grid on " << topic << " within " << timeout_s << " s\n";
      return 1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  std::lock_guard lock(mutex);
  std::size_t occupied = 0, free = 0, unknown = 0;
  for (const std::int8_t c : received->data) {
    occupied += c == 100;
    free += c == 0;
    unknown += c == -1;
  }
  std::cout << received->header.frame_id << ' ' << received->info.width << ' '
            << received->info.height << ' ' << received->info.resolution << ' ' << occupied << ' '
            << free << ' ' << unknown << ' ' << received->data.size() << '\n';
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> a(argv + 1, argv + argc);
  try {
    if (a.size() == 4 && a[0] == "mutate") return mutate(a[1], a[2], a[3]);
    if ((a.size() == 6 || a.size() == 8) && a[0] == "play") {
      PlayOptions options;
      options.expected = std::stoul(a[4]);
      options.timeout_s = std::stod(a[5]);
      if (a.size() == 8) {
        options.odom_camera = parse_transform(a[6], "odom", "camera");
        options.map_odom_path = a[7];
      }
      return play(a[1], a[2], a[3], options);
    }
    if (a.size() == 3 && a[0] == "grid") return grid(a[1], std::stod(a[2]));
  } catch (const std::exception& e) {
    std::cerr << "ros_test_tool: " << e.what() << "\n";
    return 2;
  }
  std::cerr << "usage: ros_test_tool mutate IN OUT encoding|depth-size|stamps-back\n"
               "       ros_test_tool play BAG POSES TOPICS EXPECTED TIMEOUT_S "
               "[ODOM_CAMERA MAP_ODOM]\n"
               "       ros_test_tool grid TOPIC TIMEOUT_S\n";
  return 2;
}
