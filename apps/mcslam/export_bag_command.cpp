// `mcslam export-bag SEQUENCE BAG`: a TUM-layout folder as a ROS 1 bag or a ROS 2 recording.
#include <iostream>
#include <optional>
#include <string>
#include <utility>

#include "command.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/io/frame_source.hpp"
#include "mcslam/rosbag2/source.hpp"
#include "mcslam/slam/config.hpp"
#include "shared_options.hpp"

namespace mcslam::cli {
namespace {

class ExportBagCommand : public Command {
 public:
  explicit ExportBagCommand(CLI::App& cli)
      : Command(cli.add_subcommand(
            "export-bag",
            "Write a TUM-layout sequence as a ROS 1 bag (needs ROS) or a ROS 2 recording")) {
    CLI::App* cmd = app();
    cmd->add_option("sequence", sequence_, "Sequence folder")->required();
    cmd->add_option("bag", bag_, "Bag file (ros1) or recording folder (ros2) to write")->required();
    cmd->add_option("--format", format_, "ros1 (a .bag; default) or ros2 (a rosbag2 folder)")
        ->check(CLI::IsMember({"ros1", "ros2"}));
    cmd->add_option("--storage", storage_, "ros2: mcap (default) or sqlite3")
        ->check(CLI::IsMember({"mcap", "sqlite3"}));
    cmd->add_option("--compression", compression_,
                    "ros2: none (default), zstd, or for mcap lz4 (MCAP chunks; sqlite3: rosbag2's "
                    "per-message zstd)")
        ->check(CLI::IsMember({"none", "lz4", "zstd"}));
    cmd->add_option("--config,-c", config_, "Settings file for the camera");
    cmd->add_option("--camera-preset", preset_,
                    "Camera preset instead of the one the folder name chooses");
    cmd->add_option("--rgb-encoding", rgb_encoding_,
                    "bgr8 (default) or rgb8; ros2 also png (CompressedImage on TOPIC/compressed)")
        ->check(CLI::IsMember({"bgr8", "rgb8", "png"}));
    cmd->add_option("--depth-encoding", depth_encoding_,
                    "32FC1 (metres, as the TUM bags; default) or 16UC1 (millimetres); ros2 also "
                    "png (16UC1 compressedDepth on TOPIC/compressedDepth)")
        ->check(CLI::IsMember({"32FC1", "16UC1", "png"}));
    add_topic_options(cmd, topics_);
    cmd->add_flag("--quiet,-q", quiet_, "No summary");
  }

  int run(int, char**) override { return format_ == "ros2" ? export_ros2() : export_ros1(); }

 private:
  /// The TUM folder to export and its camera, as `mcslam run` resolves it.
  std::pair<std::shared_ptr<io::FolderSource>, slam::RunConfig> open_source() const {
    auto source = io::FolderSource::open(sequence_);
    for (const auto& warning : source->warnings())
      std::cerr << "mcslam: warning: " << warning << "\n";
    return std::make_pair(source,
                          slam::resolve_run_config(sequence_, config_, io::CameraHints{}, preset_));
  }

  int export_ros2() const {
    rosbag2::ExportOptions options;
    options.topics = ros2_topic_options(topics_);
    options.rgb_encoding = rgb_encoding_;
    options.depth_encoding = depth_encoding_;
    options.storage = storage_;
    options.compression = compression_;
    const auto [source, config] = open_source();
    const std::size_t frames = rosbag2::export_recording(*source, config.camera, bag_, options);
    if (!quiet_)
      std::cout << "wrote " << frames << " frames to " << bag_ << " (" << storage_
                << ", camera from " << config.camera_source << ")\n";
    return 0;
  }

  int export_ros1() const {
    if (rgb_encoding_ == "png" || depth_encoding_ == "png")
      throw InputError("--rgb-encoding/--depth-encoding png: only with --format ros2");
    if (app()->count("--storage") || app()->count("--compression"))
      throw InputError(
          "--storage/--compression: only with --format ros2 (a ROS 1 bag "
          "is always LZ4-compressed)");
#ifdef MCSLAM_HAVE_ROS
    ros::ExportOptions options;
    options.topics = topic_options(topics_);
    options.rgb_encoding = rgb_encoding_;
    options.depth_encoding = depth_encoding_;
    const auto [source, config] = open_source();
    const std::size_t frames = ros::export_bag(*source, config.camera, bag_, options);
    if (!quiet_)
      std::cout << "wrote " << frames << " frames to " << bag_ << " (camera from "
                << config.camera_source << ")\n";
    return 0;
#else
    no_ros("export-bag");
#endif
  }

  std::string sequence_, bag_;
  std::optional<std::string> config_, preset_;
  std::string rgb_encoding_ = "bgr8", depth_encoding_ = "32FC1";
  std::string format_ = "ros1", storage_ = "mcap", compression_ = "none";
  TopicArgs topics_;
  bool quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> make_export_bag_command(CLI::App& cli) {
  return std::make_unique<ExportBagCommand>(cli);
}

}  // namespace mcslam::cli
