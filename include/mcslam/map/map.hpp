#pragma once
// The sparse map: keyframes, point, line and plane landmarks, and the covisibility graph between
// keyframes.
//
// Ownership and threads: the local mapper is the only writer. The tracker receives a
// `const Map&` and reads it under a shared lock (Map::read_lock); the mapper modifies it under an
// exclusive lock (Map::write_lock) held only for short updates. Landmarks and keyframes are
// referenced by id, never by pointer, so an erased element can never dangle.

#include <array>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <shared_mutex>
#include <unordered_map>
#include <vector>

#include "mcslam/core/se3.hpp"
#include "mcslam/features/frame_features.hpp"
#include "mcslam/place/database.hpp"
#include "mcslam/place/vocabulary.hpp"

namespace mcslam::map {

using KeyFrameId = std::uint64_t;
using PointId = std::uint64_t;
using LineId = std::uint64_t;
using PlaneId = std::uint64_t;
inline constexpr std::uint64_t kNoId = std::numeric_limits<std::uint64_t>::max();

struct KeyFrame {
  KeyFrameId id = kNoId;
  std::uint64_t frame_id = 0;
  double timestamp = 0.0;
  SE3 T_c_w;
  std::shared_ptr<const features::FrameFeatures> features;
  /// The landmark observed by each feature (kNoId where none); same size as features->points.
  std::vector<PointId> landmarks;
  /// The same for the frame's line segments (features->lines) and planes (features->planes).
  std::vector<LineId> line_landmarks;
  std::vector<PlaneId> plane_landmarks;
  /// Features on moving (dynamic or constrained) objects, 1 per excluded point / segment: no
  /// landmark is created or fused there. Empty when the keyframe saw no moving object.
  std::vector<std::uint8_t> excluded_points;
  std::vector<std::uint8_t> excluded_lines;
  bool point_excluded(std::size_t i) const {
    return i < excluded_points.size() && excluded_points[i] != 0;
  }
  bool line_excluded(std::size_t i) const {
    return i < excluded_lines.size() && excluded_lines[i] != 0;
  }
  /// Covisibility: number of landmarks shared with each other keyframe (only weights > 0).
  std::unordered_map<KeyFrameId, int> covisibility;
  /// Bag of words of the static points (moving objects' features take no part), with the direct
  /// index; null without a vocabulary.
  std::shared_ptr<const place::BowImage> bow;
  /// Keyframes this one closed a loop with (both ends hold the edge).
  std::set<KeyFrameId> loop_edges;

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
  /// Colour (R, G, B) of the keyframe image where the point was created, for display.
  std::array<std::uint8_t, 3> color{160, 160, 160};
  /// Tracking statistics for culling: frames in whose view it was, and frames that matched it.
  int visible = 1;
  int found = 1;

  double found_ratio() const { return static_cast<double>(found) / visible; }
};

/// A 3D line segment, stored by its two endpoints as the paper does. The endpoints span what the
/// observations have seen of the line (they grow as new observations extend it).
struct MapLine {
  LineId id = kNoId;
  Eigen::Vector3d start_w = Eigen::Vector3d::Zero();
  Eigen::Vector3d end_w = Eigen::Vector3d::Zero();
  /// The observation descriptor with the least median distance to the others.
  features::LineDescriptor descriptor;
  /// keyframe -> index of the segment that observes this line.
  std::map<KeyFrameId, int> observations;
  KeyFrameId first_keyframe = kNoId;
  int visible = 1;
  int found = 1;

  Eigen::Vector3d direction() const { return (end_w - start_w).normalized(); }
  double length() const { return (end_w - start_w).norm(); }
  double found_ratio() const { return static_cast<double>(found) / visible; }
};

/// An infinite plane n . p + d = 0 (world frame, |n| = 1) and the extent observed of it.
struct MapPlane {
  PlaneId id = kNoId;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double d = 0.0;
  /// keyframe -> index of the frame plane that observes it.
  std::map<KeyFrameId, int> observations;
  /// Convex hull (world frame, in the plane) of everything observed of the plane, for display.
  std::vector<Eigen::Vector3d> hull;
  KeyFrameId first_keyframe = kNoId;

  Eigen::Vector4d coefficients() const { return {normal.x(), normal.y(), normal.z(), d}; }
  double distance(const Eigen::Vector3d& p_w) const { return normal.dot(p_w) + d; }
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
  std::size_t num_lines() const { return lines_.size(); }
  std::size_t num_planes() const { return planes_.size(); }
  const MapLine* line(LineId id) const;
  const MapPlane* plane(PlaneId id) const;
  /// The point that stands for `id` now: `id` itself while it exists, else the point it was
  /// fused into (replace_point), followed to the end; kNoId when that point is gone too. A
  /// keyframe request made before a fusion keeps its association this way.
  PointId resolve_point(PointId id) const;
  LineId resolve_line(LineId id) const;
  /// The number of corrections applied (map/correction.hpp).
  std::uint64_t corrections() const { return corrections_; }
  const std::unordered_map<LineId, MapLine>& lines() const { return lines_; }
  const std::unordered_map<PlaneId, MapPlane>& planes() const { return planes_; }
  /// Up to `n` covisible keyframes of `id`, by decreasing weight (ties: increasing id).
  std::vector<KeyFrameId> best_covisible(KeyFrameId id, std::size_t n, int min_weight = 1) const;
  /// The pose of a keyframe, following the chain of culled keyframes to a surviving one.
  std::optional<SE3> keyframe_pose_T_c_w(KeyFrameId id) const;
  KeyFrameId last_keyframe_id() const { return last_keyframe_; }
  std::uint64_t version() const { return version_; }
  /// The keyframe database (inverted index of the keyframes' bags of words); null until
  /// enable_database(). Keyframes with a bag of words are in it while they are in the map.
  const place::Database* database() const { return database_ ? &*database_ : nullptr; }

  // --- writes (local mapper only) ---
  /// Starts the keyframe database for a vocabulary of `words` words (keyframes already in the
  /// map with a bag of words are added).
  void enable_database(int words);
  /// Sets a keyframe's bag of words (and its database entry).
  void set_keyframe_bow(KeyFrameId id, std::shared_ptr<const place::BowImage> bow);
  /// Records a loop closed between two keyframes (an edge of the essential graph).
  void add_loop_edge(KeyFrameId a, KeyFrameId b);
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
  void set_point_color(PointId id, const std::array<std::uint8_t, 3>& rgb);
  /// Recomputes descriptor, normal and distance range of a point from its observations.
  void update_point_appearance(PointId id);
  /// Normal and distance range only: what changes when the point or its keyframes move (the
  /// descriptor depends on the observations alone).
  void update_point_geometry(PointId id);
  /// Recomputes the covisibility weights of `id` (and the reverse edges).
  void update_covisibility(KeyFrameId id);
  void add_tracking_statistics(PointId id, int visible, int found);

  // Lines (same conventions as points).
  LineId add_line(const Eigen::Vector3d& start_w, const Eigen::Vector3d& end_w, KeyFrameId keyframe,
                  int segment_index);
  void add_line_observation(LineId line, KeyFrameId keyframe, int segment_index);
  void erase_line_observation(LineId line, KeyFrameId keyframe);
  void erase_line(LineId line);
  void replace_line(LineId old_line, LineId new_line);
  void set_line_endpoints(LineId id, const Eigen::Vector3d& start_w, const Eigen::Vector3d& end_w);
  /// Grows the segment so that it covers the projection of [start_w, end_w] onto its line.
  void extend_line(LineId id, const Eigen::Vector3d& start_w, const Eigen::Vector3d& end_w);
  /// Recomputes the representative descriptor from the observations.
  void update_line_appearance(LineId id);
  void add_line_statistics(LineId id, int visible, int found);

  // Planes.
  PlaneId add_plane(const Eigen::Vector4d& plane_w, const std::vector<Eigen::Vector3d>& hull_w,
                    KeyFrameId keyframe, int plane_index);
  void add_plane_observation(PlaneId plane, KeyFrameId keyframe, int plane_index);
  void erase_plane_observation(PlaneId plane, KeyFrameId keyframe);
  void set_plane(PlaneId id, const Eigen::Vector4d& plane_w);
  /// Replaces the plane's extent (a map correction moved it).
  void set_plane_hull(PlaneId id, std::vector<Eigen::Vector3d> hull_w);
  /// Adds observed points (world) of the plane to its extent: the hull of the old hull and them,
  /// both projected onto the plane.
  void extend_plane(PlaneId id, const std::vector<Eigen::Vector3d>& points_w);
  /// Moves every observation and the extent of `old_plane` to `new_plane`, then erases it.
  void replace_plane(PlaneId old_plane, PlaneId new_plane);
  void bump_version() { ++version_; }
  void count_correction() { ++corrections_; }

  // --- sessions (map/session.hpp): what saving reads beyond the reads above, and restoring a
  // saved map exactly (ids, links and counters as they were) ---
  struct Counters {
    KeyFrameId next_keyframe = 0;
    PointId next_point = 0;
    LineId next_line = 0;
    PlaneId next_plane = 0;
    KeyFrameId last_keyframe = kNoId;
    std::uint64_t version = 0;
  };
  Counters counters() const {
    return {next_keyframe_id_, next_point_id_, next_line_id_,
            next_plane_id_,    last_keyframe_, version_};
  }
  const std::unordered_map<KeyFrameId, ErasedKeyFrame>& erased_keyframes() const {
    return erased_keyframes_;
  }
  /// Insert an element as it is, under its own id (replacing one with that id): landmark slots,
  /// observations and covisibility are kept, nothing is recomputed or checked (load_session
  /// checks the whole map) and neither the counters nor the version change.
  void restore_keyframe(KeyFrame keyframe) {
    const KeyFrameId id = keyframe.id;
    keyframes_.insert_or_assign(id, std::move(keyframe));
  }
  void restore_point(MapPoint point) {
    const PointId id = point.id;
    points_.insert_or_assign(id, std::move(point));
  }
  void restore_line(MapLine line) {
    const LineId id = line.id;
    lines_.insert_or_assign(id, std::move(line));
  }
  void restore_plane(MapPlane plane) {
    const PlaneId id = plane.id;
    planes_.insert_or_assign(id, std::move(plane));
  }
  void restore_erased_keyframe(KeyFrameId id, const ErasedKeyFrame& erased) {
    erased_keyframes_.insert_or_assign(id, erased);
  }
  void restore_counters(const Counters& counters) {
    next_keyframe_id_ = counters.next_keyframe;
    next_point_id_ = counters.next_point;
    next_line_id_ = counters.next_line;
    next_plane_id_ = counters.next_plane;
    last_keyframe_ = counters.last_keyframe;
    version_ = counters.version;
  }

 private:
  mutable std::shared_mutex mutex_;
  std::unordered_map<KeyFrameId, KeyFrame> keyframes_;
  std::unordered_map<PointId, MapPoint> points_;
  std::unordered_map<LineId, MapLine> lines_;
  std::unordered_map<PlaneId, MapPlane> planes_;
  std::unordered_map<KeyFrameId, ErasedKeyFrame> erased_keyframes_;
  std::optional<place::Database> database_;
  KeyFrameId next_keyframe_id_ = 0;
  PointId next_point_id_ = 0;
  LineId next_line_id_ = 0;
  PlaneId next_plane_id_ = 0;
  KeyFrameId last_keyframe_ = kNoId;
  std::uint64_t version_ = 0;
  std::uint64_t corrections_ = 0;
  // Forward links of fused landmarks (replaced -> replacement), for resolve_point/resolve_line.
  std::unordered_map<PointId, PointId> replaced_points_;
  std::unordered_map<LineId, LineId> replaced_lines_;
};

}  // namespace mcslam::map
