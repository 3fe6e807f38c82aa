#pragma once
// The stages of object handling, each with its inputs and outputs; ObjectHandler (objects.hpp)
// runs them in this order every frame:
//
//  carrying boxes      carry_boxes: boxes detected on an earlier frame brought to the frame
//                      being tracked by the image motion of their own features.
//  features to boxes   frame_plane_extents, grow_flat_movers, assign_features: which box each
//                      feature belongs to (structural planes, background and overlaps resolved).
//  matching            match_to_reference: the boxes' features and a sample of the background
//                      matched to an earlier frame; background_threshold: the frame's epsilon_d.
//  Algorithm 1         judge_boxes (the verdict of each box, retried against the last frame),
//                      withhold_shared_verdicts (a box seen through a moving one), and the class
//                      prior (track_evidence): what a verdict tells the box's track.
//  Algorithm 2         check_box_constraint: a moving object sliding on a plane; and
//                      constraint_measurements: the inputs of residuals (9) and (10).
//  movers without box  motion_seeds, moving_planes, region_nodes, connected_regions,
//                      mover_region: features whose position contradicts the camera's motion,
//                      grown into regions that become boxes of class kMovingRegionClass.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/features/frame_features.hpp"
#include "mcslam/map/map.hpp"
#include "mcslam/optim/constraint_residual.hpp"
#include "mcslam/perception/detection.hpp"
#include "mcslam/slam/dynamics.hpp"

namespace mcslam::slam {

/// Class name of the boxes made around moving regions found without a detection.
inline constexpr const char* kMovingRegionClass = "moving region";
/// Boxes per frame (one bit each in the feature masks).
inline constexpr std::size_t kMaxBoxes = 64;

/// How a box came to the frame being tracked: detected on it, carried forward from the
/// detector's frame by its features' motion, only grown (too few matches), or a moving region.
enum class BoxSource : std::uint8_t { kFresh, kPropagated, kGrown, kMover };

/// A frame kept for carrying boxes and for Algorithm 1: its features and, once tracked, its pose.
struct ObjectFrame {
  std::uint64_t id = 0;
  std::shared_ptr<const features::FrameFeatures> features;
  std::optional<SE3> T_c_w;
};

/// A box of the frame being tracked, with what was learnt about it.
struct ObjectBox {
  perception::Detection detection;
  int track = -1;
  BoxSource source = BoxSource::kFresh;
  int propagated_matches = 0;
  float depth = -1.0f;  ///< median depth of the object's own features (-1: none)
  float depth_near = -1.0f, depth_far = -1.0f;
  /// Moving regions: the object's depth when it was last seen (-1: unknown); its band is the
  /// cluster of depths nearest to it (object_geometry::object_band).
  float last_depth = -1.0f;
  int background_points = 0;
  int unconfirmed = 0;  ///< moving regions: frames without confirmation
  int age = 0;          ///< moving regions: frames since the region was last seen
  bool flat = false;    ///< moving regions: found on a moving frame plane
};

/// A moving region found without a box, carried to later frames.
struct MovingRegion {
  perception::Detection detection;  ///< in frame `frame`
  std::uint64_t frame = 0;
  int unconfirmed = 0;  ///< frames since evidence last confirmed it
  bool flat = false;    ///< found on a frame plane seen to move
  float depth = -1.0f;  ///< the object's median depth when last seen (-1: unknown)
};

/// The boxes each feature of a frame belongs to (bit b: box b).
struct FeatureBoxes {
  std::vector<std::uint64_t> points;
  std::vector<std::uint64_t> lines;
};

/// The label of a feature in the boxes of `mask`: dynamic when any of them is dynamic, else
/// constrained when any is constrained, else static.
FeatureLabel label_for(std::uint64_t mask, const std::vector<ObjectState>& state);

// --- carrying boxes ---

/// Boxes detected on `from` (`age` frames back; nullptr: that frame is no longer kept) to be
/// brought to the frame with features `to` and pose `T_to_w` (when known).
struct BoxCarry {
  const ObjectFrame* from = nullptr;
  const features::FrameFeatures* to = nullptr;
  std::optional<SE3> T_to_w;
  int age = 0;
  BoxSource source = BoxSource::kFresh;
};

/// The boxes moved by the median image motion of their object's features (optical flow or
/// descriptor matches near where the camera's motion puts them) and given a margin; boxes with
/// too few matches move with the camera only and are grown. Fresh boxes become kPropagated or
/// kGrown; kMover boxes keep their source.
std::vector<ObjectBox> carry_boxes(const std::vector<perception::Detection>& detections,
                                   const BoxCarry& carry, const PinholeCamera& camera,
                                   const DynamicsOptions& options);

// --- features to boxes ---

/// Image extent of each frame plane (its hull projected, clipped to the image).
std::vector<cv::Rect2f> frame_plane_extents(const features::FrameFeatures& features,
                                            const PinholeCamera& camera);

/// Grows each moving region found on a moving plane (`flat`) towards the frame planes it holds
/// most of, by at most propagation_radius pixels a frame of its age on each side.
void grow_flat_movers(std::vector<ObjectBox>& boxes, const features::FrameFeatures& features,
                      const std::vector<cv::Rect2f>& plane_extent, const PinholeCamera& camera,
                      const DynamicsOptions& options);

/// The boxes each feature belongs to: those containing it, except a box for a feature on a
/// structural plane (one mostly outside the box) and for a feature behind the object's depth
/// band; of overlapping boxes, the one at the feature's depth. Sets each box's depth band,
/// median depth and count of background points.
FeatureBoxes assign_features(const features::FrameFeatures& features,
                             const std::vector<cv::Rect2f>& plane_extent,
                             std::vector<ObjectBox>& boxes, const DynamicsOptions& options);

// --- matching to the reference frame ---

/// The features of `current` in the boxes of `selected` (bit b: box b; `box_count` boxes) and a
/// sample of the background (box -1), matched by appearance near where they would be in
/// `reference` if they were static (T_cur_ref: the camera's motion). A feature in several boxes
/// gives one match per box.
std::vector<MotionMatch> match_to_reference(const features::FrameFeatures& current,
                                            const features::FrameFeatures& reference,
                                            const SE3& T_cur_ref, const FeatureBoxes& boxes,
                                            std::size_t box_count, std::uint64_t selected,
                                            const PinholeCamera& camera,
                                            const DynamicsOptions& options);

/// epsilon_d of the frame: background_factor times the median distance of the background's
/// matches to the camera's motion, never below epipolar_threshold (20 matches needed).
double background_threshold(const std::vector<MotionMatch>& matches, const SE3& T_cur_ref,
                            const PinholeCamera& camera, const DynamicsOptions& options);

// --- Algorithm 1 ---

/// Algorithm 1 over a frame's boxes: the matches to the reference frame, each box's verdict,
/// and the epsilon_d used.
struct BoxVerdicts {
  std::vector<MotionMatch> matches;
  std::vector<ObjectDecision> decisions;
  double threshold = 0.0;
};

/// Algorithm 1 against `reference` (tracked frames back); the boxes it leaves undecided (too few
/// matches: an object that just came into view) are judged against `last`, the last frame.
BoxVerdicts judge_boxes(const features::FrameFeatures& current, const SE3& T_c_w,
                        const ObjectFrame& reference, const ObjectFrame& last,
                        const FeatureBoxes& boxes, std::size_t box_count,
                        const PinholeCamera& camera, const DynamicsOptions& options);

/// An object seen through a moving one (a cupboard behind a walking person) is not judged by
/// the features it shares with it: a dynamic verdict with most of its matches inside a box in
/// front that is `moving` is withdrawn (no verdict this frame).
void withhold_shared_verdicts(std::vector<ObjectDecision>& decisions,
                              const std::vector<MotionMatch>& matches,
                              const std::vector<ObjectBox>& boxes, const std::vector<bool>& moving);

/// What a box's verdict tells its track, and the frames of static evidence that clear it.
struct TrackEvidence {
  ObjectDecision evidence;
  int frames_to_clear = 0;
};

/// The class prior: for a self-moving class only a "still" verdict under the strict epsilon_d
/// counts, for moving_class_static_frames; a verdict of "still" that holds only under the
/// frame's `threshold` is "moving" when the median distance exceeds it, else no evidence.
/// Other classes: the verdict as it is, cleared after static_frames_to_clear.
TrackEvidence track_evidence(const ObjectDecision& decision, const std::string& class_name,
                             double threshold, const DynamicsOptions& options);

// --- Algorithm 2 ---

/// The frames Algorithm 2 compares: the current frame's planes (camera frame, and world frame
/// as [n, d] with n . p + d = 0) and the poses of the reference and current frames.
struct ConstraintFrame {
  const std::vector<features::PlaneFeature>& planes;
  std::vector<Eigen::Vector4d> planes_w;
  SE3 T_w_ref;
  SE3 T_w_c;
};
ConstraintFrame constraint_frame(const std::vector<features::PlaneFeature>& planes,
                                 const SE3& T_c_w, const SE3& T_ref_w);

/// Algorithm 2 for box `box` (index `b`) against the frame planes that reach beyond it (the
/// floor, not its seat); the decision's plane indexes `frame.planes`.
ConstraintDecision check_box_constraint(std::size_t b, const ObjectBox& box,
                                        const std::vector<MotionMatch>& matches,
                                        const ConstraintFrame& frame, const PinholeCamera& camera,
                                        const DynamicsOptions& options);

/// The inputs of residuals (9) and (10).
struct ConstraintMeasurements {
  std::vector<optim::ConstrainedPointMeasurement> points;
  std::vector<optim::ConstrainedLineMeasurement> lines;
};

/// Residual inputs from the matched features (with depth at both ends) of constrained boxes
/// that are in no dynamic box, tied to their box's plane.
ConstraintMeasurements constraint_measurements(const std::vector<MotionMatch>& matches,
                                               const std::vector<ObjectState>& state,
                                               const FeatureBoxes& boxes,
                                               const std::vector<ConstraintDecision>& constraints,
                                               const ConstraintFrame& frame,
                                               const DynamicsOptions& options);

// --- movers without a box ---

/// A feature of the frame whose position the map predicts: where its landmark (or last-frame
/// point) should be in the camera frame with the estimated pose.
struct MotionEvidence {
  int point = -1;                      ///< index into the frame's points
  Eigen::Vector3d expected_c;          ///< predicted camera-frame position
  map::PointId landmark = map::kNoId;  ///< the map point, when it is one
};

/// Per point of the frame: whether it has evidence (measured), whether it contradicts the
/// camera's motion (seed), and its map point.
struct MotionSeeds {
  std::vector<std::uint8_t> seed;
  std::vector<std::uint8_t> measured;
  std::vector<map::PointId> landmark;
  int count = 0;  ///< seeds
};

/// Seeds among the points with depth that are not `excluded`: their predicted position is
/// farther than mover_displacement + mover_relative * depth from where the depth camera sees
/// them, and more than mover_pixels from the keypoint in the image.
MotionSeeds motion_seeds(const features::FrameFeatures& features,
                         const std::vector<MotionEvidence>& evidence,
                         const std::vector<std::uint8_t>& excluded, const PinholeCamera& camera,
                         const DynamicsOptions& options);

/// Frame planes seen to move: their points with evidence pass a region's test (at least
/// mover_min_seeds seeds, and at least mover_seed_share of them seeds).
std::vector<std::uint8_t> moving_planes(const features::FrameFeatures& features,
                                        const MotionSeeds& seeds, const DynamicsOptions& options);

/// The points a region may hold (points with depth not `excluded`: seeds, points on no plane
/// and points on a moving plane), and how many points with depth are not excluded.
struct RegionNodes {
  std::vector<std::size_t> nodes;
  int with_depth = 0;
};
RegionNodes region_nodes(const features::FrameFeatures& features, const MotionSeeds& seeds,
                         const std::vector<std::uint8_t>& excluded,
                         const std::vector<std::uint8_t>& moving_plane);

/// The nodes linked to each seed (closer than mover_link_radius pixels and mover_link_depth
/// metres, transitively), one list per region, in the order the regions are found.
std::vector<std::vector<std::size_t>> connected_regions(const features::FrameFeatures& features,
                                                        const RegionNodes& nodes,
                                                        const MotionSeeds& seeds,
                                                        const DynamicsOptions& options);

/// A region's box of class kMovingRegionClass (score: its share of seeds) when it is a mover:
/// enough seeds, a large enough share of its points with evidence, and not most of the view (a
/// bad pose, not a mover); nullopt otherwise.
std::optional<perception::Detection> mover_region(const features::FrameFeatures& features,
                                                  const std::vector<std::size_t>& members,
                                                  const MotionSeeds& seeds, int with_depth,
                                                  const DynamicsOptions& options);

/// The moving regions carried on from the frame `frame_id`: the boxes of source kMover whose
/// track is not static, confirmed when Algorithm 1 found them dynamic, dropped after `life`
/// frames unconfirmed.
std::vector<MovingRegion> surviving_movers(const std::vector<ObjectBox>& boxes,
                                           const std::vector<ObjectState>& state,
                                           const std::vector<ObjectDecision>& decisions,
                                           std::uint64_t frame_id, int life);

}  // namespace mcslam::slam
