#include "mcslam/app/faults.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "mcslam/core/error.hpp"
#include "mcslam/io/camera_presets.hpp"
#include "mcslam/io/files.hpp"
#include "mcslam/io/sequence.hpp"
#include "mcslam/io/trajectory_io.hpp"
#include "mcslam/perception/detection.hpp"
#include "mcslam/slam/config.hpp"

namespace mcslam::app {
namespace {

namespace fs = std::filesystem;

struct KindName {
  Fault::Kind kind;
  const char* name;
  bool has_length;  // START:LEN (else drop-every:K or time-jump:START:SECONDS)
};

constexpr KindName kKinds[] = {
    {Fault::Kind::kDropEvery, "drop-every", false}, {Fault::Kind::kDropBurst, "drop-burst", true},
    {Fault::Kind::kBlack, "black", true},           {Fault::Kind::kSaturate, "saturate", true},
    {Fault::Kind::kZeroDepth, "zero-depth", true},  {Fault::Kind::kFreeze, "freeze", true},
    {Fault::Kind::kTimeJump, "time-jump", false},   {Fault::Kind::kKidnap, "kidnap", true},
};

const char* kForms =
    "drop-every:K, drop-burst:START:LEN, black:START:LEN, saturate:START:LEN, "
    "zero-depth:START:LEN, freeze:START:LEN, time-jump:START:SECONDS, kidnap:START:LEN";

struct OutFrame {
  double t_rgb = 0, t_depth = 0;
  std::string rgb, depth;
  bool keep = true;
  /// The frame's boxes from the source's detections.json (the ground truth of a synthetic scene);
  /// a frame it has no entry for gets none.
  std::vector<perception::Detection> boxes;
};

std::string absolute(const std::string& path) {
  std::error_code ec;
  const fs::path p = fs::absolute(path, ec);
  return (ec ? fs::path(path) : p).lexically_normal().string();
}

void write_image(const fs::path& path, const cv::Mat& image) {
  if (!cv::imwrite(path.string(), image))
    throw InputError(file_error(path.string(), "cannot write"));
}

}  // namespace

Fault parse_fault(const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream stream(text);
  for (std::string p; std::getline(stream, p, ':');) parts.push_back(p);
  const auto bad = [&](const std::string& why) {
    return InputError("--fault '" + text + "': " + why + " (forms: " + kForms + ")");
  };
  if (parts.empty()) throw bad("empty");
  const auto it = std::find_if(std::begin(kKinds), std::end(kKinds),
                               [&](const KindName& k) { return parts[0] == k.name; });
  if (it == std::end(kKinds)) throw bad("unknown fault");
  Fault f;
  f.kind = it->kind;
  const std::size_t expected = f.kind == Fault::Kind::kDropEvery ? 2 : 3;
  if (parts.size() != expected)
    throw bad("expected " + std::to_string(expected - 1) + " number(s)");
  try {
    std::size_t used = 0;
    const auto integer = [&](const std::string& s) {
      const int v = std::stoi(s, &used);
      if (used != s.size()) throw std::invalid_argument(s);
      return v;
    };
    if (f.kind == Fault::Kind::kDropEvery) {
      f.length = integer(parts[1]);
      if (f.length < 2) throw bad("K must be at least 2");
    } else {
      f.start = integer(parts[1]);
      if (f.start < 0) throw bad("START must not be negative");
      if (f.kind == Fault::Kind::kTimeJump) {
        f.seconds = std::stod(parts[2], &used);
        if (used != parts[2].size() || !std::isfinite(f.seconds) || f.seconds <= 0)
          throw bad("SECONDS must be a positive number");
      } else {
        f.length = integer(parts[2]);
        if (f.length < 1) throw bad("LEN must be at least 1");
      }
    }
  } catch (const std::logic_error&) {  // stoi / stod
    throw bad("not a number");
  }
  return f;
}

std::string to_string(const Fault& f) {
  const auto it = std::find_if(std::begin(kKinds), std::end(kKinds),
                               [&](const KindName& k) { return k.kind == f.kind; });
  std::ostringstream s;
  s << it->name << ':';
  if (f.kind == Fault::Kind::kDropEvery)
    s << f.length;
  else if (f.kind == Fault::Kind::kTimeJump)
    s << f.start << ':' << f.seconds;
  else
    s << f.start << ':' << f.length;
  return s.str();
}

namespace {

/// The source's frames as the copy starts from them: absolute paths and their boxes.
std::vector<OutFrame> source_frames(const io::RgbdSequence& source,
                                    const std::optional<perception::DetectionsFile>& boxes) {
  std::vector<OutFrame> frames;
  for (const io::FrameEntry& e : source.frames()) {
    OutFrame& f = frames.emplace_back();
    f.t_rgb = e.rgb_timestamp;
    f.t_depth = e.depth_timestamp;
    f.rgb = absolute(e.rgb_path);
    f.depth = absolute(e.depth_path);
    if (const perception::FrameDetections* d = boxes ? boxes->find(e.rgb_timestamp) : nullptr)
      f.boxes = d->detections;
  }
  return frames;
}

/// Fault `f` applied to frame i (replacement images go to `out`); false when the frame is left
/// as it is.
bool fault_frame(const Fault& f, int i, std::vector<OutFrame>& frames, const fs::path& out,
                 const cv::Size& size) {
  OutFrame& fr = frames[i];
  char name[32];
  std::snprintf(name, sizeof(name), "%06d.png", i);
  switch (f.kind) {
    case Fault::Kind::kDropEvery:
      if ((i + 1) % f.length != 0) return false;
      fr.keep = false;
      break;
    case Fault::Kind::kDropBurst:
      fr.keep = false;
      break;
    case Fault::Kind::kBlack:
    case Fault::Kind::kSaturate:
      write_image(out / "rgb" / name,
                  cv::Mat(size, CV_8UC3, cv::Scalar::all(f.kind == Fault::Kind::kBlack ? 0 : 255)));
      fr.rgb = absolute((out / "rgb" / name).string());
      fr.boxes.clear();  // a detector finds nothing in a blank image
      break;
    case Fault::Kind::kZeroDepth:
      write_image(out / "depth" / name, cv::Mat(size, CV_16UC1, cv::Scalar(0)));
      fr.depth = absolute((out / "depth" / name).string());
      break;
    case Fault::Kind::kKidnap:
      write_image(out / "rgb" / name, cv::Mat(size, CV_8UC3, cv::Scalar::all(0)));
      write_image(out / "depth" / name, cv::Mat(size, CV_16UC1, cv::Scalar(0)));
      fr.rgb = absolute((out / "rgb" / name).string());
      fr.depth = absolute((out / "depth" / name).string());
      fr.boxes.clear();
      break;
    case Fault::Kind::kFreeze:
      if (i == f.start) return false;  // the frame that stays on screen
      fr.rgb = frames[f.start].rgb;
      fr.depth = frames[f.start].depth;
      fr.boxes = frames[f.start].boxes;
      break;
    case Fault::Kind::kTimeJump:
      fr.t_rgb += f.seconds;
      fr.t_depth += f.seconds;
      break;
  }
  return true;
}

/// Fault `f` applied to the frames (and a time jump to the ground truth); its line of
/// faults.json.
nlohmann::json apply_fault(const Fault& f, const io::RgbdSequence& source,
                           std::vector<OutFrame>& frames, std::optional<Trajectory>& groundtruth,
                           const fs::path& out, const cv::Size& size) {
  const int n = static_cast<int>(frames.size());
  if (f.kind != Fault::Kind::kDropEvery && f.start >= n)
    throw InputError("--fault '" + to_string(f) + "': the sequence has only " + std::to_string(n) +
                     " frames");
  const int first = f.kind == Fault::Kind::kDropEvery ? 0 : f.start;
  const int end = f.kind == Fault::Kind::kDropEvery || f.kind == Fault::Kind::kTimeJump
                      ? n
                      : std::min(n, f.start + f.length + (f.kind == Fault::Kind::kFreeze));
  int affected = 0;
  for (int i = first; i < end; ++i)
    if (fault_frame(f, i, frames, out, size)) ++affected;
  if (f.kind == Fault::Kind::kTimeJump && groundtruth) {
    const double from = source.frames()[f.start].rgb_timestamp - 1e-6;
    for (StampedPose& p : *groundtruth)
      if (p.timestamp >= from) p.timestamp += f.seconds;
  }
  nlohmann::json j = {{"fault", to_string(f)}, {"frames_affected", affected}};
  if (f.kind != Fault::Kind::kDropEvery) {
    const int last = std::min(n, f.kind == Fault::Kind::kTimeJump ? f.start + 1 : end) - 1;
    j["first_frame"] = f.start;
    j["last_frame"] = last;
    j["t_begin"] = frames[f.start].t_rgb;
    j["t_end"] = frames[last].t_rgb;
  }
  return j;
}

/// rgb.txt and depth.txt of the frames kept; how many there are (InputError for none).
int write_frame_lists(const fs::path& out, const std::vector<OutFrame>& frames) {
  std::ostringstream rgb, depth;
  rgb << "# colour images (mcslam faults)\n" << std::fixed << std::setprecision(6);
  depth << "# depth images (mcslam faults)\n" << std::fixed << std::setprecision(6);
  int kept = 0;
  for (const OutFrame& f : frames) {
    if (!f.keep) continue;
    rgb << f.t_rgb << ' ' << f.rgb << '\n';
    depth << f.t_depth << ' ' << f.depth << '\n';
    ++kept;
  }
  if (kept == 0) throw InputError("--fault: every frame would be dropped");
  io::write_file_atomic((out / "rgb.txt").string(), rgb.str());
  io::write_file_atomic((out / "depth.txt").string(), depth.str());
  return kept;
}

/// The copy's detections.json: the source's boxes of the frames kept.
void write_kept_boxes(const fs::path& out, const perception::DetectionsFile& boxes,
                      const std::vector<OutFrame>& frames) {
  perception::DetectionsFile copy = boxes;
  copy.source += " (mcslam faults)";
  copy.frames.clear();
  for (const OutFrame& f : frames)
    if (f.keep) copy.frames.push_back({f.t_rgb, f.boxes});
  perception::write_detections((out / "detections.json").string(), copy);
}

}  // namespace

nlohmann::json write_faulty_sequence(const FaultRequest& request) {
  const io::RgbdSequence source = io::RgbdSequence::open(request.sequence_dir);
  const slam::RunConfig config = slam::resolve_run_config(request.sequence_dir, std::nullopt);
  const int n = static_cast<int>(source.frames().size());
  const fs::path boxes_path = fs::path(source.directory()) / "detections.json";
  std::optional<perception::DetectionsFile> boxes;
  if (fs::exists(boxes_path)) boxes = perception::read_detections(boxes_path.string());
  std::vector<OutFrame> frames = source_frames(source, boxes);
  std::optional<Trajectory> groundtruth;
  if (const auto gt = source.groundtruth_path()) groundtruth = io::read_tum_trajectory(*gt);

  const fs::path out(request.output_dir);
  io::ensure_directory((out / "rgb").string());
  io::ensure_directory((out / "depth").string());
  const cv::Size size(config.camera.width, config.camera.height);
  nlohmann::json report = {
      {"source", source.directory()}, {"frames_in", n}, {"faults", nlohmann::json::array()}};
  for (const Fault& f : request.faults)
    report["faults"].push_back(apply_fault(f, source, frames, groundtruth, out, size));

  const int kept = write_frame_lists(out, frames);
  io::write_file_atomic(
      (out / "camera.yaml").string(),
      io::camera_settings_yaml(config.camera,
                               "the camera of the source sequence (written by mcslam faults)"));
  if (groundtruth) io::write_tum_trajectory((out / "groundtruth.txt").string(), *groundtruth);
  if (boxes) write_kept_boxes(out, *boxes, frames);
  report["frames_out"] = kept;
  io::write_file_atomic((out / "faults.json").string(), report.dump(2) + "\n");
  return report;
}

}  // namespace mcslam::app
