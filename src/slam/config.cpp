#include "mcslam/slam/config.hpp"

#include <filesystem>
#include <sstream>
#include <variant>
#include <vector>

#include "mcslam/core/error.hpp"
#include "mcslam/io/camera_presets.hpp"

namespace mcslam::slam {
namespace {

/// The readout time: a number of seconds, or `auto` (estimated while running).
struct ReadoutRef {
  double* time;
  bool* automatic;
};

/// A list of names is written as one comma-separated scalar ("chair, dining table").
using FieldRef =
    std::variant<double*, int*, bool*, std::string*, std::vector<std::string>*, ReadoutRef>;
struct Field {
  std::string key;
  FieldRef value;
};

/// Every setting under its mcslam key, in the order of the effective configuration file. One
/// table serves reading and writing, so that a written configuration always loads back.
std::vector<Field> mcslam_fields(PinholeCamera& c, SystemOptions& o) {
  auto& t = o.tracker;
  auto& m = o.mapper;
  return {
      {"camera.fx", &c.fx},
      {"camera.fy", &c.fy},
      {"camera.cx", &c.cx},
      {"camera.cy", &c.cy},
      {"camera.width", &c.width},
      {"camera.height", &c.height},
      {"camera.k1", &c.distortion[0]},
      {"camera.k2", &c.distortion[1]},
      {"camera.p1", &c.distortion[2]},
      {"camera.p2", &c.distortion[3]},
      {"camera.k3", &c.distortion[4]},
      {"camera.depth_factor", &c.depth_factor},
      {"camera.bf", &c.bf},
      {"camera.readout_time", ReadoutRef{&c.readout_time, &c.readout_auto}},
      {"features.points", &o.use.points},
      {"features.lines", &o.use.lines},
      {"features.planes", &o.use.planes},
      {"orb.num_features", &o.orb.num_features},
      {"orb.num_levels", &o.orb.num_levels},
      {"orb.scale_factor", &o.orb.scale_factor},
      {"orb.fast_threshold", &o.orb.fast_threshold},
      {"orb.min_fast_threshold", &o.orb.min_fast_threshold},
      {"orb.moving_density", &o.orb.moving_density},
      {"lines.detector", &o.lines.detector},
      {"lines.min_length", &o.lines.min_length},
      {"lines.max_lines", &o.lines.max_lines},
      {"lines.detection_scale", &o.lines.detection_scale},
      {"lines.depth_samples", &o.lines.depth_samples},
      {"lines.min_valid_fraction", &o.lines.min_valid_fraction},
      {"lines.fit_tolerance", &o.lines.fit_tolerance},
      {"lines.fit_tolerance_per_metre", &o.lines.fit_tolerance_per_metre},
      {"lines.min_inlier_fraction", &o.lines.min_inlier_fraction},
      {"planes.cell_size", &o.planes.cell_size},
      {"planes.pixel_step", &o.planes.pixel_step},
      {"planes.cell_tolerance", &o.planes.cell_tolerance},
      {"planes.cell_tolerance_per_metre", &o.planes.cell_tolerance_per_metre},
      {"planes.merge_angle_deg", &o.planes.merge_angle_deg},
      {"planes.merge_distance", &o.planes.merge_distance},
      {"planes.min_area_fraction", &o.planes.min_area_fraction},
      {"planes.max_fit_rms", &o.planes.max_fit_rms},
      {"planes.max_planes", &o.planes.max_planes},
      {"planes.coplanar_angle_deg", &o.planes.coplanar_angle_deg},
      {"planes.coplanar_distance", &o.planes.coplanar_distance},
      {"tracker.close_depth_factor", &t.close_depth_factor},
      {"tracker.keyframe_close_depth_factor", &t.keyframe_close_depth_factor},
      {"tracker.min_depth", &t.min_depth},
      {"tracker.max_depth", &t.max_depth},
      {"tracker.motion_search_radius", &t.motion_search_radius},
      {"tracker.max_descriptor_distance", &t.max_descriptor_distance},
      {"tracker.local_map_ratio", &t.local_map_ratio},
      {"tracker.local_map_search_radius", &t.local_map_search_radius},
      {"tracker.depth_weight", &t.depth_weight},
      {"tracker.compensate_depth_time", &t.compensate_depth_time},
      {"tracker.refine_rolling_shutter", &t.refine_rolling_shutter},
      {"tracker.filtered_angular_velocity", &t.filtered_angular_velocity},
      {"tracker.angular_velocity_sigma", &t.angular_velocity_sigma},
      {"tracker.refine_min_angular_velocity", &t.refine_min_angular_velocity},
      {"tracker.min_motion_matches", &t.min_motion_matches},
      {"tracker.min_pose_inliers", &t.min_pose_inliers},
      {"tracker.min_local_map_inliers", &t.min_local_map_inliers},
      {"tracker.min_relocalisation_inliers", &t.min_relocalisation_inliers},
      {"tracker.max_local_keyframes", &t.max_local_keyframes},
      {"tracker.spatial_keyframes", &t.spatial_keyframes},
      {"tracker.spatial_radius", &t.spatial_radius},
      {"tracker.spatial_max_angle_deg", &t.spatial_max_angle_deg},
      {"tracker.max_frames_between_keyframes", &t.max_frames_between_keyframes},
      {"tracker.keyframe_ref_ratio", &t.keyframe_ref_ratio},
      {"tracker.keyframe_interval", &t.keyframe_interval},
      {"tracker.close_tracked_threshold", &t.close_tracked_threshold},
      {"tracker.close_untracked_threshold", &t.close_untracked_threshold},
      {"tracker.relocalisation_candidates", &t.relocalisation_candidates},
      {"tracker.recovery_window", &t.recovery_window},
      {"tracker.min_initial_points", &t.min_initial_points},
      {"tracker.min_initial_lines", &t.min_initial_lines},
      {"tracker.plane_inlier_weight", &t.plane_inlier_weight},
      {"tracker.established_age", &t.established_age},
      {"tracker.established_gate", &t.established_gate},
      {"tracker.line_sigma", &t.line_sigma},
      {"tracker.line_max_descriptor_distance", &t.line_max_descriptor_distance},
      {"tracker.line_max_angle_deg", &t.line_max_angle_deg},
      {"tracker.line_max_distance", &t.line_max_distance},
      {"tracker.line_min_overlap", &t.line_min_overlap},
      {"tracker.plane_angle_sigma_deg", &t.plane_angle_sigma_deg},
      {"tracker.plane_distance_sigma", &t.plane_distance_sigma},
      {"tracker.plane_match_angle_deg", &t.plane_match_angle_deg},
      {"tracker.plane_match_distance", &t.plane_match_distance},
      {"tracker.on_plane_distance", &t.on_plane_distance},
      {"tracker.pose.rounds", &t.pose.rounds},
      {"tracker.pose.iterations_per_round", &t.pose.iterations_per_round},
      {"tracker.pose.robust_rounds", &t.pose.robust_rounds},
      {"tracker.pose.chi2_constraint", &t.pose.chi2_constraint},
      {"tracker.pose_filter.enabled", &t.pose_filter.enabled},
      {"tracker.pose_filter.acceleration_density", &t.pose_filter.acceleration_density},
      {"tracker.pose_filter.angular_acceleration_density",
       &t.pose_filter.angular_acceleration_density},
      {"tracker.pose_filter.measurement_noise_scale", &t.pose_filter.measurement_noise_scale},
      {"tracker.pose_filter.downweight_chi2", &t.pose_filter.downweight_chi2},
      {"tracker.pose_filter.gate_chi2", &t.pose_filter.gate_chi2},
      {"tracker.pose_filter.held_frames", &t.pose_filter.held_frames},
      {"tracker.pose_filter.follow_map", &t.pose_filter.follow_map},
      {"tracker.pose_filter.max_gap", &t.pose_filter.max_gap},
      {"tracker.pose_filter.adaptive_memory", &t.pose_filter.adaptive_memory},
      {"tracker.pose_filter.noise_window", &t.pose_filter.noise_window},
      {"tracker.pose_filter.max_liveliness", &t.pose_filter.max_liveliness},
      {"tracker.pose_filter.lag", &t.pose_filter.lag},
      {"dynamics.enabled", &t.dynamics.enabled},
      {"dynamics.epipolar_threshold", &t.dynamics.epipolar_threshold},
      {"dynamics.background_factor", &t.dynamics.background_factor},
      {"dynamics.outlier_ratio", &t.dynamics.outlier_ratio},
      {"dynamics.min_matches", &t.dynamics.min_matches},
      {"dynamics.min_reference_matches", &t.dynamics.min_reference_matches},
      {"dynamics.ransac_threshold", &t.dynamics.ransac_threshold},
      {"dynamics.match_radius", &t.dynamics.match_radius},
      {"dynamics.descriptor_distance", &t.dynamics.descriptor_distance},
      {"dynamics.line_descriptor_distance", &t.dynamics.line_descriptor_distance},
      {"dynamics.frame_gap", &t.dynamics.frame_gap},
      {"dynamics.plane_distance", &t.dynamics.plane_distance},
      {"dynamics.structural_outside", &t.dynamics.structural_outside},
      {"dynamics.person_prior", &t.dynamics.person_prior},
      {"dynamics.constrained_classes", &t.dynamics.constrained_classes},
      {"dynamics.moving_classes", &t.dynamics.moving_classes},
      {"dynamics.moving_class_static_frames", &t.dynamics.moving_class_static_frames},
      {"dynamics.static_frames_to_clear", &t.dynamics.static_frames_to_clear},
      {"dynamics.propagate_boxes", &t.dynamics.propagate_boxes},
      {"dynamics.propagation_radius", &t.dynamics.propagation_radius},
      {"dynamics.min_propagation_matches", &t.dynamics.min_propagation_matches},
      {"dynamics.propagation_margin", &t.dynamics.propagation_margin},
      {"dynamics.propagate_by_flow", &t.dynamics.propagate_by_flow},
      {"dynamics.flow_max_error", &t.dynamics.flow_max_error},
      {"dynamics.separate_background", &t.dynamics.separate_background},
      {"dynamics.object_depth_gap", &t.dynamics.object_depth_gap},
      {"dynamics.find_movers", &t.dynamics.find_movers},
      {"dynamics.mover_displacement", &t.dynamics.mover_displacement},
      {"dynamics.mover_relative", &t.dynamics.mover_relative},
      {"dynamics.mover_pixels", &t.dynamics.mover_pixels},
      {"dynamics.mover_link_radius", &t.dynamics.mover_link_radius},
      {"dynamics.mover_link_depth", &t.dynamics.mover_link_depth},
      {"dynamics.mover_min_seeds", &t.dynamics.mover_min_seeds},
      {"dynamics.mover_seed_share", &t.dynamics.mover_seed_share},
      {"dynamics.mover_max_width", &t.dynamics.mover_max_width},
      {"dynamics.mover_max_height", &t.dynamics.mover_max_height},
      {"dynamics.constraints", &t.dynamics.constraints},
      {"dynamics.constraint_distance", &t.dynamics.constraint_distance},
      {"dynamics.constraint_angle_deg", &t.dynamics.constraint_angle_deg},
      {"dynamics.min_constraint_points", &t.dynamics.min_constraint_points},
      {"dynamics.min_constraint_lines", &t.dynamics.min_constraint_lines},
      {"dynamics.constraint_point_sigma", &t.dynamics.constraint_point_sigma},
      {"dynamics.constraint_line_sigma", &t.dynamics.constraint_line_sigma},
      {"mapper.min_new_points", &m.min_new_points},
      {"mapper.fuse_neighbours", &m.fuse_neighbours},
      {"mapper.fuse_radius", &m.fuse_radius},
      {"mapper.fuse_descriptor_distance", &m.fuse_descriptor_distance},
      {"mapper.depth_weight", &m.depth_weight},
      {"mapper.disparity_residual", &m.disparity_residual},
      {"mapper.ba_keyframes", &m.ba_keyframes},
      {"mapper.min_covisibility_weight", &m.min_covisibility_weight},
      {"mapper.redundant_ratio", &m.redundant_ratio},
      {"mapper.cull_keyframes", &m.cull_keyframes},
      {"mapper.plane_merge_angle_deg", &m.plane_merge_angle_deg},
      {"mapper.plane_merge_distance", &m.plane_merge_distance},
      {"mapper.global_ba_iterations", &m.global_ba_iterations},
      {"mapper.ba.robust_iterations", &m.ba.robust_iterations},
      {"mapper.ba.refine_iterations", &m.ba.refine_iterations},
      {"place.vocabulary", &o.place.vocabulary},
      {"place.direct_levels_up", &o.place.direct_levels_up},
      {"loop.enabled", &o.place.loop.enabled},
      {"loop.min_keyframes", &o.place.loop.min_keyframes},
      {"loop.min_consistency", &o.place.loop.min_consistency},
      {"loop.min_matches", &o.place.loop.min_matches},
      {"loop.min_ransac_inliers", &o.place.loop.min_ransac_inliers},
      {"loop.min_inliers", &o.place.loop.min_inliers},
      {"loop.ransac_iterations", &o.place.loop.ransac_iterations},
      {"loop.essential_edge_weight", &o.place.loop.essential_edge_weight},
      {"loop.pose_graph.iterations", &o.place.loop.pose_graph.iterations},
      {"loop.pose_graph.sigma_translation", &o.place.loop.pose_graph.sigma_translation},
      {"loop.pose_graph.sigma_rotation", &o.place.loop.pose_graph.sigma_rotation},
      {"loop.full_ba_iterations", &o.place.loop.full_ba_iterations},
      {"readout.min_angular_velocity", &o.readout.min_angular_velocity},
      {"readout.min_points", &o.readout.min_points},
      {"readout.min_frames", &o.readout.min_frames},
      {"readout.max_std", &o.readout.max_std},
      {"readout.min_significance", &o.readout.min_significance},
      {"readout.huber", &o.readout.huber},
      {"readout.max_readout", &o.readout.max_readout},
      {"readout.anchor_age", &o.readout.anchor_age},
      {"readout.calibration_seconds", &o.readout.calibration_seconds},
      {"trajectory.smoothing", &o.trajectory.enabled},
      {"trajectory.acceleration_density", &o.trajectory.acceleration_density},
      {"trajectory.outlier_sigmas", &o.trajectory.outlier_sigmas},
      {"trajectory.max_gap", &o.trajectory.max_gap},
      {"trajectory.iterations", &o.trajectory.iterations},
      {"mapping.enabled", &o.occupancy_enabled},
      {"mapping.resolution", &o.occupancy.resolution},
      {"mapping.max_range", &o.occupancy.max_range},
      {"mapping.depth_noise_k", &o.occupancy.depth_noise_k},
      {"mapping.free_margin_sigmas", &o.occupancy.free_margin_sigmas},
      {"mapping.spread_yield_ratio", &o.occupancy.spread_yield_ratio},
      {"mapping.tail_yield_ratio", &o.occupancy.tail_yield_ratio},
      {"mapping.prob_hit", &o.occupancy.prob_hit},
      {"mapping.prob_miss", &o.occupancy.prob_miss},
      {"mapping.prob_occupied", &o.occupancy.prob_occupied},
      {"mapping.clamp_min", &o.occupancy.clamp_min},
      {"mapping.clamp_max", &o.occupancy.clamp_max},
      {"mapping.pixel_step", &o.occupancy.pixel_step},
      {"mapping.mask_dilation_px", &o.occupancy.mask_dilation_px},
      {"mapping.use_masks", &o.occupancy.use_masks},
      {"mapping.store_colour", &o.occupancy.store_colour},
      {"mapping.band_min", &o.occupancy.band_min},
      {"mapping.band_max", &o.occupancy.band_max},
      {"mapping.rebuild_tolerance", &o.occupancy.rebuild_tolerance},
      {"mapping.rebuild_threads", &o.occupancy.rebuild_threads},
      {"mapping.integration", &o.occupancy.integration},
      {"mapping.localize_view_period", &o.occupancy.localize_view_period},
      {"mapping.niceness", &o.occupancy.niceness},
      {"system.sequential", &o.sequential},
      {"system.wait_for_keyframe_points", &o.wait_for_keyframe_points},
      {"system.extract_ahead", &o.extract_ahead},
      {"system.detection_interval", &o.detection_interval},
      {"system.background_niceness", &o.background_niceness},
      {"system.detector_niceness", &o.detector_niceness},
      {"system.opencv_threads", &o.opencv_threads},
      {"system.cold_start_keyframes", &o.cold_start_keyframes},
      {"system.detector_scale", &o.detector_scale},
  };
}

/// ORB-SLAM2 settings keys, read after mcslam's (so they win when a file has both).
std::vector<Field> orbslam2_fields(PinholeCamera& c, SystemOptions& o) {
  return {
      {"Camera.fx", &c.fx},
      {"Camera.fy", &c.fy},
      {"Camera.cx", &c.cx},
      {"Camera.cy", &c.cy},
      {"Camera.width", &c.width},
      {"Camera.height", &c.height},
      {"Camera.k1", &c.distortion[0]},
      {"Camera.k2", &c.distortion[1]},
      {"Camera.p1", &c.distortion[2]},
      {"Camera.p2", &c.distortion[3]},
      {"Camera.k3", &c.distortion[4]},
      {"Camera.bf", &c.bf},
      {"DepthMapFactor", &c.depth_factor},
      {"ORBextractor.nFeatures", &o.orb.num_features},
      {"ORBextractor.nLevels", &o.orb.num_levels},
      {"ORBextractor.scaleFactor", &o.orb.scale_factor},
      {"ORBextractor.iniThFAST", &o.orb.fast_threshold},
      {"ORBextractor.minThFAST", &o.orb.min_fast_threshold},
  };
}

std::string join_names(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

void read_readout(io::ConfigFile& file, const std::string& key, ReadoutRef value) {
  std::string text;
  if (!file.has(key)) return;
  const bool is_auto = file.read(key, text) && text == "auto";
  if (is_auto) {
    // The value so far (a preset's, or 0) stays as the starting value of the estimate.
    *value.automatic = true;
    return;
  }
  file.read(key, *value.time);  // a number (throws otherwise)
  *value.automatic = false;
}

void read_fields(io::ConfigFile& file, const std::vector<Field>& fields) {
  for (const Field& f : fields)
    std::visit(
        [&](auto value) {
          if constexpr (std::is_same_v<decltype(value), ReadoutRef>) {
            read_readout(file, f.key, value);
          } else if constexpr (std::is_same_v<decltype(value), std::vector<std::string>*>) {
            std::string list;
            if (!file.read(f.key, list)) return;
            value->clear();
            std::stringstream stream(list);
            for (std::string name; std::getline(stream, name, ',');) {
              const auto first = name.find_first_not_of(" \t");
              if (first == std::string::npos) continue;
              value->push_back(name.substr(first, name.find_last_not_of(" \t") - first + 1));
            }
          } else {
            file.read(f.key, *value);
          }
        },
        f.value);
}

}  // namespace

void apply_config(io::ConfigFile& file, PinholeCamera& camera, SystemOptions& options) {
  read_fields(file, mcslam_fields(camera, options));
  read_fields(file, orbslam2_fields(camera, options));
  // ORB-SLAM2's camera rate sets the keyframe interval; its viewer, colour order and camera
  // model name describe things mcslam does not have and are accepted and ignored.
  double fps = 0.0;
  if (file.read("Camera.fps", fps) && fps >= 1.0)
    options.tracker.max_frames_between_keyframes = static_cast<int>(fps);
  // ORB-SLAM2's one close-depth threshold serves both of mcslam's.
  double th_depth = 0.0;
  if (file.read("ThDepth", th_depth))
    options.tracker.close_depth_factor = options.tracker.keyframe_close_depth_factor = th_depth;
  for (const char* ignored :
       {"Viewer", "Camera.RGB", "Camera.type", "Camera.name", "PointCloudMapping", "File.version"})
    file.mark_used(ignored);
  // Retired: bundle adjustment runs on one thread since it left Ceres. Accepted and ignored, so
  // that the config.yaml of an earlier run still loads.
  file.mark_used("mapper.ba.num_threads");

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
  return resolve_run_config(sequence_dir, settings_path, io::CameraHints{}, std::nullopt);
}

RunConfig resolve_run_config(const std::string& source_path,
                             const std::optional<std::string>& settings_path,
                             const io::CameraHints& hints,
                             const std::optional<std::string>& preset_name) {
  namespace fs = std::filesystem;
  RunConfig config;
  bool have_camera = false;
  fs::path normal = fs::path(source_path).lexically_normal();
  if (normal.filename().empty()) normal = normal.parent_path();  // "dir/" names "dir"
  const std::string folder = normal.filename().string();
  if (preset_name) {
    const auto preset = io::camera_preset(*preset_name);
    if (!preset) {
      std::string names;
      for (const auto& n : io::camera_preset_names()) names += (names.empty() ? "" : ", ") + n;
      throw InputError("--camera-preset: unknown preset '" + *preset_name + "' (use one of " +
                       names + ")");
    }
    config.camera = *preset;
    config.camera_source = "preset " + *preset_name + " (--camera-preset)";
    have_camera = true;
  } else if (auto preset = io::camera_preset_for_sequence(folder)) {
    config.camera = *preset;
    config.camera_source = "preset chosen by the folder name '" + folder + "'";
    have_camera = true;
  }
  const fs::path camera_yaml = fs::path(source_path) / "camera.yaml";
  if (fs::is_directory(source_path) && fs::exists(camera_yaml)) {
    io::ConfigFile file = io::ConfigFile::load(camera_yaml.string());
    apply_config(file, config.camera, config.options);
    config.camera_source = camera_yaml.string();
    have_camera = true;
  }
  if (hints.settings_yaml) {
    io::ConfigFile file = io::ConfigFile::from_string(*hints.settings_yaml, hints.settings_name);
    apply_config(file, config.camera, config.options);
    config.camera_source = hints.settings_name;
    have_camera = true;
  }
  if (hints.intrinsics) {
    const io::CameraHints::Intrinsics& k = *hints.intrinsics;
    config.camera.fx = k.fx;
    config.camera.fy = k.fy;
    config.camera.cx = k.cx;
    config.camera.cy = k.cy;
    config.camera.width = k.width;
    config.camera.height = k.height;
    config.camera.distortion = k.distortion;
    config.camera_source = have_camera
                               ? config.camera_source + ", intrinsics from " + hints.intrinsics_name
                               : hints.intrinsics_name;
    have_camera = true;
    if (auto e = config.camera.check()) throw InputError(file_error(hints.intrinsics_name, *e));
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
    throw InputError(file_error(source_path,
                                "cannot tell the camera: the name contains none of "
                                "freiburg1/2/3 or bonn, there is no camera.yaml (or camera_info) "
                                "in it, and neither --camera-preset nor a --config file that "
                                "sets camera.fx is given"));
  if (auto e = config.camera.check()) throw InputError(file_error(config.camera_source, *e));
  return config;
}

std::string to_yaml(const RunConfig& config) { return to_yaml(config, ReadoutReport{}); }

std::string to_yaml(const RunConfig& config, const ReadoutReport& readout) {
  RunConfig copy = config;  // the field table takes mutable references
  std::ostringstream s;
  s.precision(10);
  s << "# mcslam effective configuration (camera from " << config.camera_source << ")\n";
  std::vector<std::string> open;  // the map path of the previous key
  for (const Field& f : mcslam_fields(copy.camera, copy.options)) {
    std::vector<std::string> parts;
    std::stringstream key(f.key);
    for (std::string part; std::getline(key, part, '.');) parts.push_back(part);
    std::size_t common = 0;
    while (common < open.size() && common + 1 < parts.size() && open[common] == parts[common])
      ++common;
    for (std::size_t i = common; i + 1 < parts.size(); ++i)
      s << std::string(2 * i, ' ') << parts[i] << ":\n";
    open.assign(parts.begin(), parts.end() - 1);
    s << std::string(2 * (parts.size() - 1), ' ') << parts.back() << ": ";
    std::visit(
        [&](auto value) {
          if constexpr (std::is_same_v<decltype(value), ReadoutRef>) {
            if (*value.automatic) {
              s << "auto";
              if (readout.automatic) {
                std::ostringstream note;
                note.precision(3);
                note << "  # used " << readout.readout_time * 1e3 << " ms; estimated "
                     << readout.estimate * 1e3 << " +- " << readout.std * 1e3 << " ms from "
                     << readout.frames_used << " frames, "
                     << (readout.confident ? "confident" : "not confident");
                s << note.str();
              }
            } else
              s << *value.time;
          } else if constexpr (std::is_same_v<decltype(value), bool*>)
            s << (*value ? "true" : "false");
          else if constexpr (std::is_same_v<decltype(value), std::vector<std::string>*>)
            s << join_names(*value);
          else
            s << *value;
        },
        f.value);
    s << "\n";
  }
  return s.str();
}

}  // namespace mcslam::slam
