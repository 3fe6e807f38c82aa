// `mcslam synth -o OUT`: render a synthetic RGB-D sequence (TUM layout), static or dynamic.
#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <string>

#include "command.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/synth/sequence.hpp"

namespace mcslam::cli {
namespace {

class SynthCommand : public Command {
 public:
  explicit SynthCommand(CLI::App& cli)
      : Command(cli.add_subcommand("synth", "Render a synthetic RGB-D sequence (TUM layout)")) {
    add_camera_options(app());
    add_dynamic_options(app());
    app()->add_flag("--quiet,-q", quiet_, "No progress");
  }

  int run(int, char**) override {
    apply_choices();
    const bool bar = !quiet_ && isatty(fileno(stderr));
    synth::write_sequence(output_, options_, [&](int done, int total) {
      if (bar && (done % 10 == 0 || done == total)) {
        std::fprintf(stderr, "\rrendering %d/%d", done, total);
        if (done == total) std::fputc('\n', stderr);
      }
    });
    if (!quiet_) std::cout << "wrote " << options_.frames << " frames to " << output_ << "\n";
    return 0;
  }

 private:
  /// The output, the room, the camera's path and its images.
  void add_camera_options(CLI::App* cmd) {
    cmd->add_option("--output,-o", output_, "Folder to write")->required();
    cmd->add_option("--frames", options_.frames, "Number of frames");
    cmd->add_option("--seed", options_.seed, "Random seed of textures and noise");
    cmd->add_option("--texture", texture_, "rich or low")->check(CLI::IsMember({"rich", "low"}));
    cmd->add_flag("--depth-noise", options_.depth_noise, "Kinect-like depth noise");
    cmd->add_option("--speed", options_.speed, "Camera speed factor");
    cmd->add_option("--path", path_,
                    "Camera path: wander (looks at the +x wall, the default), loop (goes round "
                    "the room once per --loop-period seconds looking out, back to its start) or "
                    "orbit (round the objects on a 3.5 x 3 m ellipse looking in; --room-scale 2 "
                    "or more)")
        ->check(CLI::IsMember({"wander", "loop", "orbit"}));
    cmd->add_option("--loop-period", options_.loop_period,
                    "Seconds per lap of --path loop at speed 1 (default 24)");
    cmd->add_option("--room-scale", options_.room_scale,
                    "Scale of the room's floor plan, 1-4 (default 1: 6 x 5 m); at 2 the walls "
                    "are beyond the depth range of --depth-noise");
    cmd->add_option("--readout-time", options_.readout_time,
                    "Rolling-shutter readout time in seconds (0 = global shutter; negative: rows "
                    "read bottom to top)");
    cmd->add_option("--width", options_.width, "Image width");
    cmd->add_option("--height", options_.height, "Image height");
  }

  /// The people and the chair of a dynamic scene.
  void add_dynamic_options(CLI::App* cmd) {
    auto& dyn = options_.dynamic;
    cmd->add_flag("--dynamic", dyn.enabled,
                  "Add people moving freely and a chair sliding on the floor (writes "
                  "objects.json and labels/ with their ground truth)");
    cmd->add_flag("--no-person", no_person_, "Dynamic scene without people (--people 0)");
    people_ = cmd->add_option(
        "--people", dyn.people,
        "Number of people walking through the dynamic scene, 0-6 (default 1): person 2 passes "
        "close in front of the camera, 3 and 4 at the image border, 5-6 further away");
    cmd->add_option("--undetected-people", dyn.undetected_people,
                    "How many of the people (the last ones) get no box in detections.json, "
                    "0..--people (default 0)");
    cmd->add_flag("--no-chair", no_chair_, "Dynamic scene without the chair");
    cmd->add_option("--person-speed", dyn.person_speed,
                    "Person 1's peak speed (m/s); the others walk at fixed multiples of it");
    cmd->add_option("--chair-speed", dyn.chair_speed, "Chair's peak speed (m/s)");
    cmd->add_option("--chair-push", dyn.chair_push,
                    "Push the chair once along +x by this many metres, then it stands still "
                    "(0: it slides back and forth)");
    cmd->add_option("--person-scale", dyn.person_scale, "Person 1's size factor");
    cmd->add_option("--chair-scale", dyn.chair_scale, "Chair's size factor");
    cmd->add_option("--start-time", dyn.start_time, "Scene time (s) when the objects start");
  }

  /// The texture, path, objects and intrinsics the options as typed choose.
  void apply_choices() {
    auto& dyn = options_.dynamic;
    if (texture_ == "low") options_.texture = synth::TextureLevel::kLow;
    if (path_ == "loop") options_.path = synth::CameraPath::kLoop;
    if (path_ == "orbit") options_.path = synth::CameraPath::kOrbit;
    if (no_person_ && people_->count() > 0 && dyn.people > 0)
      throw InputError("--no-person and --people " + std::to_string(dyn.people) +
                       " exclude each other (--no-person is --people 0)");
    if (no_person_) dyn.person = false;
    if (no_chair_) dyn.chair = false;
    if (options_.width != 640 || options_.height != 480) {
      options_.cx = (options_.width - 1) / 2.0;
      options_.cy = (options_.height - 1) / 2.0;
      options_.fx = options_.fy = 525.0 * options_.width / 640.0;
    }
  }

  std::string output_;
  synth::SynthOptions options_;
  std::string texture_ = "rich", path_ = "wander";
  bool no_person_ = false, no_chair_ = false, quiet_ = false;
  CLI::Option* people_ = nullptr;
};

}  // namespace

std::unique_ptr<Command> make_synth_command(CLI::App& cli) {
  return std::make_unique<SynthCommand>(cli);
}

}  // namespace mcslam::cli
