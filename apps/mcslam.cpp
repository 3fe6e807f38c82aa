// mcslam command-line interface: run, bench, eval, synth, detect, vocabulary, and with ROS
// export-bag and ros. Each subcommand is in its own file under mcslam/; main registers them
// from a table, runs the one given and reports its errors.
#include <CLI/CLI.hpp>
#include <iostream>
#include <memory>
#include <vector>

#include "mcslam/command.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/core/thread_failure.hpp"
#include "mcslam/version.hpp"

namespace {

/// The subcommands in the order `mcslam --help` lists them.
constexpr mcslam::cli::MakeCommand kCommands[] = {
    mcslam::cli::make_run_command,        mcslam::cli::make_export_bag_command,
    mcslam::cli::make_bag_info_command,   mcslam::cli::make_ros_command,
    mcslam::cli::make_bench_command,      mcslam::cli::make_faults_command,
    mcslam::cli::make_eval_command,       mcslam::cli::make_grid_compare_command,
    mcslam::cli::make_synth_command,      mcslam::cli::make_detect_command,
    mcslam::cli::make_vocabulary_command,
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"mcslam: semantic RGB-D SLAM for dynamic indoor scenes"};
  cli.require_subcommand(1);
  cli.set_version_flag("--version", std::string("mcslam ") + MCSLAM_VERSION_STRING,
                       "Print the version and exit");
  std::vector<std::unique_ptr<mcslam::cli::Command>> commands;
  for (const mcslam::cli::MakeCommand make : kCommands) commands.push_back(make(cli));

  CLI11_PARSE(cli, argc, argv);
  try {
    for (const auto& command : commands)
      if (command->parsed()) return command->run(argc, argv);
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
