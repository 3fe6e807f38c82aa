// `mcslam detect INPUT -m MODEL -o OUT`: the object detector on an image or a sequence.
#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "command.hpp"
#include "mcslam/app/detect.hpp"

namespace mcslam::cli {
namespace {

class DetectCommand : public Command {
 public:
  explicit DetectCommand(CLI::App& cli)
      : Command(cli.add_subcommand(
            "detect",
            "Run the object detector on an image or a sequence (writes detections.json)")) {
    CLI::App* cmd = app();
    cmd->add_option("input", request_.input, "Image file, or sequence folder with rgb.txt")
        ->required();
    cmd->add_option("--model,-m", request_.model, "ONNX detector (YOLOv8/YOLO11 or YOLOX)")
        ->required();
    cmd->add_option("--output,-o", request_.output_dir, "Folder for the results")->required();
    cmd->add_option("--confidence", request_.options.confidence,
                    "Minimum detection score in (0, 1) (default 0.35)");
    cmd->add_option_function<std::string>(
           "--input-size", [this](const std::string& text) { set_input_size(text); },
           "Network input WxH, multiples of 32 (default: the model's own)")
        ->type_name("WxH");
    cmd->add_option("--max-frames", request_.max_frames, "Process at most N images")
        ->check(CLI::NonNegativeNumber);
    cmd->add_flag("--quiet,-q", quiet_, "No progress bar and no summary");
  }

  int run(int, char**) override {
    request_.progress = !quiet_ && isatty(fileno(stderr));
    const nlohmann::json summary = app::detect_images(request_);
    if (!quiet_) {
      std::cout << app::detect_summary_text(summary);
      std::cout << "results in " << request_.output_dir << " (detections.json, annotated/)\n";
    }
    return 0;
  }

 private:
  /// --input-size WxH (CLI::ValidationError otherwise).
  void set_input_size(const std::string& text) {
    int w = 0, h = 0;
    char x = 0, rest = 0;
    if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &rest) != 3 || x != 'x')
      throw CLI::ValidationError("--input-size", "expected WxH, e.g. 256x192");
    request_.options.input_size = cv::Size(w, h);
  }

  app::DetectRequest request_;
  bool quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> make_detect_command(CLI::App& cli) {
  return std::make_unique<DetectCommand>(cli);
}

}  // namespace mcslam::cli
