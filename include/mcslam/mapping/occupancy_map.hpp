#pragma once
// The dense map beside the sparse one: an OctoMap occupancy octree integrated from keyframe
// depth, with the pixels of people and other movers left out (they only free the space in front
// of them), and the 2D occupancy grid of the floor for planners.
//
// Each keyframe's depth is sampled (OccupancyOptions::pixel_step) and kept, so that a correction
// of the keyframe poses (a loop, a full bundle adjustment) rebuilds the map from its own data
// instead of leaving the walls where the old poses put them: no wall is ever doubled.
//
// Not thread-safe: one thread writes it (MappingWorker runs it on a thread of its own).

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/core/timing.hpp"
#include "mcslam/mapping/options.hpp"

namespace octomap {
class OcTree;
}

namespace mcslam::mapping {

/// The same numbers as map::KeyFrameId.
using KeyframeId = std::uint64_t;

/// An object of a keyframe by its id (an object track's, the same in every keyframe): its box
/// (undistorted pixels) and the depth band of its pixels (metres; depth_far <= 0: the whole box).
struct ObjectRegion {
  int id = -1;
  cv::Rect2f box;
  float depth_near = -1.0f;
  float depth_far = -1.0f;
};

/// What the mapping stage receives per keyframe.
struct KeyframeDepth {
  KeyframeId id = 0;
  SE3 T_w_c;
  /// The camera of the (undistorted) images.
  PinholeCamera camera;
  /// CV_32FC1, metres, undistorted, camera.width x camera.height; 0 or NaN: no measurement.
  cv::Mat depth;
  /// CV_8UC1 of the same size, nonzero on the pixels of people and of the other objects that
  /// move by themselves (movers without a box); empty: none. They are never obstacles: their
  /// rays only free the space in front of them.
  cv::Mat dynamic_mask;
  /// CV_8UC1 of the same size, nonzero on the pixels of objects that move but are obstacles
  /// where they are (a chair pushed across the floor: the object stage's constrained movers);
  /// empty: none. Their voxels are occupied at once (at least just above the threshold) and
  /// freed at once (at least just below it) when a later keyframe sees through them, instead of
  /// after the 9 keyframes a static voxel at clamp_max needs. A dynamic pixel is dynamic even
  /// when it is in this mask too.
  cv::Mat mover_mask;
  /// CV_8UC3 (BGR) of the same size, for the voxels' colours; empty: none.
  cv::Mat colour;
  /// Objects this keyframe saw standing still (a detector's static boxes), and the ids of its
  /// moving objects (those of dynamic_mask and mover_mask). When an object seen still before
  /// moves, the samples where earlier keyframes saw it become a mover's: its first place is
  /// forgotten as soon as a keyframe sees through it (a chair pushed away from where it stood),
  /// instead of after the 9 keyframes a static voxel at clamp_max needs. Not kept in sessions.
  std::vector<ObjectRegion> still_objects;
  std::vector<int> moving_objects;
};

/// A keyframe as the map keeps it: its depth sampled in blocks of step x step pixels. Sample
/// (i, j) is the block whose first pixel is (i * step, j * step), located at its centre
/// (i * step + (step - 1) / 2.0, j * step + (step - 1) / 2.0): the median of the block's valid
/// depths; dynamic when any pixel of the block is, else a mover's when any pixel is
/// (OccupancyOptions::pixel_step).
struct KeyframeSamples {
  KeyframeId id = 0;
  SE3 T_w_c;
  PinholeCamera camera;  ///< of the full image
  int step = 1;
  cv::Mat depth_mm;  ///< CV_16UC1, millimetres (below the noise from 0.5 m on); 0: none
  static constexpr std::uint8_t kStatic = 0;
  static constexpr std::uint8_t kDynamic = 1;  ///< frees its ray only (grown mask)
  static constexpr std::uint8_t kMover = 2;    ///< an obstacle that is forgotten when seen through
  cv::Mat kind;                                ///< CV_8UC1: kStatic, kDynamic or kMover per sample
  cv::Mat colour;                              ///< CV_8UC3 BGR, or empty

  /// The full-image pixel of sample (i, j).
  Eigen::Vector2d pixel(int i, int j) const {
    const double offset = 0.5 * (step - 1);
    return {i * step + offset, j * step + offset};
  }
  /// The ray through sample (i, j) at unit depth, in the camera frame: p_c = z * ray(i, j).
  Eigen::Vector3d ray(int i, int j) const {
    const Eigen::Vector2d uv = pixel(i, j);
    return {(uv.x() - camera.cx) / camera.fx, (uv.y() - camera.cy) / camera.fy, 1.0};
  }
  /// Bytes of the images (what a keyframe costs the map, beside its headers).
  std::size_t bytes() const;
  /// An empty optional when the samples fit their camera (a valid camera, a step in [1, 64],
  /// CV_16UC1 depth and CV_8UC1 kinds, and CV_8UC3 colour or none, of the camera's size over the
  /// step); otherwise what is wrong. OccupancyMap::insert and map::save_session check it.
  std::optional<std::string> check() const;
};

/// The floor in the world frame: normal . p + d = 0, |normal| = 1, the normal pointing up into
/// the room (as the sparse map's planes give it, oriented towards the cameras).
struct FloorPlane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double d = 0.0;
  double height(const Eigen::Vector3d& p_w) const { return normal.dot(p_w) + d; }
};

/// A 2D occupancy grid over the floor, in the nav_msgs/OccupancyGrid convention.
///
/// Frames: the floor frame has its origin at the world origin's foot on the floor, z along the
/// floor's normal, x along the world axis closest to the floor (projected onto it), y = z x x.
/// It does not move as the grid grows, so it is the `map` frame of a planner. The grid frame is
/// the floor frame moved to the grid's lower-left corner: cell (col, row) covers
/// [col, col + 1) x [row, row + 1) times `resolution` in the grid frame.
struct OccupancyGrid {
  static constexpr std::int8_t kUnknown = -1;
  static constexpr std::int8_t kFree = 0;
  static constexpr std::int8_t kOccupied = 100;

  int width = 0;
  int height = 0;
  double resolution = 0.05;
  /// p_world = T_world_grid * p_grid; origin at the lower-left corner of cell (0, 0).
  Eigen::Matrix4d T_world_grid = Eigen::Matrix4d::Identity();
  /// p_world = T_world_floor * p_floor (the fixed `map` frame described above).
  Eigen::Matrix4d T_world_floor = Eigen::Matrix4d::Identity();
  /// The lower-left corner of cell (0, 0) in the floor frame (map_server's `origin`, yaw 0).
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();
  /// The floor used, and whether it was estimated (no floor given: OccupancyMap::grid()).
  FloorPlane floor;
  bool floor_estimated = false;
  /// Row-major, row 0 the lowest y (nav_msgs): cells[row * width + col].
  std::vector<std::int8_t> cells;

  std::int8_t at(int col, int row) const {
    return cells[static_cast<std::size_t>(row) * width + col];
  }
  /// The cell under a world point (projected along the floor's normal), if inside the grid.
  std::optional<std::array<int, 2>> cell_of(const Eigen::Vector3d& p_world) const;
  std::size_t count(std::int8_t value) const;
};

enum class VoxelState { kUnknown, kFree, kOccupied };

struct OccupiedVoxel {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double size = 0.05;  ///< edge (metres): larger than the resolution for a pruned node
  std::array<std::uint8_t, 3> rgb{200, 200, 200};
  bool has_colour = false;
};

struct OccupancyStats {
  std::size_t keyframes = 0;
  /// Voxels of `resolution` size (a pruned node counts for all the voxels it covers).
  std::size_t occupied_voxels = 0;
  std::size_t free_voxels = 0;
  std::size_t leaf_nodes = 0;
  /// Time of insert() per keyframe (sampling and integration; with integration "at_end",
  /// sampling and storing: the integration is the rebuild), milliseconds.
  SampleStats integration_ms;
  /// "live" or "at_end" (OccupancyOptions::integration).
  std::string integration = "live";
  std::size_t rebuilds = 0;
  double last_rebuild_ms = 0.0;
  /// Memory: the octree (OcTree::memoryUsage()), the stored keyframe samples, the colour sums.
  std::size_t octree_bytes = 0;
  std::size_t keyframe_bytes = 0;
  std::size_t colour_bytes = 0;
  std::size_t total_bytes() const { return octree_bytes + keyframe_bytes + colour_bytes; }
  double keyframe_bytes_each() const {
    return keyframes == 0 ? 0.0 : static_cast<double>(keyframe_bytes) / keyframes;
  }
};

class OccupancyMap {
 public:
  /// Throws InputError (naming the setting) when options.check() fails.
  explicit OccupancyMap(const OccupancyOptions& options = {});
  ~OccupancyMap();
  OccupancyMap(OccupancyMap&&) noexcept;
  OccupancyMap& operator=(OccupancyMap&&) noexcept;
  /// A copy of the map (the octree copied, the stored samples shared: they are never written),
  /// for a rebuild off a lock while readers keep the original.
  OccupancyMap clone() const;

  /// Samples the keyframe's depth, keeps the samples and integrates them: every measurement's
  /// ray frees the voxels it crosses up to free_margin_sigmas * sigma_z before the point; a
  /// static measurement within max_range marks the voxels within +-sigma_z of its point
  /// occupied; a dynamic one marks nothing; a mover's marks its voxels as a static one does,
  /// but they become occupied at once and free at once when a later ray crosses them; one
  /// beyond max_range frees its ray up to max_range.
  /// Within a keyframe a voxel hit by one measurement is not freed by another. A keyframe id
  /// given again replaces the stored one and rebuilds. Throws InputError on images that do not
  /// match the camera.
  void insert(const KeyframeDepth& keyframe);
  /// Integrates keyframe samples (as kept by keyframes(), e.g. read from a saved session).
  void insert(KeyframeSamples samples);
  /// Samples and integrates a view as insert() does, without keeping it: a later rebuild
  /// (correct(), rebuild(), a keyframe given again) forgets it. For localisation, where the
  /// poses never change and the memory must stay bounded. The id is not used.
  void integrate_transient(const KeyframeDepth& view);
  /// Sets the listed keyframes' poses (T_w_c; ids not stored are ignored). Stored keyframes not
  /// listed (unless listed_only) move with the closest earlier listed keyframe (by id), keeping
  /// their pose relative to it, and stay when no listed keyframe is earlier: so a keyframe the
  /// sparse map culled still follows a loop correction that gives the poses of all the sparse
  /// map's keyframes. (map::apply_correction moves keyframes older than every corrected one with
  /// the first corrected one; here they stay, so that listing the keyframes that moved is
  /// enough.) When
  /// a keyframe moved by more than rebuild_tolerance of a voxel (a rotation counted at
  /// max_range), clears the octree and integrates every stored keyframe again, in the order
  /// inserted, with its pose now. Returns whether it rebuilt.
  bool correct(const std::unordered_map<KeyframeId, SE3>& T_w_c, bool listed_only = false);
  /// Clears the octree and integrates every stored keyframe again.
  void rebuild();
  /// With OccupancyOptions::integration "at_end", insert() and correct() only store keyframes
  /// and poses: whether some are not in the octree yet (until integrate_pending()).
  bool pending() const;
  /// Integrates the stored keyframes when pending() (a rebuild); returns whether it did.
  bool integrate_pending();
  /// Updates the octree's inner nodes and merges the children that agree into their parent.
  /// Integrating (insert(), correct(), ...) does so only when the tree has doubled since the
  /// last time (it walks the whole tree): the voxels' states are the same either way, but call
  /// it before reading the inner nodes of octree() or writing it (MappingWorker::wait() does).
  void settle();

  VoxelState state(const Eigen::Vector3d& p_world) const;
  /// The occupied leaves, sorted by position (deterministic).
  std::vector<OccupiedVoxel> occupied_voxels() const;
  /// The 2D grid over `floor`; with no floor, over estimate_floor().
  OccupancyGrid grid(const std::optional<FloorPlane>& floor = std::nullopt) const;
  /// A floor when none is known: perpendicular to the first keyframe's image "down" (+y of its
  /// camera), at the lowest height holding a large share of the occupied voxels (see grid.cpp).
  /// Without a keyframe: z = 0 with +z up.
  FloorPlane estimate_floor() const;

  OccupancyStats stats() const;
  const OccupancyOptions& options() const;
  const std::vector<KeyframeSamples>& keyframes() const;
  const octomap::OcTree& octree() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Samples a keyframe as OccupancyMap::insert does (exposed for sessions and tests).
KeyframeSamples sample_keyframe(const KeyframeDepth& keyframe, const OccupancyOptions& options);

}  // namespace mcslam::mapping
