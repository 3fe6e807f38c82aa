#pragma once
// What the dense map (mapping::) needs of the SLAM system, computed from what the system already
// has: the pixels of a keyframe's people and movers, and the floor among the sparse map's
// planes. The dense map itself knows nothing of the tracker or the sparse map.

#include <opencv2/core/mat.hpp>
#include <optional>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/map/map.hpp"
#include "mcslam/mapping/occupancy_map.hpp"
#include "mcslam/slam/dynamics.hpp"

namespace mcslam::slam {

struct ObjectReport;

/// An image region of a person or another mover in a keyframe (undistorted pixels), and the
/// depth band of its own features: what lies farther inside the box is the static background
/// seen past it. depth_far <= 0: the whole box.
struct DynamicRegion {
  cv::Rect2f box;
  float depth_near = -1.0f;
  float depth_far = -1.0f;
  int track_id = -1;  ///< the object's track (ObjectReport::track_id), -1 without one
};

/// The regions of a frame's objects in `state`: ObjectState::kDynamic (people, movers without a
/// box: never obstacles) or kConstrained (a pushed chair: an obstacle where it is now, freed
/// where it was as soon as a keyframe sees through its old place).
std::vector<DynamicRegion> object_regions(const std::vector<ObjectReport>& objects,
                                          ObjectState state);

/// A keyframe (or a view) for the dense map: the frame's undistorted depth (shared) seen by
/// `camera` without its distortion, at T_w_c; the masks of its people and movers (region_mask,
/// depth bands widened by depth_margin metres); its objects seen still (by track, bands widened
/// alike) and the tracks of its moving ones (mapping::KeyframeDepth::still_objects,
/// moving_objects). The id and the colour are the caller's to set.
mapping::KeyframeDepth dense_keyframe(const PinholeCamera& camera, const cv::Mat& depth,
                                      const SE3& T_w_c, const std::vector<DynamicRegion>& still,
                                      const std::vector<DynamicRegion>& dynamic,
                                      const std::vector<DynamicRegion>& movers,
                                      double depth_margin);

/// CV_8UC1 of depth's size, 255 on the pixels of the regions whose depth lies within their band
/// widened by `depth_margin` metres (or has no depth), 0 elsewhere; empty without regions.
cv::Mat region_mask(const cv::Mat& depth, const std::vector<DynamicRegion>& regions,
                    double depth_margin);

/// Where a region's object is in the world: the depth pixels of its box within its band (every
/// `step`-th pixel of every `step`-th row), back-projected with `camera` (undistorted) and moved
/// by T_w_c; the 5th to 95th percentile on each world axis (min, max). nullopt with fewer than
/// 10 such pixels.
std::optional<std::pair<Eigen::Vector3d, Eigen::Vector3d>> world_box(
    const PinholeCamera& camera, const cv::Mat& depth, const DynamicRegion& region,
    const SE3& T_w_c, double depth_margin, int step = 4);

/// The sparse map's planes that may be the floor: near-horizontal (within max_tilt_deg of "up",
/// the first keyframe's image up, -y of its camera), below the first keyframe's camera by 0.2
/// to 3 m, seen from at least min_keyframes keyframes; normals up (towards the cameras). The
/// dense map keeps the one its voxels agree with (mapping::choose_floor).
std::vector<mapping::FloorPlane> floor_candidates(const map::Map& map, double max_tilt_deg = 15.0,
                                                  std::size_t min_keyframes = 3);

}  // namespace mcslam::slam
