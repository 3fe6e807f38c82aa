// `mcslam run SEQUENCE`: SLAM on a TUM-layout folder, a ROS 1 bag or a ROS 2 recording.
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <iostream>

#include "command.hpp"
#include "mcslam/app/run.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/rosbag2/source.hpp"
#include "shared_options.hpp"

namespace mcslam::cli {
namespace {

bool is_bag_path(const std::string& path) {
  return std::filesystem::is_regular_file(path) ||
         (path.size() > 4 && path.compare(path.size() - 4, 4, ".bag") == 0);
}

class RunCommand : public Command {
 public:
  explicit RunCommand(CLI::App& cli)
      : Command(cli.add_subcommand(
            "run", "Run SLAM on a TUM-layout RGB-D sequence, a ROS 1 bag or a ROS 2 recording")) {
    CLI::App* cmd = app();
    add_input_options(cmd);
    add_detection_options(cmd);
    add_map_options(cmd);
    add_playback_options(cmd);
    add_viewer_options(cmd, viewer_);
    cmd->add_flag("--quiet,-q", quiet_, "No progress bar and no summary");
  }

  int run(int, char**) override {
    if (sequential_ && threaded_)
      throw CLI::ValidationError("--sequential and --threaded exclude each other");
    if (sequential_) request_.sequential = true;
    if (threaded_) request_.sequential = false;
    request_.progress = !quiet_ && isatty(fileno(stderr));
    apply_viewer_args(viewer_, request_);
    open_recording();
    install_stop_handler();
    request_.stop_requested = [] { return stop_requested(); };
    const nlohmann::json summary = app::run_sequence(request_);
    if (!quiet_) print_summary(summary);
    return summary["state"] == "interrupted" ? 130 : 0;
  }

 private:
  /// The sequence, its topics, camera, settings and frame range.
  void add_input_options(CLI::App* cmd) {
    cmd->add_option("sequence", request_.sequence_dir,
                    "Sequence folder (rgb.txt, depth.txt, ...), ROS 1 bag file or ROS 2 recording "
                    "(folder, .db3 or .mcap)")
        ->required();
    add_topic_options(cmd, topics_);
    cmd->add_option("--camera-preset", request_.camera_preset,
                    "Camera preset (tum_fr1, tum_fr2, tum_fr3, bonn) instead of the one the "
                    "folder or file name chooses");
    cmd->add_option("--output,-o", request_.output_dir, "Folder for the results")->required();
    cmd->add_option("--config,-c", request_.config_path,
                    "Settings file (mcslam or ORB-SLAM2 YAML)");
    cmd->add_option("--associations", request_.associations_path,
                    "TUM associate.py output to use instead of timestamp association");
    cmd->add_option("--max-frames", request_.max_frames, "Process at most N frames")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--first-frame", request_.first_frame,
                    "Start at frame N of the sequence (0-based), as if the recording began "
                    "there")
        ->check(CLI::NonNegativeNumber);
    cmd->add_flag("--sequential", sequential_, "Map inline after each keyframe (deterministic)");
    cmd->add_flag("--threaded", threaded_, "Map on its own thread (the default)");
    cmd->add_flag("--save-map", request_.save_map,
                  "Also write the map: map.ply (MeshLab, CloudCompare, Open3D) and map.json");
    cmd->add_option("--features", request_.features,
                    "Feature kinds to use: a comma-separated subset of points,lines,planes "
                    "(default: the configuration's features.*, all on)");
  }

  /// Where the boxes come from and how dynamic objects are handled.
  void add_detection_options(CLI::App* cmd) {
    cmd->add_option("--model", request_.model,
                    "ONNX object detector (Ultralytics YOLOv8/YOLO11 or YOLOX export) for "
                    "dynamic-object handling");
    cmd->add_option("--detections", request_.detections,
                    "Per-frame boxes from a detections file (JSON, see docs/objects.md) instead "
                    "of a model");
    cmd->add_option("--confidence", request_.confidence, "Detector confidence threshold");
    cmd->add_flag("--wait-detections", request_.wait_for_detections,
                  "Each frame waits for its own detection (default only with --sequential)");
    cmd->add_flag("--no-dynamics", request_.no_dynamics,
                  "Keep the boxes but do not exclude dynamic objects (ablation)");
    cmd->add_flag("--no-occupancy", request_.no_occupancy,
                  "No dense occupancy map (occupancy.bt, grid.pgm/.yaml/.png, "
                  "occupancy_voxels.ply; mapping.enabled false)");
    cmd->add_flag("--no-constraints", request_.no_constraints,
                  "Exclude dynamic objects but skip the moving-constraint check (ablation)");
  }

  /// Loop closing, sessions and the testing hook.
  void add_map_options(CLI::App* cmd) {
    cmd->add_option("--vocabulary", request_.vocabulary,
                    "Bag-of-words vocabulary file (default: place.vocabulary, the one in data/)");
    cmd->add_flag("--no-loop-closing", request_.no_loop_closing,
                  "Do not close loops (relocalisation still uses the vocabulary)");
    cmd->add_option("--save-session", request_.save_session,
                    "Write the whole map to FILE at the end (versioned binary, checksummed)");
    cmd->add_option("--load-session", request_.load_session,
                    "Start from the map in FILE (made with the same camera and vocabulary): the "
                    "run relocalises into it and maps on");
    cmd->add_flag("--localize", request_.localize,
                  "With --load-session: track against the loaded map without changing it");
    cmd->add_option("--inject-failure", request_.inject_failure,
                    "Testing: THREAD:N makes a background thread throw (mapper at keyframe N, "
                    "loop after N keyframes, detector at pass N); the run writes its outputs "
                    "so far and exits 1");
  }

  /// Overlays, soak runs and real-time playback.
  void add_playback_options(CLI::App* cmd) {
    cmd->add_flag("--save-overlays", request_.save_overlays,
                  "Write annotated frames to overlays/ (points, lines, objects and decisions)");
    cmd->add_option("--repeat", request_.repeat,
                    "Play the sequence N times in a row as one stream (a soak run; per-pass "
                    "speed, memory, map size and ATE in the summary)")
        ->check(CLI::PositiveNumber);
    cmd->add_flag("--realtime", request_.realtime,
                  "Deliver frames at their timestamps as a live camera does, dropping those the "
                  "pipeline cannot take in time (dropped frames and latency in the summary)");
  }

  /// A ROS 2 recording or a ROS 1 bag opened as the run's source (a folder opens in the run).
  void open_recording() {
    if (rosbag2::is_recording_path(request_.sequence_dir)) {
      if (request_.associations_path)
        throw InputError("--associations: only for a sequence folder, not a recording");
      rosbag2::SourceOptions source_options;
      source_options.topics = ros2_topic_options(topics_);
      request_.source = rosbag2::RecordingSource::open(request_.sequence_dir, source_options);
    } else if (is_bag_path(request_.sequence_dir)) {
#ifdef MCSLAM_HAVE_ROS
      if (request_.associations_path)
        throw InputError("--associations: only for a sequence folder, not a bag");
      ros::BagOptions bag_options;
      bag_options.topics = topic_options(topics_);
      request_.source = ros::BagSource::open(request_.sequence_dir, bag_options);
#else
      no_ros("run " + request_.sequence_dir);
#endif
    }
  }

  void print_summary(const nlohmann::json& summary) const {
    std::cout << app::summary_text(summary);
    std::cout
        << "results in " << request_.output_dir
        << " (trajectory.txt, keyframes.txt, timings.csv, summary.json, status.json, config.yaml"
        << (request_.save_map ? ", map.ply, map.json" : "")
        << (summary["dynamics"]["frames_with_boxes"].get<int>() > 0 ? ", objects.json" : "")
        << (request_.save_overlays ? ", overlays/" : "") << ")\n";
  }

  app::RunRequest request_;
  TopicArgs topics_;
  ViewerArgs viewer_;
  bool sequential_ = false, threaded_ = false, quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> make_run_command(CLI::App& cli) {
  return std::make_unique<RunCommand>(cli);
}

}  // namespace mcslam::cli
