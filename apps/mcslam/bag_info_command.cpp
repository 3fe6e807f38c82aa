// `mcslam bag-info PATH`: what a ROS 1 bag or a ROS 2 recording holds.
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "command.hpp"
#include "mcslam/rosbag2/source.hpp"
#include "shared_options.hpp"

namespace mcslam::cli {
namespace {

class BagInfoCommand : public Command {
 public:
  explicit BagInfoCommand(CLI::App& cli)
      : Command(cli.add_subcommand(
            "bag-info",
            "What a ROS 1 bag or ROS 2 recording holds: storage, duration, topics, counts")) {
    app()
        ->add_option("path", path_, "ROS 1 bag, ROS 2 recording folder, .db3 or .mcap")
        ->required();
    app()->add_flag("--json", json_, "As JSON (for scripts)");
  }

  int run(int, char**) override {
    nlohmann::json info;
    if (rosbag2::is_recording_path(path_)) {
      info = rosbag2::recording_info(path_);
    } else {
#ifdef MCSLAM_HAVE_ROS
      info = ros::bag_info(path_);
#else
      no_ros("bag-info " + path_);
#endif
    }
    std::cout << (json_ ? info.dump(2) + "\n" : rosbag2::info_text(info));
    return 0;
  }

 private:
  std::string path_;
  bool json_ = false;
};

}  // namespace

std::unique_ptr<Command> make_bag_info_command(CLI::App& cli) {
  return std::make_unique<BagInfoCommand>(cli);
}

}  // namespace mcslam::cli
