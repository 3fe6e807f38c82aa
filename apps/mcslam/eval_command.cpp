// `mcslam eval --gt GT --est EST`: ATE and RPE of a trajectory against ground truth.
#include <iostream>
#include <string>

#include "command.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/eval/bonn.hpp"
#include "mcslam/eval/metrics.hpp"
#include "mcslam/io/trajectory_io.hpp"

namespace mcslam::cli {
namespace {

class EvalCommand : public Command {
 public:
  explicit EvalCommand(CLI::App& cli)
      : Command(cli.add_subcommand("eval", "ATE and RPE of a trajectory against ground truth")) {
    app()->add_option("--gt", gt_path_, "Ground truth (TUM format)")->required();
    app()->add_option("--est", est_path_, "Estimate (TUM format)")->required();
    app()->add_flag("--bonn", bonn_, "Convert Bonn marker ground truth to the camera");
    app()->add_flag("--json", json_, "Print JSON");
    app()
        ->add_option("--max-dt", max_dt_, "Association window in seconds")
        ->check(CLI::PositiveNumber);
  }

  int run(int, char**) override {
    Trajectory gt = io::read_tum_trajectory(gt_path_);
    const Trajectory est = io::read_tum_trajectory(est_path_);
    if (bonn_) gt = eval::bonn_marker_to_camera(gt);
    eval::EvalOptions options;
    options.max_time_difference = max_dt_;
    eval::EvalReport report;
    try {
      report = eval::evaluate(gt, est, options);
    } catch (const InputError& e) {
      throw InputError(
          file_error(est_path_, std::string(e.what()) + " (ground truth: " + gt_path_ + ")"));
    }
    if (json_)
      std::cout << eval::to_json(report).dump(2) << "\n";
    else
      std::cout << eval::to_text(report);
    return 0;
  }

 private:
  std::string gt_path_, est_path_;
  bool bonn_ = false, json_ = false;
  double max_dt_ = 0.02;
};

}  // namespace

std::unique_ptr<Command> make_eval_command(CLI::App& cli) {
  return std::make_unique<EvalCommand>(cli);
}

}  // namespace mcslam::cli
