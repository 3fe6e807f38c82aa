// mcslam command-line interface: run, bench, eval, synth, detect, vocabulary, and with ROS
// export-bag and ros.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>

#include "mcslam/app/bench.hpp"
#include "mcslam/app/detect.hpp"
#include "mcslam/app/faults.hpp"
#include "mcslam/app/run.hpp"
#include "mcslam/app/vocabulary.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/core/thread_failure.hpp"
#include "mcslam/eval/bonn.hpp"
#include "mcslam/eval/metrics.hpp"
#include "mcslam/io/trajectory_io.hpp"
#include "mcslam/mapping/grid_change.hpp"
#include "mcslam/rosbag2/source.hpp"
#include "mcslam/slam/config.hpp"
#include "mcslam/synth/sequence.hpp"
#include "mcslam/version.hpp"
#ifdef MCSLAM_HAVE_ROS
#include "mcslam/ros/bag.hpp"
#include "mcslam/ros/node.hpp"
#endif

namespace {

/// Topic options as typed (the ROS module turns them into ros::TopicOptions).
struct TopicArgs {
  std::string preset = "tum";
  std::optional<std::string> rgb, depth, camera_info, groundtruth, world_frame, camera_frame;
};

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

bool is_bag_path(const std::string& path) {
  return std::filesystem::is_regular_file(path) ||
         (path.size() > 4 && path.compare(path.size() - 4, 4, ".bag") == 0);
}

[[noreturn, maybe_unused]] void no_ros(const std::string& what) {
  throw mcslam::InputError(what +
                           ": mcslam was built without ROS support (install the ROS packages "
                           "with scripts/install-deps.sh and rebuild)");
}

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
  if (auto e = t.check()) throw mcslam::InputError("topics: " + *e);
  return t;
}

mcslam::rosbag2::TopicOptions ros2_topic_options(const TopicArgs& a) {
  return topic_options_from<mcslam::rosbag2::TopicOptions>(a);
}

#ifdef MCSLAM_HAVE_ROS
mcslam::ros::TopicOptions topic_options(const TopicArgs& a) {
  return topic_options_from<mcslam::ros::TopicOptions>(a);
}
#endif

// Set by SIGINT/SIGTERM during `mcslam run`: the run stops after the current frame and writes its
// results (signals are process-wide, hence a file-scope flag; it never leaves this file).
volatile std::sig_atomic_t g_stop_requested = 0;

void request_stop(int) {
  g_stop_requested = 1;
  static const char kMessage[] =
      "\nmcslam: stopping after this frame and writing the results (again to kill)\n";
  (void)!::write(STDERR_FILENO, kMessage, sizeof(kMessage) - 1);
}

/// The first SIGINT or SIGTERM asks the run to stop; the handler then resets itself, so a second
/// one kills the process as usual.
void install_stop_handler() {
  struct sigaction action {};
  action.sa_handler = request_stop;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESETHAND;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

/// --viewer [PORT] and --viewer-bind ADDR, as typed.
struct ViewerArgs {
  CLI::Option* option = nullptr;
  std::vector<std::string> port;  // empty: the default port
  std::string bind = "127.0.0.1";
};

void add_viewer_options(CLI::App* cmd, ViewerArgs& v) {
  v.option = cmd->add_option("--viewer", v.port,
                             "Serve the live viewer at http://127.0.0.1:PORT/ (default port " +
                                 std::to_string(mcslam::app::ViewerServerOptions{}.port) +
                                 "; 0: any free port): frame, map, figures, pause, "
                                 "localisation only (docs/viewer.md)")
                 ->expected(0, 1);
  cmd->add_option("--viewer-bind", v.bind,
                  "Address the viewer listens on (default 127.0.0.1, this machine only; another "
                  "exposes the run, with a warning)");
}

/// The viewer's options when --viewer was given; InputError for a bad port.
void apply_viewer_args(const ViewerArgs& v, mcslam::app::RunRequest& request) {
  if (v.option->count() == 0) {
    if (v.bind != "127.0.0.1") throw mcslam::InputError("--viewer-bind: only with --viewer");
    return;
  }
  mcslam::app::ViewerOptions options;
  options.server.bind = v.bind;
  if (!v.port.empty() && !v.port.front().empty()) {  // `--viewer` alone: the default port
    const std::string& text = v.port.front();
    std::size_t used = 0;
    int port = -1;
    try {
      port = std::stoi(text, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != text.size() || port < 0 || port > 65535)
      throw mcslam::InputError("--viewer: the port must be a number from 0 to 65535, got '" + text +
                               "'");
    options.server.port = port;
  }
  request.viewer = options;
}

int run_command(mcslam::app::RunRequest request, bool quiet) {
  install_stop_handler();
  request.stop_requested = [] { return g_stop_requested != 0; };
  const nlohmann::json summary = mcslam::app::run_sequence(request);
  if (!quiet) {
    std::cout << mcslam::app::summary_text(summary);
    std::cout
        << "results in " << request.output_dir
        << " (trajectory.txt, keyframes.txt, timings.csv, summary.json, status.json, config.yaml"
        << (request.save_map ? ", map.ply, map.json" : "")
        << (summary["dynamics"]["frames_with_boxes"].get<int>() > 0 ? ", objects.json" : "")
        << (request.save_overlays ? ", overlays/" : "") << ")\n";
  }
  return summary["state"] == "interrupted" ? 130 : 0;
}

/// What `mcslam bench` was asked beyond a bench: collect, resubmit or run one task of a plan.
struct BenchActions {
  std::string executor = "local";
  std::string collect, resubmit;
  std::vector<std::string> task;  // DIR INDEX
};

/// The tables' summary after a local bench or a collect: 0 when every run succeeded, else 2.
int report_bench(const mcslam::app::BenchOutcome& outcome, const std::string& dir, bool quiet) {
  if (!quiet) std::cout << "\n" << outcome.markdown << "\n";
  if (!outcome.report_warning.empty())
    std::cerr << "mcslam bench: warning: " << outcome.report_warning << "\n";
  std::cerr << "mcslam bench: " << outcome.runs - outcome.failed << " of " << outcome.runs
            << " runs succeeded; tables in " << dir << " (results.md, results.json, runs.csv"
            << (outcome.report_path.empty() ? "" : ", report.html") << ")\n";
  if (outcome.failed > 0 || outcome.sequences_not_run > 0) {
    std::cerr << "mcslam bench: " << outcome.failed << " run(s) failed and "
              << outcome.sequences_not_run
              << " sequence(s) could not be read; see \"Failed runs\" in results.md\n";
    return 2;
  }
  return 0;
}

int task_index(const std::string& text) {
  std::size_t used = 0;
  int index = -1;
  try {
    index = std::stoi(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || index < 0)
    throw mcslam::InputError("--run-task: '" + text + "' is not a run number (0, 1, ...)");
  return index;
}

/// --collect, --resubmit-failed or --run-task on a bench folder; nullopt when none was given.
std::optional<int> bench_folder_action(const mcslam::app::BenchRequest& request,
                                       const BenchActions& actions, bool quiet) {
  const int given = !actions.collect.empty() + !actions.resubmit.empty() + !actions.task.empty();
  if (given == 0) return std::nullopt;
  if (given > 1)
    throw mcslam::InputError("--collect, --resubmit-failed and --run-task exclude each other");
  if (!request.data_roots.empty())
    throw mcslam::InputError(
        "--collect, --resubmit-failed and --run-task take a bench folder and no DATA_ROOT (the "
        "folder's plan says what runs)");
  if (!actions.collect.empty())
    return report_bench(mcslam::app::collect_bench(actions.collect, !quiet, request.report_assets),
                        actions.collect, quiet);
  if (!actions.resubmit.empty()) {
    std::cout << mcslam::app::resubmit_failed(actions.resubmit, request.slurm).message;
    return 0;
  }
  return mcslam::app::run_bench_task(actions.task.at(0), task_index(actions.task.at(1)));
}

int bench_command(mcslam::app::BenchRequest request, const BenchActions& actions, bool quiet) {
  if (actions.executor == "slurm") request.executor = mcslam::app::BenchExecutor::kSlurm;
  if (request.list_only) {
    std::cout << mcslam::app::list_sequences(request);
    return 0;
  }
  if (const auto code = bench_folder_action(request, actions, quiet)) return *code;
  if (request.data_roots.empty()) throw mcslam::InputError("bench: give at least one DATA_ROOT");
  if (request.output_dir.empty()) throw mcslam::InputError("bench: --output is required");
  if (request.executor == mcslam::app::BenchExecutor::kSlurm) {
    std::cout << mcslam::app::submit_bench(request).message;
    return 0;
  }
  return report_bench(mcslam::app::run_bench(request), request.output_dir, quiet);
}

/// The command as typed, quoted where a shell would need it.
std::string command_line(int argc, char** argv) {
  std::string line;
  for (int i = 0; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool plain = !arg.empty() && arg.find_first_of(" \t'\"$\\;&|<>*?()") == std::string::npos;
    if (!line.empty()) line += ' ';
    if (plain) {
      line += arg;
    } else {
      line += '\'';
      for (char c : arg) line += c == '\'' ? std::string("'\\''") : std::string(1, c);
      line += '\'';
    }
  }
  return line;
}

int eval_command(const std::string& gt_path, const std::string& est_path, bool bonn, bool json,
                 double max_dt) {
  mcslam::Trajectory gt = mcslam::io::read_tum_trajectory(gt_path);
  const mcslam::Trajectory est = mcslam::io::read_tum_trajectory(est_path);
  if (bonn) gt = mcslam::eval::bonn_marker_to_camera(gt);
  mcslam::eval::EvalOptions options;
  options.max_time_difference = max_dt;
  mcslam::eval::EvalReport report;
  try {
    report = mcslam::eval::evaluate(gt, est, options);
  } catch (const mcslam::InputError& e) {
    throw mcslam::InputError(
        mcslam::file_error(est_path, std::string(e.what()) + " (ground truth: " + gt_path + ")"));
  }
  if (json)
    std::cout << mcslam::eval::to_json(report).dump(2) << "\n";
  else
    std::cout << mcslam::eval::to_text(report);
  return 0;
}

int synth_command(const std::string& output, const mcslam::synth::SynthOptions& options,
                  bool quiet) {
  const bool bar = !quiet && isatty(fileno(stderr));
  mcslam::synth::write_sequence(output, options, [&](int done, int total) {
    if (bar && (done % 10 == 0 || done == total)) {
      std::fprintf(stderr, "\rrendering %d/%d", done, total);
      if (done == total) std::fputc('\n', stderr);
    }
  });
  if (!quiet) std::cout << "wrote " << options.frames << " frames to " << output << "\n";
  return 0;
}

int detect_command(const mcslam::app::DetectRequest& request, bool quiet) {
  const nlohmann::json summary = mcslam::app::detect_images(request);
  if (!quiet) {
    std::cout << mcslam::app::detect_summary_text(summary);
    std::cout << "results in " << request.output_dir << " (detections.json, annotated/)\n";
  }
  return 0;
}

}  // namespace

namespace {

/// `mcslam grid-compare REF FULL`: docs/occupancy.md.
int grid_compare_command(const std::string& ref_dir, const std::string& full_dir, bool json) {
  const mcslam::mapping::OccupancyGrid ref = mcslam::mapping::read_run_grid(ref_dir);
  const mcslam::mapping::OccupancyGrid full = mcslam::mapping::read_run_grid(full_dir);
  const mcslam::mapping::GridChange c = mcslam::mapping::compare_grids(ref, full);
  if (json) {
    std::cout << nlohmann::json{{"full_occupied_seen_by_ref", c.full_occupied_seen},
                                {"appeared", c.appeared},
                                {"appeared_rate", c.appeared_rate},
                                {"ref_occupied_seen_by_full", c.ref_occupied_seen},
                                {"vanished", c.vanished}}
                     .dump(2)
              << "\n";
    return 0;
  }
  std::cout << std::fixed << std::setprecision(2)
            << "occupied in FULL where REF saw free: " << c.appeared << " of "
            << c.full_occupied_seen << " cells REF saw (" << 100.0 * c.appeared_rate << " %)\n"
            << "free in FULL where REF had occupied: " << c.vanished << " of "
            << c.ref_occupied_seen << " cells FULL saw\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"mcslam: semantic RGB-D SLAM for dynamic indoor scenes"};
  cli.require_subcommand(1);
  cli.set_version_flag("--version", std::string("mcslam ") + MCSLAM_VERSION_STRING,
                       "Print the version and exit");

  mcslam::app::RunRequest run;
  bool quiet = false;
  bool sequential = false, threaded = false;
  auto* run_cmd = cli.add_subcommand(
      "run", "Run SLAM on a TUM-layout RGB-D sequence, a ROS 1 bag or a ROS 2 recording");
  run_cmd
      ->add_option("sequence", run.sequence_dir,
                   "Sequence folder (rgb.txt, depth.txt, ...), ROS 1 bag file or ROS 2 recording "
                   "(folder, .db3 or .mcap)")
      ->required();
  TopicArgs run_topics;
  add_topic_options(run_cmd, run_topics);
  run_cmd->add_option("--camera-preset", run.camera_preset,
                      "Camera preset (tum_fr1, tum_fr2, tum_fr3, bonn) instead of the one the "
                      "folder or file name chooses");
  run_cmd->add_option("--output,-o", run.output_dir, "Folder for the results")->required();
  run_cmd->add_option("--config,-c", run.config_path, "Settings file (mcslam or ORB-SLAM2 YAML)");
  run_cmd->add_option("--associations", run.associations_path,
                      "TUM associate.py output to use instead of timestamp association");
  run_cmd->add_option("--max-frames", run.max_frames, "Process at most N frames")
      ->check(CLI::NonNegativeNumber);
  run_cmd
      ->add_option("--first-frame", run.first_frame,
                   "Start at frame N of the sequence (0-based), as if the recording began "
                   "there")
      ->check(CLI::NonNegativeNumber);
  run_cmd->add_flag("--sequential", sequential, "Map inline after each keyframe (deterministic)");
  run_cmd->add_flag("--threaded", threaded, "Map on its own thread (the default)");
  run_cmd->add_flag("--save-map", run.save_map,
                    "Also write the map: map.ply (MeshLab, CloudCompare, Open3D) and map.json");
  run_cmd->add_option("--features", run.features,
                      "Feature kinds to use: a comma-separated subset of points,lines,planes "
                      "(default: the configuration's features.*, all on)");
  run_cmd->add_option("--model", run.model,
                      "ONNX object detector (Ultralytics YOLOv8/YOLO11 or YOLOX export) for "
                      "dynamic-object handling");
  run_cmd->add_option(
      "--detections", run.detections,
      "Per-frame boxes from a detections file (JSON, see docs/objects.md) instead of a "
      "model");
  run_cmd->add_option("--confidence", run.confidence, "Detector confidence threshold");
  run_cmd->add_flag("--wait-detections", run.wait_for_detections,
                    "Each frame waits for its own detection (default only with --sequential)");
  run_cmd->add_flag("--no-dynamics", run.no_dynamics,
                    "Keep the boxes but do not exclude dynamic objects (ablation)");
  run_cmd->add_flag("--no-occupancy", run.no_occupancy,
                    "No dense occupancy map (occupancy.bt, grid.pgm/.yaml/.png, "
                    "occupancy_voxels.ply; mapping.enabled false)");
  run_cmd->add_flag("--no-constraints", run.no_constraints,
                    "Exclude dynamic objects but skip the moving-constraint check (ablation)");
  run_cmd->add_option("--vocabulary", run.vocabulary,
                      "Bag-of-words vocabulary file (default: place.vocabulary, the one in data/)");
  run_cmd->add_flag("--no-loop-closing", run.no_loop_closing,
                    "Do not close loops (relocalisation still uses the vocabulary)");
  run_cmd->add_option("--save-session", run.save_session,
                      "Write the whole map to FILE at the end (versioned binary, checksummed)");
  run_cmd->add_option("--load-session", run.load_session,
                      "Start from the map in FILE (made with the same camera and vocabulary): the "
                      "run relocalises into it and maps on");
  run_cmd->add_flag("--localize", run.localize,
                    "With --load-session: track against the loaded map without changing it");
  run_cmd->add_option("--inject-failure", run.inject_failure,
                      "Testing: THREAD:N makes a background thread throw (mapper at keyframe N, "
                      "loop after N keyframes, detector at pass N); the run writes its outputs "
                      "so far and exits 1");
  run_cmd->add_flag("--save-overlays", run.save_overlays,
                    "Write annotated frames to overlays/ (points, lines, objects and decisions)");
  run_cmd
      ->add_option("--repeat", run.repeat,
                   "Play the sequence N times in a row as one stream (a soak run; per-pass "
                   "speed, memory, map size and ATE in the summary)")
      ->check(CLI::PositiveNumber);
  run_cmd->add_flag("--realtime", run.realtime,
                    "Deliver frames at their timestamps as a live camera does, dropping those the "
                    "pipeline cannot take in time (dropped frames and latency in the summary)");
  ViewerArgs run_viewer;
  add_viewer_options(run_cmd, run_viewer);
  run_cmd->add_flag("--quiet,-q", quiet, "No progress bar and no summary");

  // export-bag: a TUM-layout folder as a ROS 1 bag.
  std::string export_sequence, export_bag;
  std::optional<std::string> export_config, export_preset;
  std::string export_rgb_encoding = "bgr8", export_depth_encoding = "32FC1";
  std::string export_format = "ros1", export_storage = "mcap", export_compression = "none";
  TopicArgs export_topics;
  auto* export_cmd = cli.add_subcommand(
      "export-bag", "Write a TUM-layout sequence as a ROS 1 bag (needs ROS) or a ROS 2 recording");
  export_cmd->add_option("sequence", export_sequence, "Sequence folder")->required();
  export_cmd->add_option("bag", export_bag, "Bag file (ros1) or recording folder (ros2) to write")
      ->required();
  export_cmd
      ->add_option("--format", export_format, "ros1 (a .bag; default) or ros2 (a rosbag2 folder)")
      ->check(CLI::IsMember({"ros1", "ros2"}));
  export_cmd->add_option("--storage", export_storage, "ros2: mcap (default) or sqlite3")
      ->check(CLI::IsMember({"mcap", "sqlite3"}));
  export_cmd
      ->add_option("--compression", export_compression,
                   "ros2: none (default), zstd, or for mcap lz4 (MCAP chunks; sqlite3: rosbag2's "
                   "per-message zstd)")
      ->check(CLI::IsMember({"none", "lz4", "zstd"}));
  export_cmd->add_option("--config,-c", export_config, "Settings file for the camera");
  export_cmd->add_option("--camera-preset", export_preset,
                         "Camera preset instead of the one the folder name chooses");
  export_cmd
      ->add_option("--rgb-encoding", export_rgb_encoding,
                   "bgr8 (default) or rgb8; ros2 also png (CompressedImage on TOPIC/compressed)")
      ->check(CLI::IsMember({"bgr8", "rgb8", "png"}));
  export_cmd
      ->add_option("--depth-encoding", export_depth_encoding,
                   "32FC1 (metres, as the TUM bags; default) or 16UC1 (millimetres); ros2 also "
                   "png (16UC1 compressedDepth on TOPIC/compressedDepth)")
      ->check(CLI::IsMember({"32FC1", "16UC1", "png"}));
  add_topic_options(export_cmd, export_topics);
  export_cmd->add_flag("--quiet,-q", quiet, "No summary");

  // bag-info: what a ROS 1 bag or a ROS 2 recording holds.
  std::string info_path;
  bool info_json = false;
  auto* info_cmd = cli.add_subcommand(
      "bag-info", "What a ROS 1 bag or ROS 2 recording holds: storage, duration, topics, counts");
  info_cmd->add_option("path", info_path, "ROS 1 bag, ROS 2 recording folder, .db3 or .mcap")
      ->required();
  info_cmd->add_flag("--json", info_json, "As JSON (for scripts)");

  // ros: the live node.
  mcslam::app::RunRequest node_run;
  TopicArgs node_topics;
  bool node_keep_all = false, node_sequential = false;
  std::string node_prefix = "/mcslam", node_map_frame = "map", node_camera_frame = "camera";
  std::string node_floor_frame = "floor", node_odom_frame;
  double node_cloud_period = 1.0, node_grid_period = 1.0, node_odom_timeout = 0.05;
  auto* ros_cmd = cli.add_subcommand(
      "ros",
      "ROS node: SLAM on live colour + depth topics; publishes pose, TF, path, map points, the "
      "occupancy grid and voxels, the people and the annotated image (needs ROS and a running "
      "roscore)");
  ros_cmd->add_option("--output,-o", node_run.output_dir,
                      "Also write the run's results here when the node stops (Ctrl-C)");
  ros_cmd->add_option("--config,-c", node_run.config_path, "Settings file (mcslam or ORB-SLAM2)");
  ros_cmd->add_option("--camera-preset", node_run.camera_preset,
                      "Camera preset (tum_fr1, tum_fr2, tum_fr3, bonn) below the CameraInfo");
  add_topic_options(ros_cmd, node_topics);
  ros_cmd->add_option("--prefix", node_prefix,
                      "Output topics: PREFIX/pose, PREFIX/path, PREFIX/map_points, PREFIX/image, "
                      "PREFIX/grid, PREFIX/occupied_voxels, PREFIX/people");
  ros_cmd->add_option("--map-frame", node_map_frame, "Frame of the poses and the map (map)");
  ros_cmd->add_option("--camera-frame", node_camera_frame,
                      "TF frame of the camera (camera): the colour camera's optical frame");
  ros_cmd->add_option("--floor-frame", node_floor_frame,
                      "Frame of the occupancy grid, tf MAP -> FLOOR on /tf_static (floor): a "
                      "planner's global frame");
  ros_cmd->add_option("--odom-frame", node_odom_frame,
                      "The robot's odometry frame: publish tf MAP -> ODOM (REP 105) from ODOM -> "
                      "CAMERA in tf, instead of MAP -> CAMERA (default: none)");
  ros_cmd->add_option("--odom-timeout", node_odom_timeout,
                      "Seconds a frame waits for ODOM -> CAMERA at its stamp, 0-1 (default 0.05)");
  ros_cmd
      ->add_option("--cloud-period", node_cloud_period,
                   "Seconds between map point and occupied voxel clouds (default 1)")
      ->check(CLI::PositiveNumber);
  ros_cmd
      ->add_option("--grid-period", node_grid_period,
                   "Seconds between occupancy grids, sent only when the map changed (default 1)")
      ->check(CLI::PositiveNumber);
  ros_cmd->add_flag("--keep-all", node_keep_all,
                    "Process every frame (replays, tests) instead of only the newest (a robot)");
  ros_cmd->add_flag("--sequential", node_sequential,
                    "Map inline after each keyframe (deterministic; replays and tests)");
  ros_cmd->add_option("--model", node_run.model, "ONNX object detector");
  ros_cmd->add_option("--detections", node_run.detections,
                      "Boxes from a detections file, matched by the images' stamps (replays of a "
                      "recorded sequence and tests)");
  ros_cmd->add_option("--confidence", node_run.confidence, "Detector confidence threshold");
  ros_cmd->add_option("--features", node_run.features, "Subset of points,lines,planes");
  ros_cmd->add_option("--vocabulary", node_run.vocabulary, "Bag-of-words vocabulary file");
  ros_cmd->add_flag("--no-loop-closing", node_run.no_loop_closing, "Do not close loops");
  ros_cmd->add_flag("--no-occupancy", node_run.no_occupancy,
                    "No dense occupancy map: no PREFIX/grid and PREFIX/occupied_voxels");
  ros_cmd->add_flag("--save-map", node_run.save_map, "With --output: also map.ply and map.json");
  ros_cmd->add_flag("--save-overlays", node_run.save_overlays, "With --output: also overlays/");
  ViewerArgs node_viewer;
  add_viewer_options(ros_cmd, node_viewer);
  ros_cmd->add_flag("--quiet,-q", quiet, "No summary at the end");

  mcslam::app::BenchRequest bench;
  auto* bench_cmd = cli.add_subcommand(
      "bench",
      "Run every TUM-layout sequence under DATA_ROOT N times per ablation configuration "
      "(sequential for accuracy, threaded for speed), here or on a Slurm cluster; tables and "
      "report.html");
  BenchActions bench_actions;
  bench_cmd->add_option("data_root", bench.data_roots,
                        "Folder(s) searched for sequences (folders with rgb.txt and depth.txt)");
  bench_cmd->add_option("--output,-o", bench.output_dir,
                        "Folder for the results (required unless --list)");
  bench_cmd->add_option("--runs,-n", bench.runs, "Runs per configuration and mode (default 3)");
  bench_cmd
      ->add_option("--configs", bench.configs,
                   "Comma-separated subset of points,lines,planes,detection,full (default all)")
      ->delimiter(',');
  bench_cmd
      ->add_option("--modes", bench.modes,
                   "Comma-separated subset of sequential,threaded,realtime (default: "
                   "sequential,threaded; realtime: threaded with --realtime)")
      ->delimiter(',');
  bench_cmd
      ->add_option("--sequences", bench.sequences,
                   "Only sequences whose name contains one of these (comma-separated)")
      ->delimiter(',');
  bench_cmd->add_option("--model", bench.model,
                        "ONNX detector for the detection and full configurations (a sequence's "
                        "own detections.json is used first)");
  bench_cmd->add_option("--confidence", bench.confidence, "Detector confidence threshold");
  bench_cmd->add_option("--max-frames", bench.max_frames, "Frames per run (default all)");
  bench_cmd->add_option("--timeout", bench.timeout_s,
                        "Seconds after which a run is stopped and reported failed (0: none; "
                        "default 3600)");
  bench_cmd->add_option("--overlays", bench.overlays,
                        "Annotated frames per sequence in report.html (default 6)");
  bench_cmd->add_option("--report-assets", bench.report_assets,
                        "Folder with report.js (default: report/ beside the mcslam binary)");
  bench_cmd->add_flag("--list", bench.list_only, "Print the sequences found and stop");
  bench_cmd
      ->add_option("--executor", bench_actions.executor,
                   "Who runs the runs: local (this machine, the default) or slurm (one Slurm job "
                   "array, and a job collecting the results after it)")
      ->check(CLI::IsMember({"local", "slurm"}));
  bench_cmd->add_option("--jobs,-j", bench.jobs,
                        "Local executor: runs at once (default 1; more share the CPUs, and the "
                        "tables say so)");
  bench_cmd->add_option("--partition", bench.slurm.partition, "Slurm partition (sbatch default)");
  bench_cmd->add_option("--time-limit", bench.slurm.time_limit_min,
                        "Slurm time limit of each run's task, in minutes (partition default)");
  bench_cmd->add_option("--array-limit", bench.slurm.array_limit,
                        "Slurm tasks running at once (default: no limit)");
  bench_cmd->add_option("--sbatch-arg", bench.slurm.sbatch_args,
                        "Another sbatch option for the batch scripts, e.g. "
                        "--sbatch-arg=--cpus-per-task=2 (repeatable)");
  bench_cmd->add_option("--collect", bench_actions.collect,
                        "Score the runs of bench folder DIR and write its tables and report "
                        "(what the Slurm collect job does)");
  bench_cmd->add_option("--resubmit-failed", bench_actions.resubmit,
                        "Submit again to Slurm the runs of bench folder DIR that have no result");
  bench_cmd
      ->add_option("--run-task", bench_actions.task,
                   "DIR INDEX: run line INDEX (from 0) of DIR/plan.tsv (what each Slurm array "
                   "task does)")
      ->expected(2);
  bench_cmd->add_flag("--quiet,-q", quiet, "No per-run progress and no tables on stdout");

  mcslam::app::FaultRequest faults;
  std::vector<std::string> fault_texts;
  auto* faults_cmd = cli.add_subcommand(
      "faults",
      "Write a copy of a sequence with faults injected (dropped, black, frozen frames...)");
  faults_cmd->add_option("sequence", faults.sequence_dir, "Sequence folder")->required();
  faults_cmd->add_option("--output,-o", faults.output_dir, "Folder for the faulty copy")
      ->required();
  faults_cmd->add_option("--fault", fault_texts,
                         "drop-every:K, drop-burst:START:LEN, black:START:LEN, saturate:START:LEN, "
                         "zero-depth:START:LEN, freeze:START:LEN, time-jump:START:SECONDS, "
                         "kidnap:START:LEN (frames are 0-based; repeat for several; none: a "
                         "plain copy)");
  faults_cmd->add_flag("--quiet,-q", quiet, "No summary");

  std::string gt_path, est_path;
  bool bonn = false, json = false;
  double max_dt = 0.02;
  auto* eval_cmd = cli.add_subcommand("eval", "ATE and RPE of a trajectory against ground truth");
  eval_cmd->add_option("--gt", gt_path, "Ground truth (TUM format)")->required();
  eval_cmd->add_option("--est", est_path, "Estimate (TUM format)")->required();
  eval_cmd->add_flag("--bonn", bonn, "Convert Bonn marker ground truth to the camera");
  eval_cmd->add_flag("--json", json, "Print JSON");
  eval_cmd->add_option("--max-dt", max_dt, "Association window in seconds")
      ->check(CLI::PositiveNumber);

  std::string grid_ref, grid_full;
  bool grid_json = false;
  auto* grid_cmd = cli.add_subcommand(
      "grid-compare",
      "Cells occupied in one run's grid (FULL) where another's (REF) saw free: people left in "
      "the map");
  grid_cmd->add_option("REF", grid_ref, "Output folder of the reference run")->required();
  grid_cmd->add_option("FULL", grid_full, "Output folder of the run to check")->required();
  grid_cmd->add_flag("--json", grid_json, "Print JSON");

  std::string synth_output;
  mcslam::synth::SynthOptions synth_options;
  std::string texture = "rich";
  auto* synth_cmd = cli.add_subcommand("synth", "Render a synthetic RGB-D sequence (TUM layout)");
  synth_cmd->add_option("--output,-o", synth_output, "Folder to write")->required();
  synth_cmd->add_option("--frames", synth_options.frames, "Number of frames");
  synth_cmd->add_option("--seed", synth_options.seed, "Random seed of textures and noise");
  synth_cmd->add_option("--texture", texture, "rich or low")->check(CLI::IsMember({"rich", "low"}));
  synth_cmd->add_flag("--depth-noise", synth_options.depth_noise, "Kinect-like depth noise");
  synth_cmd->add_option("--speed", synth_options.speed, "Camera speed factor");
  std::string path = "wander";
  synth_cmd
      ->add_option("--path", path,
                   "Camera path: wander (looks at the +x wall, the default), loop (goes round "
                   "the room once per --loop-period seconds looking out, back to its start) or "
                   "orbit (round the objects on a 3.5 x 3 m ellipse looking in; --room-scale 2 "
                   "or more)")
      ->check(CLI::IsMember({"wander", "loop", "orbit"}));
  synth_cmd->add_option("--loop-period", synth_options.loop_period,
                        "Seconds per lap of --path loop at speed 1 (default 24)");
  synth_cmd->add_option("--room-scale", synth_options.room_scale,
                        "Scale of the room's floor plan, 1-4 (default 1: 6 x 5 m); at 2 the walls "
                        "are beyond the depth range of --depth-noise");
  synth_cmd->add_option(
      "--readout-time", synth_options.readout_time,
      "Rolling-shutter readout time in seconds (0 = global shutter; negative: rows "
      "read bottom to top)");
  synth_cmd->add_option("--width", synth_options.width, "Image width");
  synth_cmd->add_option("--height", synth_options.height, "Image height");
  auto& dyn = synth_options.dynamic;
  bool no_person = false, no_chair = false;
  synth_cmd->add_flag("--dynamic", dyn.enabled,
                      "Add people moving freely and a chair sliding on the floor (writes "
                      "objects.json and labels/ with their ground truth)");
  synth_cmd->add_flag("--no-person", no_person, "Dynamic scene without people (--people 0)");
  auto* people_opt = synth_cmd->add_option(
      "--people", dyn.people,
      "Number of people walking through the dynamic scene, 0-6 (default 1): person 2 passes "
      "close in front of the camera, 3 and 4 at the image border, 5-6 further away");
  synth_cmd->add_option("--undetected-people", dyn.undetected_people,
                        "How many of the people (the last ones) get no box in detections.json, "
                        "0..--people (default 0)");
  synth_cmd->add_flag("--no-chair", no_chair, "Dynamic scene without the chair");
  synth_cmd->add_option("--person-speed", dyn.person_speed,
                        "Person 1's peak speed (m/s); the others walk at fixed multiples of it");
  synth_cmd->add_option("--chair-speed", dyn.chair_speed, "Chair's peak speed (m/s)");
  synth_cmd->add_option("--chair-push", dyn.chair_push,
                        "Push the chair once along +x by this many metres, then it stands still "
                        "(0: it slides back and forth)");
  synth_cmd->add_option("--person-scale", dyn.person_scale, "Person 1's size factor");
  synth_cmd->add_option("--chair-scale", dyn.chair_scale, "Chair's size factor");
  synth_cmd->add_option("--start-time", dyn.start_time, "Scene time (s) when the objects start");
  synth_cmd->add_flag("--quiet,-q", quiet, "No progress");

  mcslam::app::DetectRequest detect;
  auto* detect_cmd = cli.add_subcommand(
      "detect", "Run the object detector on an image or a sequence (writes detections.json)");
  detect_cmd->add_option("input", detect.input, "Image file, or sequence folder with rgb.txt")
      ->required();
  detect_cmd->add_option("--model,-m", detect.model, "ONNX detector (YOLOv8/YOLO11 or YOLOX)")
      ->required();
  detect_cmd->add_option("--output,-o", detect.output_dir, "Folder for the results")->required();
  detect_cmd->add_option("--confidence", detect.options.confidence,
                         "Minimum detection score in (0, 1) (default 0.35)");
  detect_cmd
      ->add_option_function<std::string>(
          "--input-size",
          [&detect](const std::string& text) {
            int w = 0, h = 0;
            char x = 0, rest = 0;
            if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &rest) != 3 || x != 'x')
              throw CLI::ValidationError("--input-size", "expected WxH, e.g. 256x192");
            detect.options.input_size = cv::Size(w, h);
          },
          "Network input WxH, multiples of 32 (default: the model's own)")
      ->type_name("WxH");
  detect_cmd->add_option("--max-frames", detect.max_frames, "Process at most N images")
      ->check(CLI::NonNegativeNumber);
  detect_cmd->add_flag("--quiet,-q", quiet, "No progress bar and no summary");

  mcslam::app::VocabularyRequest vocabulary;
  auto* vocabulary_cmd = cli.add_subcommand(
      "vocabulary", "Train a bag-of-words vocabulary from the ORB features of sequences");
  vocabulary_cmd->add_option("sequences", vocabulary.sequences, "Sequence folders (TUM layout)")
      ->required();
  vocabulary_cmd->add_option("--output,-o", vocabulary.output, "Vocabulary file to write")
      ->required();
  vocabulary_cmd->add_option("--every", vocabulary.every,
                             "Use every N-th image of each sequence (default 5)");
  vocabulary_cmd->add_option("--max-images", vocabulary.max_images,
                             "At most N images per sequence (default 0: all)");
  vocabulary_cmd->add_option("--branching", vocabulary.options.branching,
                             "Children per node, 2-255 (default 10)");
  vocabulary_cmd->add_option("--depth", vocabulary.options.depth,
                             "Levels below the root, 1-16 (default 5)");
  vocabulary_cmd->add_option("--iterations", vocabulary.options.iterations,
                             "k-majority iterations per node (default 10)");
  vocabulary_cmd->add_option("--seed", vocabulary.options.seed, "Seed of the clustering");
  vocabulary_cmd->add_flag("--quiet,-q", quiet, "No progress and no summary");

  CLI11_PARSE(cli, argc, argv);
  try {
    if (run_cmd->parsed()) {
      if (sequential && threaded)
        throw CLI::ValidationError("--sequential and --threaded exclude each other");
      if (sequential) run.sequential = true;
      if (threaded) run.sequential = false;
      run.progress = !quiet && isatty(fileno(stderr));
      apply_viewer_args(run_viewer, run);
      if (mcslam::rosbag2::is_recording_path(run.sequence_dir)) {
        if (run.associations_path)
          throw mcslam::InputError("--associations: only for a sequence folder, not a recording");
        mcslam::rosbag2::SourceOptions source_options;
        source_options.topics = ros2_topic_options(run_topics);
        run.source = mcslam::rosbag2::RecordingSource::open(run.sequence_dir, source_options);
      } else if (is_bag_path(run.sequence_dir)) {
#ifdef MCSLAM_HAVE_ROS
        if (run.associations_path)
          throw mcslam::InputError("--associations: only for a sequence folder, not a bag");
        mcslam::ros::BagOptions bag_options;
        bag_options.topics = topic_options(run_topics);
        run.source = mcslam::ros::BagSource::open(run.sequence_dir, bag_options);
#else
        no_ros("run " + run.sequence_dir);
#endif
      }
      return run_command(run, quiet);
    }
    if (info_cmd->parsed()) {
      nlohmann::json info;
      if (mcslam::rosbag2::is_recording_path(info_path)) {
        info = mcslam::rosbag2::recording_info(info_path);
      } else {
#ifdef MCSLAM_HAVE_ROS
        info = mcslam::ros::bag_info(info_path);
#else
        no_ros("bag-info " + info_path);
#endif
      }
      std::cout << (info_json ? info.dump(2) + "\n" : mcslam::rosbag2::info_text(info));
      return 0;
    }
    // The TUM folder to export and its camera, as `mcslam run` resolves it.
    const auto open_export_source = [&] {
      auto source = mcslam::io::FolderSource::open(export_sequence);
      for (const auto& warning : source->warnings())
        std::cerr << "mcslam: warning: " << warning << "\n";
      return std::make_pair(
          source, mcslam::slam::resolve_run_config(export_sequence, export_config,
                                                   mcslam::io::CameraHints{}, export_preset));
    };
    if (export_cmd->parsed() && export_format == "ros2") {
      mcslam::rosbag2::ExportOptions options;
      options.topics = ros2_topic_options(export_topics);
      options.rgb_encoding = export_rgb_encoding;
      options.depth_encoding = export_depth_encoding;
      options.storage = export_storage;
      options.compression = export_compression;
      const auto [source, config] = open_export_source();
      const std::size_t frames =
          mcslam::rosbag2::export_recording(*source, config.camera, export_bag, options);
      if (!quiet)
        std::cout << "wrote " << frames << " frames to " << export_bag << " (" << export_storage
                  << ", camera from " << config.camera_source << ")\n";
      return 0;
    }
    if (export_cmd->parsed()) {
      if (export_rgb_encoding == "png" || export_depth_encoding == "png")
        throw mcslam::InputError("--rgb-encoding/--depth-encoding png: only with --format ros2");
      if (export_cmd->count("--storage") || export_cmd->count("--compression"))
        throw mcslam::InputError(
            "--storage/--compression: only with --format ros2 (a ROS 1 bag "
            "is always LZ4-compressed)");
#ifdef MCSLAM_HAVE_ROS
      mcslam::ros::ExportOptions options;
      options.topics = topic_options(export_topics);
      options.rgb_encoding = export_rgb_encoding;
      options.depth_encoding = export_depth_encoding;
      const auto [source, config] = open_export_source();
      const std::size_t frames =
          mcslam::ros::export_bag(*source, config.camera, export_bag, options);
      if (!quiet)
        std::cout << "wrote " << frames << " frames to " << export_bag << " (camera from "
                  << config.camera_source << ")\n";
      return 0;
#else
      no_ros("export-bag");
#endif
    }
    if (ros_cmd->parsed()) {
#ifdef MCSLAM_HAVE_ROS
      mcslam::ros::NodeOptions options;
      options.topics = topic_options(node_topics);
      options.prefix = node_prefix;
      options.map_frame = node_map_frame;
      options.camera_frame = node_camera_frame;
      options.floor_frame = node_floor_frame;
      options.odom_frame = node_odom_frame;
      options.odom_timeout_s = node_odom_timeout;
      options.keep_all = node_keep_all;
      options.cloud_period_s = node_cloud_period;
      options.grid_period_s = node_grid_period;
      if (node_sequential) node_run.sequential = true;
      apply_viewer_args(node_viewer, node_run);
      install_stop_handler();
      const nlohmann::json summary =
          mcslam::ros::run_node(node_run, options, [] { return g_stop_requested != 0; });
      if (!quiet && !summary.is_null()) {
        std::cout << mcslam::app::summary_text(summary);
        if (!node_run.output_dir.empty()) std::cout << "results in " << node_run.output_dir << "\n";
      }
      return 0;
#else
      no_ros("ros");
#endif
    }
    if (bench_cmd->parsed()) {
      bench.progress = !quiet;
      bench.command_line = command_line(argc, argv);
      return bench_command(bench, bench_actions, quiet);
    }
    if (faults_cmd->parsed()) {
      for (const auto& t : fault_texts) faults.faults.push_back(mcslam::app::parse_fault(t));
      const nlohmann::json report = mcslam::app::write_faulty_sequence(faults);
      if (!quiet)
        std::cout << "wrote " << report["frames_out"].get<int>() << " of "
                  << report["frames_in"].get<int>() << " frames to " << faults.output_dir
                  << " (faults.json lists the faults)\n";
      return 0;
    }
    if (detect_cmd->parsed()) {
      detect.progress = !quiet && isatty(fileno(stderr));
      return detect_command(detect, quiet);
    }
    if (vocabulary_cmd->parsed()) {
      vocabulary.progress = !quiet && isatty(fileno(stderr));
      const nlohmann::json summary = mcslam::app::train_vocabulary(vocabulary);
      if (!quiet)
        std::cout << "vocabulary: " << summary["words"].get<int>() << " words ("
                  << summary["branching"].get<int>() << "^" << summary["depth"].get<int>()
                  << " at most), " << summary["nodes"].get<int>() << " nodes, from "
                  << summary["descriptors"].get<std::size_t>() << " descriptors of "
                  << summary["images"].get<std::size_t>() << " images; "
                  << summary["bytes"].get<std::size_t>() << " bytes in " << vocabulary.output
                  << " (id " << summary["id"].get<std::string>() << "); extraction "
                  << static_cast<int>(summary["extract_seconds"].get<double>()) << " s, training "
                  << static_cast<int>(summary["train_seconds"].get<double>()) << " s\n";
      return 0;
    }
    if (eval_cmd->parsed()) return eval_command(gt_path, est_path, bonn, json, max_dt);
    if (grid_cmd->parsed()) return grid_compare_command(grid_ref, grid_full, grid_json);
    if (synth_cmd->parsed()) {
      if (texture == "low") synth_options.texture = mcslam::synth::TextureLevel::kLow;
      if (path == "loop") synth_options.path = mcslam::synth::CameraPath::kLoop;
      if (path == "orbit") synth_options.path = mcslam::synth::CameraPath::kOrbit;
      if (no_person && people_opt->count() > 0 && dyn.people > 0)
        throw mcslam::InputError("--no-person and --people " + std::to_string(dyn.people) +
                                 " exclude each other (--no-person is --people 0)");
      if (no_person) dyn.person = false;
      if (no_chair) dyn.chair = false;
      synth_options.width = synth_options.width;
      if (synth_options.width != 640 || synth_options.height != 480) {
        synth_options.cx = (synth_options.width - 1) / 2.0;
        synth_options.cy = (synth_options.height - 1) / 2.0;
        synth_options.fx = synth_options.fy = 525.0 * synth_options.width / 640.0;
      }
      return synth_command(synth_output, synth_options, quiet);
    }
  } catch (const mcslam::InputError& e) {
    std::cerr << "mcslam: error: " << e.what() << "\n";
    return 1;
  } catch (const mcslam::BackgroundThreadError& e) {
    std::cerr << "mcslam: error: " << e.what() << "\n";
    return 1;
  } catch (const CLI::Error& e) {
    return cli.exit(e);
  } catch (const std::exception& e) {
    std::cerr << "mcslam: unexpected error: " << e.what() << "\n";
    return 3;
  }
  return 0;
}
