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

namespace mcslam::slam {

/// Class name of the boxes that find_movers() makes around moving regions without a detection.
inline constexpr const char* kMovingRegionClass = "moving region";

/// One detected object of a frame, with the decisions of Algorithms 1 and 2.
struct ObjectReport {
  perception::Detection detection;  ///< undistorted pixels, in the frame being tracked
  int track_id = -1;                ///< stable across frames
  ObjectState state = ObjectState::kStatic;
  ObjectDecision decision;
  ConstraintDecision constraint;
  /// How the box came to this frame: detected on it, carried forward from the detector's frame
  /// by its features' motion (`propagated_matches` of them), or only grown (too few matches).
  enum class Source : std::uint8_t { kFresh, kPropagated, kGrown, kMover } source = Source::kFresh;
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

/// A feature of the frame whose position the map predicts: where its landmark (or last-frame
/// point) should be in the camera frame with the estimated pose.
struct MotionEvidence {
  int point = -1;                      ///< index into the frame's points
  Eigen::Vector3d expected_c;          ///< predicted camera-frame position
  map::PointId landmark = map::kNoId;  ///< the map point, when it is one
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
  struct PastFrame {
    std::uint64_t id = 0;
    std::shared_ptr<const features::FrameFeatures> features;
    std::optional<SE3> T_c_w;  ///< when tracked
  };
  /// A box of the frame with what was learnt about it.
  struct Box {
    perception::Detection detection;
    int track = -1;
    ObjectReport::Source source = ObjectReport::Source::kFresh;
    int propagated_matches = 0;
    float depth = -1.0f;  ///< median depth of the object's own features (-1: none)
    float depth_near = -1.0f, depth_far = -1.0f;
    int background_points = 0;
    int unconfirmed = 0;  ///< moving regions: frames without confirmation
    int age = 0;          ///< moving regions: frames since the region was last seen
    bool flat = false;    ///< moving regions: found on a moving frame plane
  };

  /// A moving region found without a box, carried to later frames.
  struct Mover {
    perception::Detection detection;  ///< in frame `frame`
    std::uint64_t frame = 0;
    int unconfirmed = 0;  ///< frames since evidence last confirmed it
    bool flat = false;    ///< found on a frame plane seen to move (grow_movers)
  };

  /// Brings boxes detected on frame `from` (`age` frames back) to the frame with features `to`
  /// and pose `T_to_w` (when known). Boxes carried by their features' motion get source
  /// kPropagated, the others kGrown (unless `source` is kMover).
  std::vector<Box> propagate(const std::vector<perception::Detection>& boxes, const PastFrame* from,
                             const features::FrameFeatures& to, const std::optional<SE3>& T_to_w,
                             int age, ObjectReport::Source source) const;
  /// Grows each moving region's box towards the frame planes it holds most of.
  void grow_movers(const features::FrameFeatures& features,
                   const std::vector<cv::Rect2f>& plane_extent);
  /// Assigns features to boxes (structural planes, background and overlaps resolved).
  void assign_features(const Frame& frame);
  void update_exclusions();
  /// Matches the features of the boxes in `boxes` (bit b: box b) and a sample of the
  /// background to an earlier frame by appearance.
  std::vector<MotionMatch> match_to_reference(const Frame& frame, const PastFrame& ref,
                                              const SE3& T_cur_ref,
                                              std::uint64_t boxes = ~std::uint64_t{0}) const;
  std::vector<std::uint8_t> moving_planes(const features::FrameFeatures& features,
                                          const std::vector<std::uint8_t>& seed,
                                          const std::vector<std::uint8_t>& measured) const;
  double adaptive_threshold(const std::vector<MotionMatch>& matches, const SE3& T_cur_ref) const;
  const PastFrame* recent(std::uint64_t id) const;
  std::vector<ObjectState> box_states() const;

  PinholeCamera camera_;
  DynamicsOptions options_;
  ObjectTracks tracks_;
  // The current frame.
  std::vector<Box> boxes_;
  bool fresh_ = true;
  int age_ = 0;
  std::vector<std::uint64_t> point_boxes_;  // bit b: box b
  std::vector<std::uint64_t> line_boxes_;
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
  std::vector<Mover> movers_;
  std::vector<Mover> candidates_;
  // Recent frames (any state) for propagation, newest first; tracked frames for Algorithm 1.
  std::deque<PastFrame> recent_;
  std::deque<PastFrame> history_;
};

}  // namespace mcslam::slam
