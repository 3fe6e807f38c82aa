// `mcslam ros`: the live ROS node (SLAM on colour and depth topics, publishing its results).
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "command.hpp"
#include "mcslam/app/run.hpp"
#include "shared_options.hpp"
#ifdef MCSLAM_HAVE_ROS
#include "mcslam/ros/node.hpp"
#endif

namespace mcslam::cli {
namespace {

class RosCommand : public Command {
 public:
  explicit RosCommand(CLI::App& cli)
      : Command(cli.add_subcommand(
            "ros",
            "ROS node: SLAM on live colour + depth topics; publishes pose, TF, path, map points, "
            "the occupancy grid and voxels, the people and the annotated image (needs ROS and a "
            "running roscore)")) {
    add_input_options(app());
    add_frame_options(app());
    add_run_options(app());
    add_viewer_options(app(), viewer_);
    app()->add_flag("--quiet,-q", quiet_, "No summary at the end");
  }

  int run(int, char**) override {
#ifdef MCSLAM_HAVE_ROS
    ros::NodeOptions options;
    options.topics = topic_options(topics_);
    options.prefix = prefix_;
    options.map_frame = map_frame_;
    options.camera_frame = camera_frame_;
    options.floor_frame = floor_frame_;
    options.odom_frame = odom_frame_;
    options.odom_timeout_s = odom_timeout_;
    options.keep_all = keep_all_;
    options.cloud_period_s = cloud_period_;
    options.grid_period_s = grid_period_;
    if (sequential_) request_.sequential = true;
    apply_viewer_args(viewer_, request_);
    install_stop_handler();
    const nlohmann::json summary =
        ros::run_node(request_, options, [] { return stop_requested(); });
    if (!quiet_ && !summary.is_null()) {
      std::cout << app::summary_text(summary);
      if (!request_.output_dir.empty()) std::cout << "results in " << request_.output_dir << "\n";
    }
    return 0;
#else
    no_ros("ros");
#endif
  }

 private:
  /// The results folder, the settings and the topics to read.
  void add_input_options(CLI::App* cmd) {
    cmd->add_option("--output,-o", request_.output_dir,
                    "Also write the run's results here when the node stops (Ctrl-C)");
    cmd->add_option("--config,-c", request_.config_path, "Settings file (mcslam or ORB-SLAM2)");
    cmd->add_option("--camera-preset", request_.camera_preset,
                    "Camera preset (tum_fr1, tum_fr2, tum_fr3, bonn) below the CameraInfo");
    add_topic_options(cmd, topics_);
  }

  /// The topics and TF frames the node publishes, and how often.
  void add_frame_options(CLI::App* cmd) {
    cmd->add_option("--prefix", prefix_,
                    "Output topics: PREFIX/pose, PREFIX/path, PREFIX/map_points, PREFIX/image, "
                    "PREFIX/grid, PREFIX/occupied_voxels, PREFIX/people");
    cmd->add_option("--map-frame", map_frame_, "Frame of the poses and the map (map)");
    cmd->add_option("--camera-frame", camera_frame_,
                    "TF frame of the camera (camera): the colour camera's optical frame");
    cmd->add_option("--floor-frame", floor_frame_,
                    "Frame of the occupancy grid, tf MAP -> FLOOR on /tf_static (floor): a "
                    "planner's global frame");
    cmd->add_option("--odom-frame", odom_frame_,
                    "The robot's odometry frame: publish tf MAP -> ODOM (REP 105) from ODOM -> "
                    "CAMERA in tf, instead of MAP -> CAMERA (default: none)");
    cmd->add_option("--odom-timeout", odom_timeout_,
                    "Seconds a frame waits for ODOM -> CAMERA at its stamp, 0-1 (default 0.05)");
    cmd->add_option("--cloud-period", cloud_period_,
                    "Seconds between map point and occupied voxel clouds (default 1)")
        ->check(CLI::PositiveNumber);
    cmd->add_option("--grid-period", grid_period_,
                    "Seconds between occupancy grids, sent only when the map changed (default 1)")
        ->check(CLI::PositiveNumber);
  }

  /// How frames are taken and what the run does with them, as in `mcslam run`.
  void add_run_options(CLI::App* cmd) {
    cmd->add_flag("--keep-all", keep_all_,
                  "Process every frame (replays, tests) instead of only the newest (a robot)");
    cmd->add_flag("--sequential", sequential_,
                  "Map inline after each keyframe (deterministic; replays and tests)");
    cmd->add_option("--model", request_.model, "ONNX object detector");
    cmd->add_option("--detections", request_.detections,
                    "Boxes from a detections file, matched by the images' stamps (replays of a "
                    "recorded sequence and tests)");
    cmd->add_option("--confidence", request_.confidence, "Detector confidence threshold");
    cmd->add_option("--features", request_.features, "Subset of points,lines,planes");
    cmd->add_option("--vocabulary", request_.vocabulary, "Bag-of-words vocabulary file");
    cmd->add_flag("--no-loop-closing", request_.no_loop_closing, "Do not close loops");
    cmd->add_flag("--no-occupancy", request_.no_occupancy,
                  "No dense occupancy map: no PREFIX/grid and PREFIX/occupied_voxels");
    cmd->add_flag("--save-map", request_.save_map, "With --output: also map.ply and map.json");
    cmd->add_flag("--save-overlays", request_.save_overlays, "With --output: also overlays/");
  }

  app::RunRequest request_;
  TopicArgs topics_;
  ViewerArgs viewer_;
  bool keep_all_ = false, sequential_ = false, quiet_ = false;
  std::string prefix_ = "/mcslam", map_frame_ = "map", camera_frame_ = "camera";
  std::string floor_frame_ = "floor", odom_frame_;
  double cloud_period_ = 1.0, grid_period_ = 1.0, odom_timeout_ = 0.05;
};

}  // namespace

std::unique_ptr<Command> make_ros_command(CLI::App& cli) {
  return std::make_unique<RosCommand>(cli);
}

}  // namespace mcslam::cli
