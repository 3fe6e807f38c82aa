// Options and helpers several mcslam subcommands share (shared_options.hpp).
#include "shared_options.hpp"

#include <unistd.h>

#include <csignal>

#include "mcslam/app/viewer.hpp"
#include "mcslam/core/error.hpp"

namespace mcslam::cli {
namespace {

/// The topic options of a ROS 1 bag or a ROS 2 recording (mcslam::ros::TopicOptions or
/// mcslam::rosbag2::TopicOptions: the same fields; each realsense preset has its driver's names),
/// with the command line's overrides.
template <typename Topics>
Topics topic_options_from(const TopicArgs& a) {
  Topics t = Topics::preset(a.preset);
  if (a.rgb) t.rgb = *a.rgb;
  if (a.depth) t.depth = *a.depth;
  if (a.camera_info) t.camera_info = *a.camera_info;
  if (a.groundtruth) t.groundtruth = *a.groundtruth;
  if (a.world_frame) t.world_frame = *a.world_frame;
  if (a.camera_frame) t.camera_frame = *a.camera_frame;
  if (auto e = t.check()) throw InputError("topics: " + *e);
  return t;
}

// Set by SIGINT/SIGTERM during `mcslam run` and `mcslam ros`: the run stops after the current
// frame and writes its results (signals are process-wide, hence a file-scope flag; it never
// leaves this file).
volatile std::sig_atomic_t g_stop_requested = 0;

void request_stop(int) {
  g_stop_requested = 1;
  static const char kMessage[] =
      "\nmcslam: stopping after this frame and writing the results (again to kill)\n";
  (void)!::write(STDERR_FILENO, kMessage, sizeof(kMessage) - 1);
}

}  // namespace

void add_topic_options(CLI::App* cmd, TopicArgs& t) {
  cmd->add_option("--topics", t.preset,
                  "Topic names preset: tum (/camera/rgb/image_color, /camera/depth/image, "
                  "/camera/rgb/camera_info, /tf; the default) or realsense "
                  "(/camera/color/image_raw, /camera/aligned_depth_to_color/image_raw, "
                  "/camera/color/camera_info)")
      ->check(CLI::IsMember({"tum", "realsense"}));
  cmd->add_option("--rgb-topic", t.rgb, "Colour image topic (sensor_msgs/Image)");
  cmd->add_option("--depth-topic", t.depth, "Depth image topic (16UC1 mm or 32FC1 m)");
  cmd->add_option("--info-topic", t.camera_info,
                  "sensor_msgs/CameraInfo topic (\"\": none; the camera then comes from the "
                  "preset or --config)");
  cmd->add_option("--gt-topic", t.groundtruth,
                  "Ground-truth topic: TF, PoseStamped, TransformStamped or Odometry (\"\": none)");
  cmd->add_option("--gt-world-frame", t.world_frame, "Ground truth on TF: the parent frame");
  cmd->add_option("--gt-camera-frame", t.camera_frame, "Ground truth on TF: the child frame");
}

rosbag2::TopicOptions ros2_topic_options(const TopicArgs& a) {
  return topic_options_from<rosbag2::TopicOptions>(a);
}

#ifdef MCSLAM_HAVE_ROS
ros::TopicOptions topic_options(const TopicArgs& a) {
  return topic_options_from<ros::TopicOptions>(a);
}
#endif

std::optional<int> parse_int(const std::string& text) {
  std::size_t used = 0;
  int value = 0;
  try {
    value = std::stoi(text, &used);
  } catch (const std::exception&) {
    return std::nullopt;
  }
  if (used == 0 || used != text.size()) return std::nullopt;
  return value;
}

void no_ros(const std::string& what) {
  throw InputError(what +
                   ": mcslam was built without ROS support (install the ROS packages "
                   "with scripts/install-deps.sh and rebuild)");
}

void add_viewer_options(CLI::App* cmd, ViewerArgs& v) {
  v.option = cmd->add_option("--viewer", v.port,
                             "Serve the live viewer at http://127.0.0.1:PORT/ (default port " +
                                 std::to_string(app::ViewerServerOptions{}.port) +
                                 "; 0: any free port): frame, map, figures, pause, "
                                 "localisation only (docs/viewer.md)")
                 ->expected(0, 1);
  cmd->add_option("--viewer-bind", v.bind,
                  "Address the viewer listens on (default 127.0.0.1, this machine only; another "
                  "exposes the run, with a warning)");
}

void apply_viewer_args(const ViewerArgs& v, app::RunRequest& request) {
  if (v.option->count() == 0) {
    if (v.bind != "127.0.0.1") throw InputError("--viewer-bind: only with --viewer");
    return;
  }
  app::ViewerOptions options;
  options.server.bind = v.bind;
  if (!v.port.empty() && !v.port.front().empty()) {  // `--viewer` alone: the default port
    const std::string& text = v.port.front();
    const std::optional<int> port = parse_int(text);
    if (!port || *port < 0 || *port > 65535)
      throw InputError("--viewer: the port must be a number from 0 to 65535, got '" + text + "'");
    options.server.port = *port;
  }
  request.viewer = options;
}

void install_stop_handler() {
  struct sigaction action {};
  action.sa_handler = request_stop;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESETHAND;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

bool stop_requested() { return g_stop_requested != 0; }

}  // namespace mcslam::cli
