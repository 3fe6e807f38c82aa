#pragma once
// Dynamic objects (the paper's Algorithm 1) and moving constraints (Algorithm 2).
//
// Algorithm 1, as mcslam runs it. For each detected box, the features inside it (ORB points, and
// line segments as their two endpoints) are matched by appearance to an earlier frame (the last
// one by default), within a window around where they would be if they were static. Features
// that lie on a structural plane (floor, wall: a frame plane that extends well beyond the box)
// are not the object's and are left out. Then per box:
//  1. With at least `min_matches` (8) matches, a fundamental matrix of the box is estimated by
//     RANSAC from its point pairs, as in the paper; its outliers are mismatches or parts that do
//     not move with the rest, and they are not counted either way.
//  2. Each remaining feature gets its distance to the camera's own motion (the pose estimated
//     from the features outside the boxes): the epipolar distance (4)-(5) in pixels for a
//     feature without depth, and for a feature with depth the full transfer distance, of which
//     the epipolar distance is the component across the epipolar line (a point that slides
//     along its epipolar line is invisible to (5) but not to the transfer distance). Line
//     endpoints are measured to the current segment's infinite line, since LSD endpoints slide
//     along it. A feature is an outlier when its distance exceeds epsilon_d pixels (times its
//     pyramid level's scale).
//  3. The box is dynamic when outliers / counted features > epsilon_r (0.7).
// Boxes with fewer than `min_matches` (but at least `min_reference_matches`) matches are checked
// against the same camera motion: dynamic when their median distance exceeds epsilon_d and the
// image displacements of their points agree in direction (without RANSAC, mismatches would
// otherwise decide; they scatter, a moving object's points move alike). This is
// the paper's "F of the static object with the most features": the background outside all
// boxes is the largest static object, and its F is the camera's relative pose.
//
// Why not the box's own F alone: a rigid object that moves has an epipolar geometry of its own
// that fits all its features, so the outlier ratio of its own F stays near zero; and under the
// rotation-dominated motion of a hand-held camera F is nearly degenerate. The paper's epsilon_d
// of "0.1 metres" is for a distance that (5) measures in pixels; mcslam uses pixels at level 0.
//
// Algorithm 2: a dynamic object of a class that can only slide on a plane (chair, table, ...)
// whose points keep their mean distance to a structural plane (change below epsilon_m^p metres)
// and whose lines keep their mean angle to it (change below epsilon_m^l degrees) between the
// two frames is a constrained moving object, tied to that plane. Of several such planes, the one
// the object rests on (its lowest point closest to the plane) is taken.

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/perception/detection.hpp"

namespace mcslam::slam {

enum class ObjectState : std::uint8_t { kStatic, kDynamic, kConstrained };
const char* to_string(ObjectState state);

/// What a feature of the frame is, for tracking, the map and the outputs.
enum class FeatureLabel : std::uint8_t { kStatic = 0, kDynamic = 1, kConstrained = 2 };

struct DynamicsOptions {
  /// Dynamic-object handling runs when the frame has detections; off: boxes are ignored.
  bool enabled = true;
  /// epsilon_d: a feature is an outlier of the camera's motion beyond this many pixels (level 0).
  double epipolar_threshold = 2.5;
  /// epsilon_d grows to this many times the median distance of background features (outside
  /// every box) when a frame is noisier than that floor (fast rotation, blur, rolling shutter).
  double background_factor = 3.0;
  /// epsilon_r: a box is dynamic when more than this fraction of its features are outliers.
  double outlier_ratio = 0.7;
  /// Boxes with at least this many matches get their own RANSAC fundamental matrix.
  int min_matches = 8;
  /// Boxes with fewer matches than this are not decided (they keep their previous state).
  int min_reference_matches = 5;
  /// RANSAC threshold (pixels) of a box's own fundamental matrix.
  double ransac_threshold = 2.0;
  /// Appearance matching to the earlier frame: window radius (pixels, level 0) around the
  /// static prediction and Hamming threshold of ORB descriptors (LBD: line_descriptor_distance).
  double match_radius = 60.0;
  int descriptor_distance = 50;
  int line_descriptor_distance = 80;
  /// Compare with the frame this many tracked frames back (1: the last frame, as in the paper).
  /// Between consecutive frames at 30 Hz a chair pushed at 0.5 m/s 2.5 m away moves about 1 px,
  /// inside the noise; eight frames (0.27 s) make it 8 px (see README, Dynamic objects). Boxes
  /// with too few matches that far back fall back to the last frame.
  int frame_gap = 8;
  /// A feature inside a box within this distance (metres) of a structural plane is not the
  /// object's (the floor or the wall behind it).
  double plane_distance = 0.03;
  /// A frame plane is structural for a box when at least this fraction of its image extent lies
  /// outside the box (a chair's seat is the chair's; the floor under it is not).
  double structural_outside = 0.5;
  /// The class prior: objects of `moving_classes` (things that move by themselves: people,
  /// animals) are dynamic whenever detected, whatever Algorithm 1 says of one frame, until they
  /// have been judged still for `moving_class_static_frames` frames in a row with the strict
  /// epsilon_d (a person sitting still). An object that just appeared has no matches to judge it
  /// by, and in a crowd the adaptive epsilon_d is raised by the movers the detector misses, so
  /// one frame's "static" is no evidence for a person. Off: every object starts static and is
  /// judged by Algorithms 1 and 2 alone. (The key's name predates the class list.)
  bool person_prior = true;
  std::vector<std::string> moving_classes = {"person", "bird", "cat", "dog"};
  /// 30 frames, one second at 30 Hz: longer than a walking gait cycle (about 1 s), so a person
  /// walking slowly is never judged still throughout it.
  int moving_class_static_frames = 30;
  /// Hysteresis for other classes: a dynamic object becomes static again after this many frames
  /// judged static.
  int static_frames_to_clear = 5;

  // --- boxes for the frame being tracked ---
  /// Boxes the detector computed on an earlier frame are carried to the frame being tracked by
  /// the image motion of their own features (median displacement of the features in the
  /// object's depth band, matched by descriptor). Off: they are only grown (5% a frame of age).
  bool propagate_boxes = true;
  /// Search radius for those matches: this many pixels per frame of age around the static
  /// prediction, plus match_radius. 30 px a frame is a person crossing the view at 1.5 m/s
  /// 1 m from the camera (fx 540, 30 Hz).
  double propagation_radius = 30.0;
  /// Matches needed to move a box by its features; fewer: the box moves with the camera only.
  int min_propagation_matches = 4;
  /// Margin (pixels per frame of age) added around a carried box for what its motion misses.
  double propagation_margin = 3.0;
  /// Carry boxes by the optical flow (pyramidal Lucas-Kanade, checked forwards and backwards)
  /// of their features from the detector's image to the frame's, started at where the camera's
  /// motion alone would put them; the descriptor matches above are the fallback when fewer than
  /// min_propagation_matches features are followed. Flow follows a blurred person whose
  /// descriptors no longer match (half the person boxes on Bonn crowd had fewer than 8 matches).
  /// Off by default: on Bonn crowd part 1 (threaded, 3 runs each) the carried boxes overlap the
  /// detector's next boxes better (median IoU 0.80 against 0.78) but the frame costs 3.5 ms more
  /// (object_prepare 4.4 against 1.1 ms) and the ATE is no better (0.0184 against 0.0188 m);
  /// docs/crowd.md.
  bool propagate_by_flow = false;
  /// A followed feature must come back to within this many pixels of its start when tracked
  /// back (the forward-backward check that rejects occlusions and drift).
  double flow_max_error = 1.0;

  // --- background inside boxes ---
  /// A box holds background behind the object: features farther than the object's own depth
  /// band are the background's and stay static. The box's feature depths are split into
  /// clusters where sorted depths jump by more than `object_depth_gap` metres (a body's surface
  /// is continuous; Kinect-class depth noise is 1-3 cm at 2-4 m); the object is the largest
  /// cluster, and only clusters behind it are freed (whatever is in front of it, an occluder or
  /// the object itself, stays the object's).
  bool separate_background = true;
  double object_depth_gap = 0.3;

  // --- movers without a box ---
  /// Features whose matched map point (or last-frame point, or the position where the feature's
  /// chain of frame-to-frame matches saw it up to frame_gap frames ago), moved by the estimated
  /// pose, lands farther than mover_displacement + mover_relative * depth metres from where the
  /// depth camera sees them are seeds of motion. 5 cm + 3 % of the depth is well above Kinect-class
  /// depth noise (about 1.5 % at 4 m) and the pose's error; a walking person moves 5 cm in 1-2
  /// frames.
  bool find_movers = true;
  double mover_displacement = 0.05;
  double mover_relative = 0.03;
  /// ... and whose reprojection lands more than this many pixels (level 0) from the keypoint:
  /// five standard deviations of a keypoint's position. A depth error alone (dark or shiny
  /// surfaces, mixed pixels at an edge) moves a point along its ray, not across the image.
  double mover_pixels = 5.0;
  /// Seeds and features are linked when closer than mover_link_radius pixels in the image and
  /// mover_link_depth metres in depth; features on a structural plane never link (a person's
  /// feet touch the floor). A region needs mover_min_seeds seeds, and at least mover_seed_share
  /// of its features with evidence must be seeds (a static region has a few outliers too).
  double mover_link_radius = 40.0;
  double mover_link_depth = 0.15;
  int mover_min_seeds = 8;
  double mover_seed_share = 0.5;
  /// A moving region found on a moving plane grows with the plane (the object coming into
  /// view), but its box stays within the image of an object this wide and tall (metres) at the
  /// depth it was last seen at: a person with a swinging arm or a cart is at most 1 m wide and
  /// 2 m tall; a box beyond that has taken the scene around the object (a room where an unboxed
  /// person fills 45 % of the view: the region's box grew to the whole image, ATE 0.0060 m and
  /// 0.0059 m on two rooms; within 1 x 2 m, 0.0069 and 0.0032 m, the online poses 0.0089 and
  /// 0.0057 m).
  double mover_max_width = 1.0;
  double mover_max_height = 2.0;

  // --- Algorithm 2 ---
  bool constraints = true;
  /// Classes that can only slide on a plane.
  std::vector<std::string> constrained_classes = {
      "chair", "dining table", "couch", "bench", "suitcase", "bed", "potted plant"};
  /// epsilon_m^p (metres) and epsilon_m^l (degrees).
  double constraint_distance = 0.02;
  double constraint_angle_deg = 8.0;
  /// Points with depth needed for the check; segments with depth needed for the line test to
  /// count (their 3D directions are noisy: with fewer, only the points decide).
  int min_constraint_points = 4;
  int min_constraint_lines = 3;
  /// Standard deviations of residuals (9) (metres) and (10) (cosine of the angle).
  double constraint_point_sigma = 0.02;
  double constraint_line_sigma = 0.03;

  std::optional<std::string> check() const;
  bool constrainable(const std::string& class_name) const;
  /// Whether the class prior holds for this class (person_prior and the class in moving_classes).
  bool self_moving(const std::string& class_name) const;
};

/// One feature of the current frame matched to the earlier (reference) frame. A point is one
/// pair; a line segment is its two endpoints (oriented like the current segment), each measured
/// to the current segment's infinite line.
struct MotionMatch {
  bool line = false;
  int feature = -1;  ///< index into the current frame's points or lines
  int box = -1;      ///< the box it belongs to
  Eigen::Vector2d ref_uv[2] = {Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero()};
  Eigen::Vector2d cur_uv[2] = {Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero()};
  std::optional<Eigen::Vector3d> ref_c[2];  ///< reference camera frame, when it has depth
  std::optional<Eigen::Vector3d> cur_c[2];  ///< current camera frame, when it has depth
  Eigen::Vector3d cur_line = Eigen::Vector3d::Zero();  ///< lines: normalised a u + b v + c
  double scale = 1.0;                                  ///< pyramid scale of a keypoint
  int endpoints() const { return line ? 2 : 1; }
};

/// Algorithm 1's verdict on one box.
struct ObjectDecision {
  int box = -1;
  int matches = 0;         ///< matched features (a line counts as two endpoints)
  int ransac_inliers = 0;  ///< of the box's own F (0 when not estimated)
  int counted = 0;         ///< features whose distance was measured
  int outliers = 0;
  double outlier_ratio = 0.0;
  double median_distance = 0.0;
  bool own_f = false;  ///< the box had enough matches for its own fundamental matrix
  bool decided = false;
  bool dynamic = false;
};

/// Distance (pixels) of a match's endpoint k to the camera's motion T_cur_ref: the transfer
/// distance when the reference endpoint has depth, else the epipolar distance (5); nullopt when
/// neither is defined (no depth and no baseline).
std::optional<double> motion_distance(const PinholeCamera& camera, const SE3& T_cur_ref,
                                      const MotionMatch& match, int k);

/// Epipolar distance (4)-(5) of p2 to the epipolar line F p1 (pixels).
double epipolar_distance(const Eigen::Matrix3d& F, const Eigen::Vector2d& p1,
                         const Eigen::Vector2d& p2);
/// F = K^-T [t]x R K^-1 of the relative pose T_cur_ref (maps reference pixels to current lines).
Eigen::Matrix3d fundamental_from_pose(const PinholeCamera& camera, const SE3& T_cur_ref);

/// Algorithm 1 over all boxes: `matches` carry their box index.
std::vector<ObjectDecision> detect_dynamic_objects(int num_boxes,
                                                   const std::vector<MotionMatch>& matches,
                                                   const PinholeCamera& camera,
                                                   const SE3& T_cur_ref,
                                                   const DynamicsOptions& options);

/// Algorithm 2's verdict on one dynamic box.
struct ConstraintDecision {
  bool constrained = false;
  int plane = -1;                 ///< index into the planes given
  double distance_change = 0.0;   ///< |mean point-plane distance change| (metres)
  double angle_change_deg = 0.0;  ///< |mean line-plane angle change|
  int points = 0;
  int lines = 0;
};

/// Algorithm 2 for one object's matches (in reference and current camera frames) against
/// planes given in the world frame ([n, d], n . p + d = 0, |n| = 1).
ConstraintDecision check_moving_constraint(const std::vector<const MotionMatch*>& object,
                                           const std::vector<Eigen::Vector4d>& planes_w,
                                           const SE3& T_w_ref, const SE3& T_w_cur,
                                           const DynamicsOptions& options);

/// Objects followed from frame to frame (class and box overlap), so that their state survives a
/// frame without evidence and flickers less.
class ObjectTracks {
 public:
  struct Track {
    int id = 0;
    perception::Detection detection;
    ObjectState state = ObjectState::kStatic;
    int static_streak = 0;
    int constraint_plane = -1;
    int frames = 0;
  };

  /// Matches this frame's boxes to the tracks (same class, best IoU >= 0.3); unmatched boxes
  /// start new tracks, dynamic when `starts_dynamic(box)` (the class prior), else static; tracks
  /// not seen are dropped. Returns the track index of each box.
  std::vector<int> associate(
      const std::vector<perception::Detection>& boxes,
      const std::function<bool(const perception::Detection&)>& starts_dynamic = {});
  /// Applies a decision: evidence of motion makes the track dynamic at once; static evidence
  /// clears it after `static_frames_to_clear` frames in a row; no evidence keeps the state.
  void update(int track, const ObjectDecision& decision, int static_frames_to_clear);
  void set_constrained(int track, bool constrained, int plane);
  const std::vector<Track>& tracks() const { return tracks_; }
  Track& track(int i) { return tracks_[static_cast<std::size_t>(i)]; }
  void clear() { tracks_.clear(); }

 private:
  std::vector<Track> tracks_;
  int next_id_ = 0;
};

}  // namespace mcslam::slam
