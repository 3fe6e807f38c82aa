#pragma once
// Object handling for tracking: which features of a frame belong to objects that move, so that
// tracking and the map leave them out (or, for a constrained moving object, use them through
// residuals (9) and (10)). The tracker asks; this unit decides. Per frame, in order:
//
//  1. prepare(): the frame's boxes are brought to the frame. A detector on its own thread often
//     delivers an earlier frame's boxes; each box is carried forward by the image motion of its
//     own features (matched from the frame the detector saw to this one), so that the box fits
//     the frame being tracked. Features are assigned to boxes, except those on a structural
//     plane (floor, wall) and those well behind the object's depth (the background seen inside
//     the box). Features of objects known to move are left out of the first pose estimate:
//     objects of self-moving classes (people) always, others after Algorithm 1 found them moving.
//  2. classify(): Algorithms 1 and 2 against the camera motion of the first pose estimate; the
//     class prior keeps a self-moving object dynamic until it has been seen still for a sustained
//     time (a person sitting down), measured with the strict epsilon_d.
//  3. find_movers(): motion without a box. Features whose 3D position contradicts the camera pose
//     estimated from the static map (their map point or last-frame point, moved by the pose, lands
//     far from where the depth camera sees them) are seeds; seeds connected through neighbouring
//     features of similar depth form a region, and a region with enough seeds, found again at
//     the same place in the next frame, is a moving object the detector missed. All its features
//     are left out, the map points seen to move are reported for culling, and the region becomes a
//     box of class "moving region" that the next frames carry forward and judge by Algorithm 1 like
//     any other box. Points on a frame plane link only when the plane is seen to move, and the
//     carried box of a region found on a moving plane grows over the planes it holds most of (a
//     rigid surface moves whole).
//  4. remember(): the tracked frame joins the history Algorithm 1 compares with.
//
// Each step is a short sequence of the stages declared in object_stages.hpp: prepare() runs
// carry_boxes, grow_flat_movers and assign_features; classify() judge_boxes,
// withhold_shared_verdicts, track_evidence, check_box_constraint and constraint_measurements;
// find_movers() motion_seeds, moving_planes, region_nodes, connected_regions and mover_region.

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/features/frame_features.hpp"
#include "mcslam/map/map.hpp"
#include "mcslam/optim/constraint_residual.hpp"
#include "mcslam/perception/detection.hpp"
#include "mcslam/slam/dynamics.hpp"
#include "mcslam/slam/frame.hpp"
#include "mcslam/slam/object_stages.hpp"

namespace mcslam::slam {

/// One detected object of a frame, with the decisions of Algorithms 1 and 2.
struct ObjectReport {
  perception::Detection detection;  ///< undistorted pixels, in the frame being tracked
  int track_id = -1;                ///< stable across frames
  ObjectState state = ObjectState::kStatic;
  ObjectDecision decision;
  ConstraintDecision constraint;
  /// How the box came to this frame: detected on it, carried forward from the detector's frame
  /// by its features' motion (`propagated_matches` of them), or only grown (too few matches).
  using Source = BoxSource;
  Source source = Source::kFresh;
  int propagated_matches = 0;
  /// Depth band (metres) of the object's own features; features beyond it are background.
  float depth_near = -1.0f;
  float depth_far = -1.0f;
  int background_points = 0;  ///< features inside the box kept as static background
  /// Moving objects (dynamic and constrained) in a tracked frame: where the object is in the
  /// world frame (an axis-aligned box over its depth pixels, 5th to 95th percentile on each
  /// axis) and its velocity (m/s: the slope of its box centre over its track's last half second,
  /// once that holds 3 frames over 0.1 s). Set by System.
  std::optional<std::pair<Eigen::Vector3d, Eigen::Vector3d>> world_box;  ///< min, max corner
  std::optional<Eigen::Vector3d> velocity;
};

const char* to_string(ObjectReport::Source source);

/// What the outputs need of the object handling of one frame.
struct ObjectOutputs {
  std::vector<ObjectReport> objects;
  bool fresh = true;       ///< the boxes were the frame's own
  int age = 0;             ///< frames between the detector's image and this one
  double threshold = 0.0;  ///< epsilon_d used (pixels; 0 when Algorithm 1 did not run)
  std::vector<FeatureLabel> point_labels;
  std::vector<FeatureLabel> line_labels;
  int constrained_point_residuals = 0;
  int constrained_line_residuals = 0;
  /// When a new detection arrived: mean IoU, over its boxes matched by class, of the previous
  /// detection's boxes carried forward to its frame (propagation) and of the same boxes only
  /// grown as before propagation existed (stale); -1 when not measured in this frame.
  double propagation_iou = -1.0;
  double stale_iou = -1.0;
  int mover_regions = 0;  ///< regions found by find_movers() in this frame
  int mover_points = 0;   ///< features they took out
};

/// What find_movers() found.
struct MoverResult {
  bool any = false;  ///< features were newly left out: the pose should be re-estimated
  std::vector<map::PointId> moved_landmarks;  ///< map points seen to move (to be culled)
};

class ObjectHandler {
 public:
  ObjectHandler(const PinholeCamera& camera, const DynamicsOptions& options);

  /// Step 1. `predicted_T_c_w`: the motion model's pose of the frame (for the static prediction
  /// of feature positions), when tracking has one.
  void prepare(const Frame& frame, const std::optional<SE3>& predicted_T_c_w);
  /// The first estimate failed with objects left out: let every feature in.
  void include_all();
  /// Step 2. `T_c_w`: the first pose estimate.
  void classify(const Frame& frame, const SE3& T_c_w);
  /// Step 3, after the final pose estimate. `evidence` lists the frame's matched features that
  /// were not left out.
  MoverResult find_movers(const Frame& frame, const SE3& T_c_w,
                          const std::vector<MotionEvidence>& evidence);
  /// Step 4: the frame was tracked at T_c_w.
  void remember(const Frame& frame, const SE3& T_c_w);
  /// Tracking was lost: motion history no longer applies.
  void forget();
  /// The map's world moved (bundle adjustment, a loop or full-BA correction): `W` maps positions
  /// of the world the past frames were tracked in to the new one; their poses follow.
  void move_world(const SE3& W);

  bool any() const { return !boxes_.empty(); }
  bool point_excluded(std::size_t i) const {
    return i < point_excluded_.size() && point_excluded_[i];
  }
  bool line_excluded(std::size_t i) const { return i < line_excluded_.size() && line_excluded_[i]; }
  const std::vector<std::uint8_t>& point_exclusions() const { return point_excluded_; }
  const std::vector<std::uint8_t>& line_exclusions() const { return line_excluded_; }
  const std::vector<optim::ConstrainedPointMeasurement>& constrained_points() const {
    return constrained_points_;
  }
  const std::vector<optim::ConstrainedLineMeasurement>& constrained_lines() const {
    return constrained_lines_;
  }
  /// Points of the frame with depth that are not left out.
  int static_points_with_depth(const Frame& frame) const;
  ObjectOutputs outputs(const Frame& frame) const;

 private:
  void start_frame(const Frame& frame);
  /// When a new detection arrived: how well the previous one, carried to its frame, and the same
  /// boxes only grown overlap it (propagation_iou_, stale_iou_).
  void measure_propagation(const std::vector<perception::Detection>& detections,
                           std::uint64_t source, const ObjectFrame* from, std::uint64_t frame_id,
                           const std::optional<SE3>& predicted_T_c_w);
  /// Each box's track (same class, overlapping box in the last frame), or a new one.
  void associate_tracks();
  /// The moving regions of earlier frames carried to the frame, appended to `boxes`.
  void carry_movers(std::vector<ObjectBox>& boxes, const Frame& frame,
                    const std::optional<SE3>& T_c_w) const;
  /// Algorithm 1 with the class prior: each box's verdict into its track.
  void update_tracks(const std::vector<MotionMatch>& matches);
  /// Algorithm 2 for the boxes of moving tracks.
  void check_constraints(const ConstraintFrame& planes, const std::vector<MotionMatch>& matches);
  /// Whether a region found in this frame was found at the same place in one of the last two
  /// frames (`previous`, carried here by their features' motion).
  bool seen_before(const cv::Rect2f& region, const std::vector<MovingRegion>& previous,
                   const Frame& frame, const SE3& T_c_w) const;
  /// Leaves a confirmed region's features out (its points, and the segments within its extent
  /// and depth); returns whether it lies on a moving plane. Seeds' map points join `moved`.
  bool take_region(const features::FrameFeatures& features, const std::vector<std::size_t>& members,
                   const cv::Rect2f& region, const MotionSeeds& seeds,
                   const std::vector<std::uint8_t>& moving_plane, std::vector<map::PointId>& moved);
  void update_exclusions();
  const ObjectFrame* recent(std::uint64_t id) const;
  std::vector<ObjectState> box_states() const;

  PinholeCamera camera_;
  DynamicsOptions options_;
  ObjectTracks tracks_;
  // The current frame.
  std::vector<ObjectBox> boxes_;
  bool fresh_ = true;
  int age_ = 0;
  FeatureBoxes feature_boxes_;
  std::vector<std::uint8_t> point_excluded_;
  std::vector<std::uint8_t> line_excluded_;
  std::vector<std::uint8_t> point_mover_;  // left out by find_movers
  std::vector<std::uint8_t> line_mover_;
  std::vector<optim::ConstrainedPointMeasurement> constrained_points_;
  std::vector<optim::ConstrainedLineMeasurement> constrained_lines_;
  std::vector<ObjectDecision> decisions_;
  std::vector<ConstraintDecision> constraints_;
  double threshold_ = 0.0;
  double propagation_iou_ = -1.0, stale_iou_ = -1.0;
  int mover_regions_ = 0, mover_points_ = 0;
  // Detections as they came (the detector's frame and boxes) of the previous frame, to measure
  // propagation when a new detection arrives.
  std::optional<std::uint64_t> last_detection_frame_;
  std::vector<perception::Detection> last_detection_;
  // Moving regions found without a box, carried to the next frame as boxes; and regions seen
  // in one frame only, which a region of the next frame at the same place confirms.
  std::vector<MovingRegion> movers_;
  std::vector<MovingRegion> candidates_;
  // Recent frames (any state) for propagation, newest first; tracked frames for Algorithm 1.
  std::deque<ObjectFrame> recent_;
  std::deque<ObjectFrame> history_;
};

}  // namespace mcslam::slam
