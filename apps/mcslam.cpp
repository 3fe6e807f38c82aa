// mcslam command-line interface: run, eval, synth.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>

#include "mcslam/app/run.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/eval/bonn.hpp"
#include "mcslam/eval/metrics.hpp"
#include "mcslam/io/trajectory_io.hpp"
#include "mcslam/synth/sequence.hpp"

namespace {

int run_command(const mcslam::app::RunRequest& request, bool quiet) {
  const nlohmann::json summary = mcslam::app::run_sequence(request);
  if (!quiet) {
    std::cout << mcslam::app::summary_text(summary);
    std::cout << "results in " << request.output_dir
              << " (trajectory.txt, keyframes.txt, timings.csv, summary.json, config.yaml"
              << (request.save_map ? ", map.ply, map.json" : "") << ")\n";
  }
  return 0;
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

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"mcslam: semantic RGB-D SLAM for dynamic indoor scenes"};
  cli.require_subcommand(1);

  mcslam::app::RunRequest run;
  bool quiet = false;
  bool sequential = false, threaded = false;
  auto* run_cmd = cli.add_subcommand("run", "Run SLAM on a TUM-layout RGB-D sequence");
  run_cmd->add_option("sequence", run.sequence_dir, "Sequence folder (rgb.txt, depth.txt, ...)")
      ->required();
  run_cmd->add_option("--output,-o", run.output_dir, "Folder for the results")->required();
  run_cmd->add_option("--config,-c", run.config_path, "Settings file (mcslam or ORB-SLAM2 YAML)");
  run_cmd->add_option("--associations", run.associations_path,
                      "TUM associate.py output to use instead of timestamp association");
  run_cmd->add_option("--max-frames", run.max_frames, "Process at most N frames")
      ->check(CLI::NonNegativeNumber);
  run_cmd->add_flag("--sequential", sequential, "Map inline after each keyframe (deterministic)");
  run_cmd->add_flag("--threaded", threaded, "Map on its own thread (the default)");
  run_cmd->add_flag("--save-map", run.save_map,
                    "Also write the map: map.ply (MeshLab, CloudCompare, Open3D) and map.json");
  run_cmd->add_option("--features", run.features,
                      "Feature kinds to use: a comma-separated subset of points,lines,planes "
                      "(default: the configuration's features.*, all on)");
  run_cmd->add_flag("--quiet,-q", quiet, "No progress bar and no summary");

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
  synth_cmd->add_option("--readout-time", synth_options.readout_time,
                        "Rolling-shutter readout time in seconds (0 = global shutter)");
  synth_cmd->add_option("--width", synth_options.width, "Image width");
  synth_cmd->add_option("--height", synth_options.height, "Image height");
  synth_cmd->add_flag("--quiet,-q", quiet, "No progress");

  CLI11_PARSE(cli, argc, argv);
  try {
    if (run_cmd->parsed()) {
      if (sequential && threaded)
        throw CLI::ValidationError("--sequential and --threaded exclude each other");
      if (sequential) run.sequential = true;
      if (threaded) run.sequential = false;
      run.progress = !quiet && isatty(fileno(stderr));
      return run_command(run, quiet);
    }
    if (eval_cmd->parsed()) return eval_command(gt_path, est_path, bonn, json, max_dt);
    if (synth_cmd->parsed()) {
      if (texture == "low") synth_options.texture = mcslam::synth::TextureLevel::kLow;
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
  } catch (const CLI::Error& e) {
    return cli.exit(e);
  } catch (const std::exception& e) {
    std::cerr << "mcslam: unexpected error: " << e.what() << "\n";
    return 3;
  }
  return 0;
}
