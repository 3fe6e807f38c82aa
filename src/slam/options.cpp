#include "mcslam/slam/options.hpp"

#include <cmath>
#include <cstdlib>

#include "mcslam/core/data_files.hpp"

namespace mcslam::slam {

std::optional<std::string> TrackerOptions::check() const {
  if (!(close_depth_factor > 0.0)) return "tracker.close_depth_factor must be positive";
  if (!(keyframe_close_depth_factor > 0.0))
    return "tracker.keyframe_close_depth_factor must be positive";
  if (!(min_depth >= 0.0) || !(max_depth > min_depth))
    return "tracker.min_depth must be >= 0 and below tracker.max_depth";
  if (!(motion_search_radius > 0.0)) return "tracker.motion_search_radius must be positive";
  if (max_descriptor_distance < 1 || max_descriptor_distance > 256)
    return "tracker.max_descriptor_distance must be in [1, 256]";
  if (!(depth_weight >= 0.0)) return "tracker.depth_weight must not be negative";
  if (!(angular_velocity_sigma > 0.0) || !std::isfinite(angular_velocity_sigma))
    return "tracker.angular_velocity_sigma must be positive and finite";
  if (!(refine_min_angular_velocity >= 0.0))
    return "tracker.refine_min_angular_velocity must not be negative";
  if (!(local_map_search_radius > 0.0)) return "tracker.local_map_search_radius must be positive";
  if (!(local_map_ratio > 0.0 && local_map_ratio <= 1.0))
    return "tracker.local_map_ratio must be in (0, 1]";
  if (!(established_age >= 0.0 && established_age <= 3600.0))
    return "tracker.established_age must be in [0, 3600] seconds (0: off)";
  if (!(established_gate >= 1.0 && established_gate <= 1000.0))
    return "tracker.established_gate must be in [1, 1000]";
  if (min_motion_matches < 3 || min_pose_inliers < 3 || min_local_map_inliers < 3 ||
      min_relocalisation_inliers < 3)
    return "tracker minimum match and inlier counts must be at least 3";
  if (max_local_keyframes < 1) return "tracker.max_local_keyframes must be at least 1";
  if (spatial_keyframes < 0) return "tracker.spatial_keyframes must not be negative";
  if (!(spatial_radius > 0.0)) return "tracker.spatial_radius must be positive";
  if (!(spatial_max_angle_deg > 0.0 && spatial_max_angle_deg <= 180.0))
    return "tracker.spatial_max_angle_deg must be in (0, 180]";
  if (max_frames_between_keyframes < 1)
    return "tracker.max_frames_between_keyframes must be at least 1";
  if (!(keyframe_ref_ratio > 0.0 && keyframe_ref_ratio <= 1.0))
    return "tracker.keyframe_ref_ratio must be in (0, 1]";
  if (!(std::isfinite(keyframe_interval) && keyframe_interval >= 0.0))
    return "tracker.keyframe_interval must be a number of seconds >= 0 (0: off)";
  if (relocalisation_candidates < 1) return "tracker.relocalisation_candidates must be >= 1";
  if (!std::isfinite(recovery_window) || recovery_window < 0.0)
    return "tracker.recovery_window must be finite and >= 0";
  if (min_initial_points < 10) return "tracker.min_initial_points must be at least 10";
  if (min_initial_lines < 3) return "tracker.min_initial_lines must be at least 3";
  if (plane_inlier_weight < 0) return "tracker.plane_inlier_weight must not be negative";
  if (!(line_sigma > 0.0)) return "tracker.line_sigma must be positive";
  if (line_max_descriptor_distance < 1 || line_max_descriptor_distance > 256)
    return "tracker.line_max_descriptor_distance must be in [1, 256]";
  if (!(line_max_angle_deg > 0.0 && line_max_angle_deg < 90.0))
    return "tracker.line_max_angle_deg must be in (0, 90)";
  if (!(line_max_distance > 0.0)) return "tracker.line_max_distance must be positive";
  if (!(line_min_overlap >= 0.0 && line_min_overlap <= 1.0))
    return "tracker.line_min_overlap must be in [0, 1]";
  if (!(plane_angle_sigma_deg > 0.0)) return "tracker.plane_angle_sigma_deg must be positive";
  if (!(plane_distance_sigma > 0.0)) return "tracker.plane_distance_sigma must be positive";
  if (!(plane_match_angle_deg > 0.0 && plane_match_angle_deg < 90.0))
    return "tracker.plane_match_angle_deg must be in (0, 90)";
  if (!(plane_match_distance > 0.0)) return "tracker.plane_match_distance must be positive";
  if (!(on_plane_distance > 0.0)) return "tracker.on_plane_distance must be positive";
  if (auto e = pose.check()) return e;
  if (auto e = pose_filter.check()) return "tracker." + *e;
  return dynamics.check();
}

std::optional<std::string> MapperOptions::check() const {
  if (global_ba_iterations < 0) return "mapper.global_ba_iterations must not be negative";
  if (min_new_points < 0) return "mapper.min_new_points must not be negative";
  if (fuse_neighbours < 0) return "mapper.fuse_neighbours must not be negative";
  if (!(fuse_radius > 0.0)) return "mapper.fuse_radius must be positive";
  if (fuse_descriptor_distance < 1 || fuse_descriptor_distance > 256)
    return "mapper.fuse_descriptor_distance must be in [1, 256]";
  if (!(depth_weight >= 0.0)) return "mapper.depth_weight must not be negative";
  if (ba_keyframes < 1) return "mapper.ba_keyframes must be at least 1";
  if (min_covisibility_weight < 1) return "mapper.min_covisibility_weight must be at least 1";
  if (!(redundant_ratio > 0.0 && redundant_ratio <= 1.0))
    return "mapper.redundant_ratio must be in (0, 1]";
  if (!(plane_merge_angle_deg > 0.0 && plane_merge_angle_deg < 90.0))
    return "mapper.plane_merge_angle_deg must be in (0, 90)";
  if (!(plane_merge_distance > 0.0)) return "mapper.plane_merge_distance must be positive";
  return ba.check();
}

std::optional<std::string> SystemOptions::check() const {
  if (!use.points && !use.lines && !use.planes)
    return "features.points, features.lines and features.planes are all off";
  if (extract_ahead != "auto" && extract_ahead != "true" && extract_ahead != "false")
    return "system.extract_ahead must be auto, true or false (not '" + extract_ahead + "')";
  if (detection_interval < 1 || detection_interval > 30)
    return "system.detection_interval must be in [1, 30] (frames)";
  if (background_niceness < 0 || background_niceness > 19)
    return "system.background_niceness must be in [0, 19]";
  if (detector_niceness < 0 || detector_niceness > 19)
    return "system.detector_niceness must be in [0, 19]";
  if (opencv_threads < 0 || opencv_threads > 256)
    return "system.opencv_threads must be in [0, 256] (0: OpenCV's default)";
  if (cold_start_keyframes < 0 || cold_start_keyframes > 1000)
    return "system.cold_start_keyframes must be in [0, 1000]";
  if (!(detector_scale == 0.0 || (detector_scale >= 0.05 && detector_scale <= 4.0)))
    return "system.detector_scale must be 0 (the model's own input) or in [0.05, 4]";
  if (auto e = orb.check()) return e;
  if (auto e = lines.check()) return e;
  if (auto e = planes.check()) return e;
  if (auto e = tracker.check()) return e;
  if (auto e = place.check()) return e;
  if (auto e = readout.check()) return e;
  if (auto e = trajectory.check()) return e;
  if (occupancy_enabled)
    if (auto e = occupancy.check()) return e;
  return mapper.check();
}

std::optional<std::string> LoopOptions::check() const {
  if (min_keyframes < 1) return "loop.min_keyframes must be at least 1";
  if (min_consistency < 1) return "loop.min_consistency must be at least 1";
  if (min_ransac_inliers < 3 || min_matches < min_ransac_inliers)
    return "loop.min_ransac_inliers must be at least 3 and loop.min_matches at least as many";
  if (min_inliers < min_ransac_inliers)
    return "loop.min_inliers must be at least loop.min_ransac_inliers";
  if (ransac_iterations < 1) return "loop.ransac_iterations must be at least 1";
  if (essential_edge_weight < 1) return "loop.essential_edge_weight must be at least 1";
  if (full_ba_iterations < 0) return "loop.full_ba_iterations must not be negative";
  return pose_graph.check();
}

std::string PlaceOptions::default_vocabulary_path() {
  if (const char* path = std::getenv("MCSLAM_VOCABULARY"); path != nullptr && *path != '\0')
    return path;
  return find_data_file("orb_vocabulary.bin");
}

std::optional<std::string> PlaceOptions::check() const {
  if (direct_levels_up < 0) return "place.direct_levels_up must not be negative";
  if (loop.enabled && vocabulary.empty())
    return "loop.enabled needs a vocabulary (place.vocabulary)";
  return loop.check();
}

}  // namespace mcslam::slam
