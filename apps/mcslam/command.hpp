// The subcommands of the mcslam command line: each registers its options on the CLI and runs
// once the command line has been parsed into them (one file per subcommand).
#pragma once

#include <CLI/CLI.hpp>
#include <memory>

namespace mcslam::cli {

/// One subcommand: the constructor adds it and its options to the CLI, run() does its work.
class Command {
 public:
  virtual ~Command() = default;
  Command(const Command&) = delete;
  Command& operator=(const Command&) = delete;

  /// Whether this subcommand was the one given on the command line.
  bool parsed() const { return app_->parsed(); }
  /// Does the command's work; argc/argv are the whole command line. Returns the exit code;
  /// throws InputError, BackgroundThreadError or CLI::Error as main reports them.
  virtual int run(int argc, char** argv) = 0;

 protected:
  explicit Command(CLI::App* app) : app_(app) {}
  /// The subcommand's node, to add options to.
  CLI::App* app() const { return app_; }

 private:
  CLI::App* app_;
};

/// Adds a subcommand to the CLI; the returned object holds its options' values.
using MakeCommand = std::unique_ptr<Command> (*)(CLI::App& cli);

std::unique_ptr<Command> make_run_command(CLI::App& cli);
std::unique_ptr<Command> make_export_bag_command(CLI::App& cli);
std::unique_ptr<Command> make_bag_info_command(CLI::App& cli);
std::unique_ptr<Command> make_ros_command(CLI::App& cli);
std::unique_ptr<Command> make_bench_command(CLI::App& cli);
std::unique_ptr<Command> make_faults_command(CLI::App& cli);
std::unique_ptr<Command> make_eval_command(CLI::App& cli);
std::unique_ptr<Command> make_grid_compare_command(CLI::App& cli);
std::unique_ptr<Command> make_synth_command(CLI::App& cli);
std::unique_ptr<Command> make_detect_command(CLI::App& cli);
std::unique_ptr<Command> make_vocabulary_command(CLI::App& cli);

}  // namespace mcslam::cli
