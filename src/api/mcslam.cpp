#include "mcslam/mcslam.hpp"

#include <algorithm>
#include <cmath>

#include "mcslam/eval/metrics.hpp"
#include "mcslam/io/camera_presets.hpp"
#include "mcslam/io/config_file.hpp"
#include "mcslam/io/frame_source.hpp"
#include "mcslam/io/trajectory_io.hpp"
#include "mcslam/perception/detection.hpp"
#include "mcslam/perception/detector.hpp"
#include "mcslam/slam/config.hpp"
#include "mcslam/slam/detection_source.hpp"
#include "mcslam/slam/system.hpp"

namespace mcslam {

struct Settings::Data {
  slam::RunConfig config;
  std::string model;
  std::optional<double> confidence;
  std::string detections;
};

struct Sequence::Data {
  std::shared_ptr<io::FolderSource> source;
};

namespace {

std::string size_text(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

std::string type_text(const cv::Mat& m) {
  if (m.empty()) return "empty";
  return cv::typeToString(m.type());
}

/// The boxes the settings ask for, or null (as `mcslam run --model / --detections`).
std::unique_ptr<slam::DetectionSource> make_detection_source(const Settings::Data& s) {
  const PinholeCamera& camera = s.config.camera;
  const slam::SystemOptions& options = s.config.options;
  if (!s.model.empty() && !s.detections.empty())
    throw InputError("a detector model and a detections file exclude each other: give one");
  if (!s.detections.empty()) {
    perception::DetectionsFile file = perception::read_detections(s.detections);
    if ((file.image_width && *file.image_width != camera.width) ||
        (file.image_height && *file.image_height != camera.height))
      throw InputError(file_error(
          s.detections, "boxes are for " +
                            size_text(file.image_width.value_or(0), file.image_height.value_or(0)) +
                            " images but the camera is " + size_text(camera.width, camera.height)));
    return std::make_unique<slam::FileDetectionSource>(std::move(file), s.detections);
  }
  if (!s.model.empty()) {
    perception::DetectorOptions detector;
    if (s.confidence) detector.confidence = *s.confidence;
    if (auto e = detector.check()) throw InputError("confidence: " + *e);
    detector.input_size =
        perception::input_size_for(cv::Size(camera.width, camera.height), options.detector_scale);
    // A frame that waits for its own boxes (sequential mode) must be given to the detector.
    const bool waits = options.sequential;
    return std::make_unique<slam::ModelDetectionSource>(perception::Detector(s.model, detector),
                                                        waits ? 1 : options.detection_interval,
                                                        waits ? 0 : options.detector_niceness);
  }
  return nullptr;
}

State to_state(slam::TrackingState s) {
  switch (s) {
    case slam::TrackingState::kOk:
      return State::kOk;
    case slam::TrackingState::kLost:
      return State::kLost;
    case slam::TrackingState::kNotInitialized:
      break;
  }
  return State::kNotInitialized;
}

}  // namespace

std::string version() { return MCSLAM_VERSION_STRING; }

const char* to_string(State state) {
  switch (state) {
    case State::kOk:
      return "ok";
    case State::kLost:
      return "lost";
    case State::kNotInitialized:
      break;
  }
  return "not_initialized";
}

// ---- Settings

Settings::Settings() : d_(std::make_unique<Data>()) {}
Settings::~Settings() = default;
Settings::Settings(const Settings& other) : d_(std::make_unique<Data>(*other.d_)) {}
Settings& Settings::operator=(const Settings& other) {
  if (this != &other) d_ = std::make_unique<Data>(*other.d_);
  return *this;
}
Settings::Settings(Settings&& other) noexcept : d_(std::move(other.d_)) {
  other.d_ = std::make_unique<Data>();
}
Settings& Settings::operator=(Settings&& other) noexcept {
  std::swap(d_, other.d_);
  return *this;
}

Settings Settings::preset(const std::string& name) {
  Settings s;
  const std::optional<PinholeCamera> camera = io::camera_preset(name);
  if (!camera) {
    std::string names;
    for (const auto& n : io::camera_preset_names()) names += (names.empty() ? "" : ", ") + n;
    throw InputError("unknown camera preset '" + name + "' (known: " + names + ")");
  }
  s.d_->config.camera = *camera;
  s.d_->config.camera_source = "preset " + name;
  return s;
}

Settings Settings::for_sequence(const std::string& sequence_dir, const std::string& settings_file) {
  Settings s;
  s.d_->config = slam::resolve_run_config(
      sequence_dir,
      settings_file.empty() ? std::nullopt : std::optional<std::string>(settings_file));
  return s;
}

void Settings::load_file(const std::string& path) {
  io::ConfigFile file = io::ConfigFile::load(path);
  slam::apply_config(file, d_->config.camera, d_->config.options);
  d_->config.camera_source = path;
}

void Settings::load_yaml(const std::string& yaml, const std::string& name) {
  io::ConfigFile file = io::ConfigFile::from_string(yaml, name);
  slam::apply_config(file, d_->config.camera, d_->config.options);
}

const PinholeCamera& Settings::camera() const { return d_->config.camera; }
void Settings::set_camera(const PinholeCamera& camera) {
  d_->config.camera = camera;
  d_->config.camera_source = "given";
}
bool Settings::sequential() const { return d_->config.options.sequential; }
void Settings::set_sequential(bool sequential) { d_->config.options.sequential = sequential; }
std::string Settings::vocabulary() const { return d_->config.options.place.vocabulary; }
void Settings::set_vocabulary(const std::string& path) {
  d_->config.options.place.vocabulary = path;
  if (path.empty()) d_->config.options.place.loop.enabled = false;
}
void Settings::set_loop_closing(bool enabled) { d_->config.options.place.loop.enabled = enabled; }
void Settings::set_detector(const std::string& model_path, std::optional<double> confidence) {
  d_->model = model_path;
  d_->confidence = confidence;
}
void Settings::set_detections_file(const std::string& path) { d_->detections = path; }
const std::string& Settings::detector_model() const { return d_->model; }
const std::string& Settings::detections_file() const { return d_->detections; }
std::string Settings::to_yaml() const { return slam::to_yaml(d_->config); }

// ---- System

System::System(const Settings& settings) : settings_(settings) {
  const Settings::Data& s = settings_.data();
  if (s.config.camera.width <= 0 || s.config.camera.height <= 0)
    throw InputError(
        "no camera: give one (Settings::preset, Settings::for_sequence, a settings file with "
        "camera.* keys, or Settings::set_camera)");
  // The detector is made first: a bad model path fails before the vocabulary is loaded.
  std::unique_ptr<slam::DetectionSource> detections = make_detection_source(s);
  system_ = std::make_unique<slam::System>(s.config.camera, s.config.options);
  if (detections) system_->set_detection_source(std::move(detections), s.config.options.sequential);
}

System::~System() = default;

FrameReport System::process(const cv::Mat& rgb, const cv::Mat& depth, double timestamp,
                            std::optional<double> depth_timestamp) {
  const PinholeCamera& camera = settings_.camera();
  if (rgb.type() != CV_8UC3 && rgb.type() != CV_8UC1)
    throw InputError("process: the colour image is " + type_text(rgb) +
                     "; expected 8-bit BGR (CV_8UC3) or grey (CV_8UC1)");
  if (depth.type() != CV_32FC1 && depth.type() != CV_16UC1)
    throw InputError("process: the depth image is " + type_text(depth) +
                     "; expected metres (CV_32FC1) or raw units (CV_16UC1)");
  if (rgb.cols != camera.width || rgb.rows != camera.height)
    throw InputError("process: the colour image is " + size_text(rgb.cols, rgb.rows) +
                     " but the camera is " + size_text(camera.width, camera.height));
  if (depth.cols != camera.width || depth.rows != camera.height)
    throw InputError("process: the depth image is " + size_text(depth.cols, depth.rows) +
                     " but the camera is " + size_text(camera.width, camera.height));
  if (!std::isfinite(timestamp)) throw InputError("process: the timestamp is not a finite number");
  cv::Mat depth_m = depth;
  if (depth.type() == CV_16UC1) {
    // As io::load_rgbd converts a depth PNG (bit for bit).
    depth_m.create(depth.size(), CV_32FC1);
    for (int r = 0; r < depth.rows; ++r) {
      const auto* in = depth.ptr<std::uint16_t>(r);
      auto* out = depth_m.ptr<float>(r);
      for (int c = 0; c < depth.cols; ++c)
        out[c] = static_cast<float>(static_cast<double>(in[c]) / camera.depth_factor);
    }
  }
  const slam::FrameResult r =
      system_->process(system_->prepare(rgb, depth_m), timestamp, depth_timestamp);
  FrameReport out;
  out.frame_id = r.frame_id;
  out.timestamp = r.timestamp;
  out.state = to_state(r.state);
  out.keyframe = r.keyframe;
  out.relocalised = r.relocalised;
  out.T_w_c = r.T_w_c;
  out.lagged = r.lagged;
  out.features = r.features;
  out.lines = r.lines;
  out.planes = r.planes;
  out.matches = r.matches;
  out.inliers = r.inliers;
  out.objects = static_cast<int>(r.objects.size());
  for (const auto& o : r.objects) out.dynamic_objects += o.state == slam::ObjectState::kDynamic;
  out.dynamic_points = static_cast<int>(
      std::count(r.point_labels.begin(), r.point_labels.end(), slam::FeatureLabel::kDynamic));
  out.tracking_ms = r.times.total_ms();
  return out;
}

void System::finish() { system_->finish(); }
Trajectory System::trajectory() const { return system_->trajectory(); }
Trajectory System::unsmoothed_trajectory() const { return system_->unsmoothed_trajectory(); }
Trajectory System::keyframe_trajectory() const { return system_->keyframe_trajectory(); }
Trajectory System::online_trajectory() const { return system_->online_trajectory(); }
Trajectory System::lagged_trajectory() const { return system_->lagged_trajectory(); }

OccupancyGridSnapshot System::grid() const {
  OccupancyGridSnapshot out;
  const mapping::MappingWorker* occupancy = system_->occupancy();
  if (!occupancy) return out;
  const auto snapshot = occupancy->snapshot();
  out.width = snapshot->grid.width;
  out.height = snapshot->grid.height;
  out.resolution = snapshot->grid.resolution;
  out.T_world_grid = snapshot->grid.T_world_grid;
  out.cells = snapshot->grid.cells;
  return out;
}

std::vector<Eigen::Vector3d> System::occupied_voxels() const {
  std::vector<Eigen::Vector3d> out;
  const mapping::MappingWorker* occupancy = system_->occupancy();
  if (!occupancy) return out;
  for (const mapping::OccupiedVoxel& v : occupancy->snapshot()->voxels) out.push_back(v.centre);
  return out;
}

MapSnapshot System::map() const {
  MapSnapshot out;
  const map::Map& m = system_->map();
  auto lock = m.read_lock();
  const auto sorted_ids = [](const auto& table) {
    std::vector<std::uint64_t> ids;
    ids.reserve(table.size());
    for (const auto& [id, value] : table) ids.push_back(static_cast<std::uint64_t>(id));
    std::sort(ids.begin(), ids.end());
    return ids;
  };
  for (auto id : sorted_ids(m.points())) out.points.push_back(m.points().at(id).p_w);
  for (auto id : sorted_ids(m.lines())) {
    const map::MapLine& l = m.lines().at(id);
    out.lines.emplace_back(l.start_w, l.end_w);
  }
  for (auto id : sorted_ids(m.planes())) out.planes.push_back(m.planes().at(id).coefficients());
  for (auto id : sorted_ids(m.keyframes())) {
    const map::KeyFrame& k = m.keyframes().at(id);
    out.keyframes.push_back({k.timestamp, k.T_w_c()});
  }
  std::sort(out.keyframes.begin(), out.keyframes.end(),
            [](const StampedPose& a, const StampedPose& b) { return a.timestamp < b.timestamp; });
  return out;
}

void System::save_session(const std::string& path) const { system_->save_session(path); }

// ---- Sequence

Sequence Sequence::open(const std::string& directory, const std::string& associations) {
  io::SequenceOptions options;
  options.associations_file = associations;
  auto data = std::make_shared<Data>();
  data->source = io::FolderSource::open(directory, options);
  Sequence s;
  s.d_ = std::move(data);
  return s;
}

const std::string& Sequence::directory() const { return d_->source->path(); }
std::size_t Sequence::size() const { return d_->source->frames().size(); }

double Sequence::timestamp(std::size_t index) const {
  if (index >= size())
    throw InputError(directory() + ": frame " + std::to_string(index) + " of " +
                     std::to_string(size()));
  return d_->source->frames()[index].rgb_timestamp;
}

Sequence::Frame Sequence::load(std::size_t index, double depth_factor) const {
  const double t = timestamp(index);  // checks the index
  io::RgbdImages images = d_->source->load(index, depth_factor);
  return {std::move(images.rgb), std::move(images.depth), t,
          d_->source->frames()[index].depth_timestamp};
}

std::optional<Trajectory> Sequence::groundtruth() const { return d_->source->groundtruth(); }
std::vector<std::string> Sequence::warnings() const { return d_->source->warnings(); }

// ---- Evaluation and trajectories

Evaluation evaluate(const Trajectory& groundtruth, const Trajectory& estimate,
                    double max_time_difference) {
  eval::EvalOptions options;
  options.max_time_difference = max_time_difference;
  const eval::EvalReport report = eval::evaluate(groundtruth, estimate, options);
  constexpr double kDeg = 180.0 / 3.14159265358979323846;
  Evaluation e;
  e.ate_rmse_m = report.ate.translation.rmse;
  e.ate_mean_m = report.ate.translation.mean;
  e.ate_median_m = report.ate.translation.median;
  e.ate_max_m = report.ate.translation.max;
  e.rpe_frame_trans_rmse_m = report.rpe_frame.translation.rmse;
  e.rpe_frame_rot_rmse_deg = report.rpe_frame.rotation.rmse * kDeg;
  e.rpe_1s_trans_rmse_m = report.rpe_time.translation.rmse;
  e.rpe_1s_rot_rmse_deg = report.rpe_time.rotation.rmse * kDeg;
  e.matched = report.matched;
  e.estimate_poses = report.est_poses;
  e.groundtruth_poses = report.gt_poses;
  e.T_gt_est = report.ate.T_gt_est;
  e.text = eval::to_text(report);
  e.json = eval::to_json(report).dump(2);
  return e;
}

Trajectory read_trajectory(const std::string& path) { return io::read_tum_trajectory(path); }
void write_trajectory(const std::string& path, const Trajectory& trajectory) {
  io::write_tum_trajectory(path, trajectory);
}

}  // namespace mcslam
