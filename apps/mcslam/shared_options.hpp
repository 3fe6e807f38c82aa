// Options and helpers several mcslam subcommands share: ROS topic names, the live viewer, the
// stop signal, and the message of a build without ROS.
#pragma once

#include <CLI/CLI.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/app/run.hpp"
#include "mcslam/rosbag2/source.hpp"
#ifdef MCSLAM_HAVE_ROS
#include "mcslam/ros/bag.hpp"
#endif

namespace mcslam::cli {

/// Topic options as typed (the ROS modules turn them into their TopicOptions).
struct TopicArgs {
  std::string preset = "tum";
  std::optional<std::string> rgb, depth, camera_info, groundtruth, world_frame, camera_frame;
};

/// --topics, --rgb-topic, --depth-topic, --info-topic, --gt-topic and the ground truth's frames.
void add_topic_options(CLI::App* cmd, TopicArgs& t);

/// The topics of a ROS 2 recording (InputError for an inconsistent set).
rosbag2::TopicOptions ros2_topic_options(const TopicArgs& a);

#ifdef MCSLAM_HAVE_ROS
/// The topics of a ROS 1 bag or the live node (InputError for an inconsistent set).
ros::TopicOptions topic_options(const TopicArgs& a);
#endif

/// The whole of `text` as an int (leading blanks allowed, as std::stoi); nullopt otherwise.
std::optional<int> parse_int(const std::string& text);

/// Throws the InputError of a ROS command in a build without ROS.
[[noreturn]] void no_ros(const std::string& what);

/// --viewer [PORT] and --viewer-bind ADDR, as typed.
struct ViewerArgs {
  CLI::Option* option = nullptr;
  std::vector<std::string> port;  // empty: the default port
  std::string bind = "127.0.0.1";
};

void add_viewer_options(CLI::App* cmd, ViewerArgs& v);

/// The viewer's options when --viewer was given; InputError for a bad port.
void apply_viewer_args(const ViewerArgs& v, app::RunRequest& request);

/// The first SIGINT or SIGTERM asks the run to stop (stop_requested() turns true); the handler
/// then resets itself, so a second one kills the process as usual.
void install_stop_handler();
bool stop_requested();

}  // namespace mcslam::cli
