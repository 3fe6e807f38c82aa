#pragma once
// The sparse map: keyframes, point landmarks and the covisibility graph between keyframes.
//
// Ownership and threads: the local mapper is the only writer. The tracker receives a
// `const Map&` and reads it under a shared lock (Map::read_lock); the mapper modifies it under an
// exclusive lock (Map::write_lock) held only for short updates. Landmarks and keyframes are
// referenced by id, never by pointer, so an erased element can never dangle.

#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <unordered_map>
#include <vector>

#include "mcslam/core/se3.hpp"
#include "mcslam/features/frame_features.hpp"

namespace mcslam::map {

using KeyFrameId = std::uint64_t;
using PointId = std::uint64_t;
inline constexpr std::uint64_t kNoId = std::numeric_limits<std::uint64_t>::max();

struct KeyFrame {
  KeyFrameId id = kNoId;
  std::uint64_t frame_id = 0;
  double timestamp = 0.0;
  SE3 T_c_w;
  std::shared_ptr<const features::FrameFeatures> features;
  /// The landmark observed by each feature (kNoId where none); same size as features->points.
  std::vector<PointId> landmarks;
  /// Covisibility: number of landmarks shared with each other keyframe (only weights > 0).
  std::unordered_map<KeyFrameId, int> covisibility;

  SE3 T_w_c() const { return T_c_w.inverse(); }
  Eigen::Vector3d camera_center() const { return T_c_w.inverse().translation(); }
  int num_landmarks() const;
};

struct MapPoint {
  PointId id = kNoId;
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();
  /// The observation descriptor with the least median distance to the others.
  features::OrbDescriptor descriptor;
  /// keyframe -> index of the feature that observes this point.
  std::map<KeyFrameId, int> observations;
  /// Mean viewing direction (unit) and the scale-invariance distance range.
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double min_distance = 0.0;
  double max_distance = 0.0;
  KeyFrameId first_keyframe = kNoId;
  /// Tracking statistics for culling: frames in whose view it was, and frames that matched it.
  int visible = 1;
  int found = 1;

  double found_ratio() const { return static_cast<double>(found) / visible; }
};

/// How a culled keyframe's pose relates to a surviving one, so that frames referenced to it can
/// still be placed in the final trajectory.
struct ErasedKeyFrame {
  KeyFrameId parent = kNoId;
  SE3 T_this_parent;
};

class Map {
 public:
  std::shared_lock<std::shared_mutex> read_lock() const {
    return std::shared_lock<std::shared_mutex>(mutex_);
  }
  std::unique_lock<std::shared_mutex> write_lock() const {
    return std::unique_lock<std::shared_mutex>(mutex_);
  }

  // --- reads ---
  std::size_t num_keyframes() const { return keyframes_.size(); }
  std::size_t num_points() const { return points_.size(); }
  const KeyFrame* keyframe(KeyFrameId id) const;
  const MapPoint* point(PointId id) const;
  const std::unordered_map<KeyFrameId, KeyFrame>& keyframes() const { return keyframes_; }
  const std::unordered_map<PointId, MapPoint>& points() const { return points_; }
  /// Up to `n` covisible keyframes of `id`, by decreasing weight (ties: increasing id).
  std::vector<KeyFrameId> best_covisible(KeyFrameId id, std::size_t n, int min_weight = 1) const;
  /// The pose of a keyframe, following the chain of culled keyframes to a surviving one.
  std::optional<SE3> keyframe_pose_T_c_w(KeyFrameId id) const;
  KeyFrameId last_keyframe_id() const { return last_keyframe_; }
  std::uint64_t version() const { return version_; }

  // --- writes (local mapper only) ---
  /// Keeps keyframe.id when it is set and unused (the tracker numbers keyframes); otherwise
  /// assigns the next free id. Returns the id.
  KeyFrameId add_keyframe(KeyFrame keyframe);
  PointId add_point(const Eigen::Vector3d& p_w, KeyFrameId keyframe, int feature_index);
  /// Links feature `feature_index` of `keyframe` to `point`; replaces nothing already linked.
  void add_observation(PointId point, KeyFrameId keyframe, int feature_index);
  void erase_observation(PointId point, KeyFrameId keyframe);
  void erase_point(PointId point);
  /// Replaces `old_point` by `new_point` in every keyframe that observes it, then erases it.
  void replace_point(PointId old_point, PointId new_point);
  void erase_keyframe(KeyFrameId keyframe);
  void set_keyframe_pose(KeyFrameId id, const SE3& T_c_w);
  void set_point_position(PointId id, const Eigen::Vector3d& p_w);
  /// Recomputes descriptor, normal and distance range of a point from its observations.
  void update_point_appearance(PointId id);
  /// Recomputes the covisibility weights of `id` (and the reverse edges).
  void update_covisibility(KeyFrameId id);
  void add_tracking_statistics(PointId id, int visible, int found);
  void bump_version() { ++version_; }

 private:
  mutable std::shared_mutex mutex_;
  std::unordered_map<KeyFrameId, KeyFrame> keyframes_;
  std::unordered_map<PointId, MapPoint> points_;
  std::unordered_map<KeyFrameId, ErasedKeyFrame> erased_keyframes_;
  KeyFrameId next_keyframe_id_ = 0;
  PointId next_point_id_ = 0;
  KeyFrameId last_keyframe_ = kNoId;
  std::uint64_t version_ = 0;
};

}  // namespace mcslam::map
