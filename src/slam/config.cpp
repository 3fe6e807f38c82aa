#include "mcslam/slam/config.hpp"

#include <filesystem>
#include <sstream>

#include "mcslam/core/error.hpp"
#include "mcslam/io/camera_presets.hpp"

namespace mcslam::slam {
namespace {

void read_camera(io::ConfigFile& f, PinholeCamera& c) {
  // mcslam keys.
  f.read("camera.fx", c.fx);
  f.read("camera.fy", c.fy);
  f.read("camera.cx", c.cx);
  f.read("camera.cy", c.cy);
  f.read("camera.width", c.width);
  f.read("camera.height", c.height);
  f.read("camera.k1", c.distortion[0]);
  f.read("camera.k2", c.distortion[1]);
  f.read("camera.p1", c.distortion[2]);
  f.read("camera.p2", c.distortion[3]);
  f.read("camera.k3", c.distortion[4]);
  f.read("camera.depth_factor", c.depth_factor);
  f.read("camera.bf", c.bf);
  f.read("camera.readout_time", c.readout_time);
  // ORB-SLAM2 keys.
  f.read("Camera.fx", c.fx);
  f.read("Camera.fy", c.fy);
  f.read("Camera.cx", c.cx);
  f.read("Camera.cy", c.cy);
  f.read("Camera.width", c.width);
  f.read("Camera.height", c.height);
  f.read("Camera.k1", c.distortion[0]);
  f.read("Camera.k2", c.distortion[1]);
  f.read("Camera.p1", c.distortion[2]);
  f.read("Camera.p2", c.distortion[3]);
  f.read("Camera.k3", c.distortion[4]);
  f.read("Camera.bf", c.bf);
  f.read("DepthMapFactor", c.depth_factor);
}

void read_options(io::ConfigFile& f, SystemOptions& o, const PinholeCamera& camera) {
  f.read("orb.num_features", o.orb.num_features);
  f.read("orb.num_levels", o.orb.num_levels);
  f.read("orb.scale_factor", o.orb.scale_factor);
  f.read("orb.fast_threshold", o.orb.fast_threshold);
  f.read("orb.min_fast_threshold", o.orb.min_fast_threshold);
  f.read("ORBextractor.nFeatures", o.orb.num_features);
  f.read("ORBextractor.nLevels", o.orb.num_levels);
  f.read("ORBextractor.scaleFactor", o.orb.scale_factor);
  f.read("ORBextractor.iniThFAST", o.orb.fast_threshold);
  f.read("ORBextractor.minThFAST", o.orb.min_fast_threshold);

  auto& t = o.tracker;
  f.read("tracker.close_depth_factor", t.close_depth_factor);
  f.read("ThDepth", t.close_depth_factor);
  f.read("tracker.min_depth", t.min_depth);
  f.read("tracker.max_depth", t.max_depth);
  f.read("tracker.motion_search_radius", t.motion_search_radius);
  f.read("tracker.max_descriptor_distance", t.max_descriptor_distance);
  f.read("tracker.strict_descriptor_distance", t.strict_descriptor_distance);
  f.read("tracker.local_map_ratio", t.local_map_ratio);
  f.read("tracker.local_map_search_radius", t.local_map_search_radius);
  f.read("tracker.depth_weight", t.depth_weight);
  f.read("tracker.compensate_depth_time", t.compensate_depth_time);
  f.read("tracker.min_motion_matches", t.min_motion_matches);
  f.read("tracker.min_pose_inliers", t.min_pose_inliers);
  f.read("tracker.min_local_map_inliers", t.min_local_map_inliers);
  f.read("tracker.min_relocalisation_inliers", t.min_relocalisation_inliers);
  f.read("tracker.max_local_keyframes", t.max_local_keyframes);
  f.read("tracker.spatial_keyframes", t.spatial_keyframes);
  f.read("tracker.spatial_radius", t.spatial_radius);
  f.read("tracker.spatial_max_angle_deg", t.spatial_max_angle_deg);
  f.read("tracker.max_frames_between_keyframes", t.max_frames_between_keyframes);
  double fps = 0.0;
  if (f.read("Camera.fps", fps) && fps >= 1.0)
    t.max_frames_between_keyframes = static_cast<int>(fps);
  f.read("tracker.keyframe_ref_ratio", t.keyframe_ref_ratio);
  f.read("tracker.close_tracked_threshold", t.close_tracked_threshold);
  f.read("tracker.close_untracked_threshold", t.close_untracked_threshold);
  f.read("tracker.relocalisation_candidates", t.relocalisation_candidates);
  f.read("tracker.min_initial_points", t.min_initial_points);
  f.read("tracker.pose.rounds", t.pose.rounds);
  f.read("tracker.pose.iterations_per_round", t.pose.iterations_per_round);
  f.read("tracker.pose.robust_rounds", t.pose.robust_rounds);

  auto& m = o.mapper;
  f.read("mapper.min_new_points", m.min_new_points);
  f.read("mapper.fuse_neighbours", m.fuse_neighbours);
  f.read("mapper.fuse_radius", m.fuse_radius);
  f.read("mapper.depth_weight", m.depth_weight);
  f.read("mapper.ba_keyframes", m.ba_keyframes);
  f.read("mapper.min_covisibility_weight", m.min_covisibility_weight);
  f.read("mapper.redundant_ratio", m.redundant_ratio);
  f.read("mapper.cull_keyframes", m.cull_keyframes);
  f.read("mapper.global_ba_iterations", m.global_ba_iterations);
  f.read("mapper.ba.robust_iterations", m.ba.robust_iterations);
  f.read("mapper.ba.refine_iterations", m.ba.refine_iterations);
  f.read("mapper.ba.num_threads", m.ba.num_threads);
  f.read("system.sequential", o.sequential);

  // ORB-SLAM2 keys that describe things mcslam does not have (viewer, colour order, camera
  // model name) are accepted and ignored.
  for (const char* ignored : {"Viewer", "Camera.RGB", "Camera.type", "Camera.name",
                              "PointCloudMapping", "File.version", "Camera.fps"})
    f.mark_used(ignored);
  (void)camera;
}

}  // namespace

void apply_config(io::ConfigFile& file, PinholeCamera& camera, SystemOptions& options) {
  read_camera(file, camera);
  read_options(file, options, camera);
  const auto unused = file.unused_keys();
  if (!unused.empty()) {
    std::string list;
    for (const auto& k : unused) list += (list.empty() ? "" : ", ") + k;
    throw InputError(file_error(file.path(), "unknown key(s): " + list));
  }
  if (auto e = camera.check()) throw InputError(file_error(file.path(), "camera: " + *e));
  if (auto e = options.check()) throw InputError(file_error(file.path(), *e));
}

RunConfig resolve_run_config(const std::string& sequence_dir,
                             const std::optional<std::string>& settings_path) {
  namespace fs = std::filesystem;
  RunConfig config;
  bool have_camera = false;
  const std::string folder =
      fs::path(sequence_dir).lexically_normal().filename().string().empty()
          ? fs::path(sequence_dir).lexically_normal().parent_path().filename().string()
          : fs::path(sequence_dir).lexically_normal().filename().string();
  if (auto preset = io::camera_preset_for_sequence(folder)) {
    config.camera = *preset;
    config.camera_source = "preset chosen by the folder name '" + folder + "'";
    have_camera = true;
  }
  const fs::path camera_yaml = fs::path(sequence_dir) / "camera.yaml";
  if (fs::exists(camera_yaml)) {
    io::ConfigFile file = io::ConfigFile::load(camera_yaml.string());
    if (!have_camera) config.camera = PinholeCamera{};
    apply_config(file, config.camera, config.options);
    config.camera_source = camera_yaml.string();
    have_camera = true;
  }
  if (settings_path) {
    io::ConfigFile file = io::ConfigFile::load(*settings_path);
    const bool sets_camera = file.has("camera.fx") || file.has("Camera.fx");
    apply_config(file, config.camera, config.options);
    if (sets_camera) {
      config.camera_source = *settings_path;
      have_camera = true;
    }
  }
  if (!have_camera)
    throw InputError(file_error(sequence_dir,
                                "cannot tell the camera: the folder name contains none of "
                                "freiburg1/2/3 or bonn, there is no camera.yaml in it, and no "
                                "--config file sets camera.fx"));
  if (auto e = config.camera.check()) throw InputError(file_error(config.camera_source, *e));
  return config;
}

std::string to_yaml(const RunConfig& c) {
  std::ostringstream s;
  s.precision(10);
  const auto& cam = c.camera;
  const auto& o = c.options;
  s << "# mcslam effective configuration (camera from " << c.camera_source << ")\n";
  s << "camera:\n  fx: " << cam.fx << "\n  fy: " << cam.fy << "\n  cx: " << cam.cx
    << "\n  cy: " << cam.cy << "\n  width: " << cam.width << "\n  height: " << cam.height
    << "\n  k1: " << cam.distortion[0] << "\n  k2: " << cam.distortion[1]
    << "\n  p1: " << cam.distortion[2] << "\n  p2: " << cam.distortion[3]
    << "\n  k3: " << cam.distortion[4] << "\n  depth_factor: " << cam.depth_factor
    << "\n  bf: " << cam.bf << "\n  readout_time: " << cam.readout_time << "\n";
  s << "orb:\n  num_features: " << o.orb.num_features << "\n  num_levels: " << o.orb.num_levels
    << "\n  scale_factor: " << o.orb.scale_factor << "\n  fast_threshold: " << o.orb.fast_threshold
    << "\n  min_fast_threshold: " << o.orb.min_fast_threshold << "\n";
  const auto& t = o.tracker;
  s << "tracker:\n  close_depth_factor: " << t.close_depth_factor
    << "\n  min_depth: " << t.min_depth << "\n  max_depth: " << t.max_depth
    << "\n  motion_search_radius: " << t.motion_search_radius
    << "\n  max_descriptor_distance: " << t.max_descriptor_distance
    << "\n  strict_descriptor_distance: " << t.strict_descriptor_distance
    << "\n  local_map_ratio: " << t.local_map_ratio
    << "\n  local_map_search_radius: " << t.local_map_search_radius
    << "\n  depth_weight: " << t.depth_weight
    << "\n  compensate_depth_time: " << (t.compensate_depth_time ? "true" : "false")
    << "\n  min_motion_matches: " << t.min_motion_matches
    << "\n  min_pose_inliers: " << t.min_pose_inliers
    << "\n  min_local_map_inliers: " << t.min_local_map_inliers
    << "\n  min_relocalisation_inliers: " << t.min_relocalisation_inliers
    << "\n  max_local_keyframes: " << t.max_local_keyframes
    << "\n  spatial_keyframes: " << t.spatial_keyframes
    << "\n  spatial_radius: " << t.spatial_radius
    << "\n  spatial_max_angle_deg: " << t.spatial_max_angle_deg
    << "\n  max_frames_between_keyframes: " << t.max_frames_between_keyframes
    << "\n  keyframe_ref_ratio: " << t.keyframe_ref_ratio
    << "\n  close_tracked_threshold: " << t.close_tracked_threshold
    << "\n  close_untracked_threshold: " << t.close_untracked_threshold
    << "\n  relocalisation_candidates: " << t.relocalisation_candidates
    << "\n  min_initial_points: " << t.min_initial_points
    << "\n  pose:\n    rounds: " << t.pose.rounds
    << "\n    iterations_per_round: " << t.pose.iterations_per_round
    << "\n    robust_rounds: " << t.pose.robust_rounds << "\n";
  const auto& m = o.mapper;
  s << "mapper:\n  min_new_points: " << m.min_new_points
    << "\n  fuse_neighbours: " << m.fuse_neighbours << "\n  fuse_radius: " << m.fuse_radius
    << "\n  ba_keyframes: " << m.ba_keyframes
    << "\n  min_covisibility_weight: " << m.min_covisibility_weight
    << "\n  redundant_ratio: " << m.redundant_ratio
    << "\n  cull_keyframes: " << (m.cull_keyframes ? "true" : "false")
    << "\n  global_ba_iterations: " << m.global_ba_iterations
    << "\n  ba:\n    robust_iterations: " << m.ba.robust_iterations
    << "\n    refine_iterations: " << m.ba.refine_iterations
    << "\n    num_threads: " << m.ba.num_threads << "\n";
  s << "system:\n  sequential: " << (o.sequential ? "true" : "false") << "\n";
  return s.str();
}

}  // namespace mcslam::slam
