#pragma once
// Tracking: estimates the pose of each frame against the last frame and the local map, decides
// keyframes, and relocalises when lost. It reads the map under one shared lock per frame (so a
// frame sees one state of the map) and never writes it: everything the map should learn travels
// in a KeyFrameRequest to the local mapper. What it keeps of earlier frames in world coordinates
// follows the map when bundle adjustment or a correction moves it (follow_map).

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <unordered_set>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/id_marks.hpp"
#include "mcslam/core/timing.hpp"
#include "mcslam/map/map.hpp"
#include "mcslam/optim/constraint_residual.hpp"
#include "mcslam/optim/pose_filter.hpp"
#include "mcslam/optim/pose_smoother.hpp"
#include "mcslam/place/vocabulary.hpp"
#include "mcslam/slam/dynamics.hpp"
#include "mcslam/slam/frame.hpp"
#include "mcslam/slam/objects.hpp"
#include "mcslam/slam/occupancy.hpp"
#include "mcslam/slam/options.hpp"

namespace mcslam::slam {

enum class TrackingState { kNotInitialized, kOk, kLost };
const char* to_string(TrackingState state);

/// Tracking statistics of a landmark (point or line) between two keyframes (for culling).
struct LandmarkStatistics {
  std::uint64_t landmark = map::kNoId;
  int visible = 0;
  int found = 0;
};

/// A new keyframe for the mapper: the frame, its pose and its inlier landmark associations.
struct KeyFrameRequest {
  map::KeyFrameId id = map::kNoId;
  Frame frame;
  SE3 T_c_w;
  std::vector<map::PointId> landmarks;              // per point of frame (kNoId where none)
  std::vector<map::LineId> line_landmarks;          // per line segment of frame
  std::vector<map::PlaneId> plane_landmarks;        // per plane of frame
  std::vector<LandmarkStatistics> statistics;       // points
  std::vector<LandmarkStatistics> line_statistics;  // lines
  /// The colour image (CV_8UC3) as the camera gave it, when the caller has one: it colours new
  /// points, once the mapper has undistorted it (LocalMapper::set_undistorter).
  cv::Mat color;
  /// The frame's depth (CV_32FC1 metres, undistorted; shared, never written) and the image
  /// regions of its people and other movers and of its constrained movers (a pushed chair), for
  /// the dense map (System sets them; empty without one).
  cv::Mat depth;
  std::vector<DynamicRegion> dynamic_regions;
  std::vector<DynamicRegion> mover_regions;
  /// The objects seen standing still (their first place is forgotten when they move).
  std::vector<DynamicRegion> still_regions;
  /// Per point / line segment of frame: 1 on a dynamic or constrained moving object (no
  /// landmark may be created or fused there). Empty when the frame had no such object.
  std::vector<std::uint8_t> excluded_points;
  std::vector<std::uint8_t> excluded_lines;
  /// Map points seen to move since the last keyframe (find_movers): the mapper removes them.
  std::vector<map::PointId> moved_points;
  /// The keyframe the pose was tracked against, the pose relative to it, and the map's version
  /// then: a loop correction after it moves the new keyframe with its reference.
  map::KeyFrameId reference = map::kNoId;
  SE3 T_c_ref;
  std::uint64_t map_version = 0;
};

/// A relocalisation attempt (a lost frame).
struct RelocalisationInfo {
  /// Found again by tracking from the pose before the loss (the last frame's, then the
  /// reference keyframe's features), without a place search; the fields below stay empty.
  bool from_last_pose = false;
  bool by_database = false;  // candidates from the keyframe database (else brute force)
  double query_ms = 0.0;     // finding the candidate keyframes (the database query)
  double match_ms = 0.0;     // matching the frame's features with theirs
  int candidates = 0;        // keyframes with enough matches for PnP
  map::KeyFrameId keyframe = map::kNoId;  // the one that relocalised the frame
  double score = 0.0;                     // its bag-of-words score
};

struct TrackingOutcome {
  TrackingState state = TrackingState::kNotInitialized;
  bool relocalised = false;
  SE3 T_c_w;  // valid when state == kOk
  /// The pose fused with the motion model (tracker.pose_filter; T_c_w when it is off): what
  /// process() returns and trajectory_online.txt holds.
  SE3 T_c_w_online;
  /// What the filter made of the frame's pose (kOff with the filter off or the frame not tracked).
  optim::FilterOutcome online_pose = optim::FilterOutcome::kOff;
  /// With tracker.pose_filter.lag > 0: the pose of the frame `lag` poses back, smoothed with the
  /// frames since (pose_smoother.hpp); nullopt until there is one.
  std::optional<optim::LaggedPose> lagged;
  map::KeyFrameId reference = map::kNoId;  // keyframe the pose is stored relative to
  SE3 T_c_ref;                             // pose relative to that keyframe
  int matches = 0;                         // points matched (landmarks and depth points)
  int inliers = 0;                         // points, after the final pose optimisation
  int line_matches = 0;  // segments matched (map lines and the last frame's 3D segments)
  int line_inliers = 0;
  int plane_inliers = 0;  // frame planes matched to map planes, after optimisation
  std::optional<KeyFrameRequest> keyframe;
  /// Set when the frame was lost and relocalisation was tried.
  std::optional<RelocalisationInfo> relocalisation;
  /// Object handling: boxes, decisions, feature labels (all static without detections).
  ObjectOutputs objects;
  /// The final pose optimisation's inliers that are map points (state kOk): the frame's point
  /// index and the landmark (for the readout-time estimate).
  std::vector<std::pair<std::size_t, map::PointId>> point_inliers;
};

class Tracker {
 public:
  /// With a vocabulary, relocalisation finds its candidates through the map's keyframe
  /// database (direct index `direct_levels_up` levels above the words).
  Tracker(const PinholeCamera& camera, const TrackerOptions& options, const map::Map& map,
          std::shared_ptr<const place::Vocabulary> vocabulary = nullptr, int direct_levels_up = 3);

  /// `mapper_idle`: the mapper has nothing queued; `mapper_queue`: keyframes waiting for it.
  TrackingOutcome track(const Frame& frame, bool mapper_idle, std::size_t mapper_queue,
                        StageTimes* times = nullptr);

  TrackingState state() const { return state_; }
  /// Starts in a map made earlier (a loaded session): the first frames relocalise into it, and
  /// new keyframes are numbered after its own. With `localize`, no keyframe is ever requested:
  /// the map is only read.
  void start_in_map(map::KeyFrameId next_keyframe_id, bool localize);
  /// Localisation only (no keyframe is requested) or mapping, from the next frame on.
  void set_localize(bool localize) { localize_ = localize; }
  /// The camera's motion over `dt` seconds at the current velocity estimate, as the transform
  /// from the camera at time t to the camera at t + dt; nullopt without an estimate.
  std::optional<SE3> predicted_motion(double dt) const;
  /// Angular velocity of the camera (rad/s, camera frame) for the rolling-shutter correction:
  /// the rotation over the last two tracked steps (the last one alone after a loss), zero
  /// without an estimate. One step carries the noise of two poses over one frame interval, and
  /// the correction turns it into position noise (freiburg1_rpy: the position's second
  /// differences grow from 7.9 mm without the correction to 10.6 mm with it); over two steps it
  /// is half of that: 8.3 mm, and the unsmoothed ATE of part 1 from frame 240 0.0143 against
  /// 0.0188 m (docs/crowd.md).
  Eigen::Vector3d angular_velocity() const;
  /// Pose optimisations that found no usable solution (each left its frame's estimate failed).
  int solver_failures() const { return solver_failures_; }
  /// The lagged poses not given out yet (the last `lag`), smoothed with what came: the end of a
  /// run. Empty without a lag.
  std::vector<optim::LaggedPose> flush_lagged_poses();

 private:
  struct Match {
    map::PointId landmark = map::kNoId;  // kNoId: a point of the last frame's depth
    Eigen::Vector3d p_w = Eigen::Vector3d::Zero();
    bool active = false;
    bool outlier = false;
  };
  struct LineMatch {
    map::LineId landmark = map::kNoId;  // kNoId: a 3D segment of the last frame
    Eigen::Vector3d start_w = Eigen::Vector3d::Zero();
    Eigen::Vector3d end_w = Eigen::Vector3d::Zero();
    bool active = false;
    bool outlier = false;
  };
  struct PlaneMatch {
    map::PlaneId landmark = map::kNoId;
    Eigen::Vector4d plane_w = Eigen::Vector4d::Zero();
    bool active = false;
    bool outlier = false;
  };
  /// The frame's associations, one entry per point, line segment and plane of the frame.
  struct Associations {
    std::vector<Match> points;
    std::vector<LineMatch> lines;
    std::vector<PlaneMatch> planes;
    /// Per point, the last frame's point it was matched to by search_last_frame (-1: none).
    /// Kept when the match is later dropped as an outlier: a feature on a moving object is an
    /// outlier of the pose, and its track is what shows the motion (remove_movers()).
    std::vector<int> from_last;

    explicit Associations(const Frame& frame);
    void clear();
    /// Matched landmarks (active), and those the last optimisation kept (active, not outlier).
    int active_points() const;
    int active_lines() const;
    int inlier_points(bool landmarks_only) const;
    int inlier_lines(bool landmarks_only) const;
    int inlier_planes() const;
  };
  /// Point and line landmarks of the local map.
  struct LocalMap {
    std::vector<map::KeyFrameId> keyframes;
    std::vector<map::PointId> points;
    std::vector<map::LineId> lines;
  };
  /// What the next frame needs of this one: features, pose (relative to a keyframe, so that it
  /// follows bundle adjustment) and, per feature, its landmark or its camera-frame geometry.
  struct LastFrame {
    Frame frame;
    map::KeyFrameId reference = map::kNoId;
    SE3 T_c_ref;
    SE3 T_c_w;
    std::vector<map::PointId> landmarks;
    std::vector<std::optional<Eigen::Vector3d>> depth_points;  // camera frame
    std::vector<map::LineId> line_landmarks;
    std::vector<bool> line_has_depth;  // the segment's own 3D endpoints (camera frame) serve
    /// Per point with depth, where it was seen (world frame, through each frame's tracked pose)
    /// along its chain of frame-to-frame matches, oldest first, this frame last: at most
    /// dynamics.frame_gap + 1 positions. Motion over several frames shows a slow mover that a
    /// single frame's step hides in the depth noise.
    std::vector<std::vector<Eigen::Vector3d>> tracks;
  };

  TrackingOutcome initialize(const Frame& frame);
  /// The frame's first estimate: from the last frame, else the reference keyframe; when lost,
  /// find_again.
  struct FirstEstimate {
    bool ok = false;
    bool relocalised = false;
    bool tried_relocalisation = false;
  };
  FirstEstimate first_estimate(const Frame& frame, Associations& assoc, SE3& T_c_w);
  /// From the last frame (at the predicted pose, then at its own), else from the reference
  /// keyframe's features at the last pose. A lost tracker has no velocity: the last pose only.
  bool track_from_last_frame(const Frame& frame, Associations& assoc, SE3& T_c_w);
  /// The frame after the map's first (or after a relocalisation) has no velocity: its last pose
  /// predicts a camera that stands still, and a turning one has left the matching window
  /// (freiburg1_rpy's second frame, 3.7 degrees on: 105 inliers of 459 matches, a pose 49 mm
  /// off). Matching descriptors against the reference keyframe needs no prediction but finds
  /// fewer matches on a slow camera; both are tried, and the pose with more inliers is kept.
  bool track_without_velocity(const Frame& frame, Associations& assoc, SE3& T_c_w);
  /// A lost frame's first estimate: from the pose before the loss while it is recent
  /// (recovery_window), else by relocalisation.
  FirstEstimate find_again(const Frame& frame, Associations& assoc, SE3& T_c_w);
  /// The constant-velocity prediction of the frame's pose from the last frame's.
  SE3 predict(const Frame& frame, const SE3& T_last) const;
  /// The local map's matches, the movers without a box, and the frame's success test.
  bool refine_with_local_map(const Frame& frame, Associations& assoc, SE3& T_c_w, bool relocalised);
  /// The outcome's counts and objects, whether or not the frame was tracked.
  TrackingOutcome outcome_of(const Frame& frame, const Associations& assoc,
                             const FirstEstimate& first, bool ok) const;
  /// A tracked frame: velocity, keyframe decision, the last frame's record.
  void accept(const Frame& frame, const Associations& assoc, const SE3& T_c_w, bool mapper_idle,
              std::size_t mapper_queue, TrackingOutcome& out);
  /// Re-anchors the tracker's world-frame history (the last frame's pose and feature tracks, the
  /// object handler's past poses) through the motion of the last frame's reference keyframe
  /// since that frame was tracked. Call under the map's read lock.
  void follow_map();
  /// Motion without a box (ObjectHandler::find_movers) after the final estimate; re-optimises
  /// without the movers' features when it finds some. Returns the weighted inlier count.
  int remove_movers(const Frame& frame, Associations& assoc, SE3& T_c_w, int inliers);
  bool track_last_frame(const Frame& frame, const SE3& prediction, Associations& assoc, SE3& T_c_w);
  bool track_reference_keyframe(const Frame& frame, Associations& assoc, SE3& T_c_w);
  /// A keyframe whose features match the frame's: its landmarks, by the frame's features.
  struct RelocalisationCandidate {
    map::KeyFrameId keyframe = map::kNoId;
    double score = 0.0;
    std::vector<std::pair<int, map::PointId>> correspondences;  // feature, landmark
    std::vector<Eigen::Vector3d> p_w;
  };
  /// A candidate's PnP pose and the correspondences (by index) consistent with it.
  struct PnpPose {
    SE3 T_c_w;
    std::vector<int> inliers;
  };
  /// One frame's relocalisation work: the candidates, best first, and the PnP poses of those
  /// tried so far (nullopt: PnP failed). The frame's second try, with every feature (track()),
  /// reuses them: under the map's read lock for the whole frame they are the same. Made by the
  /// frame's first try, dropped when its first estimate is done (so it never outlives the frame).
  struct RelocalisationWork {
    RelocalisationInfo info;
    std::vector<RelocalisationCandidate> candidates;
    std::vector<std::optional<PnpPose>> poses;
  };
  bool relocalise(const Frame& frame, Associations& assoc, SE3& T_c_w);
  /// The candidates of a relocalisation (by the keyframe database, else by brute force), best
  /// first, and their timing in work.info.
  void find_relocalisation_candidates(const Frame& frame, RelocalisationWork& work) const;
  std::optional<PnpPose> solve_pnp(const Frame& frame,
                                   const RelocalisationCandidate& candidate) const;
  /// Adds local-map matches and re-optimises. Returns the weighted inlier count.
  int track_local_map(const Frame& frame, Associations& assoc, SE3& T_c_w, double radius_factor);
  /// Matches the last frame's points projected with T_c_w; from_last gets each match's source.
  int search_last_frame(const Frame& frame, const SE3& T_c_w, double radius,
                        std::vector<Match>& matches, std::vector<int>& from_last) const;
  int search_last_lines(const Frame& frame, const SE3& T_c_w, double distance_factor,
                        std::vector<LineMatch>& matches) const;
  /// Matches the frame's planes to the map's. Call under the map's read lock.
  int search_planes(const Frame& frame, const SE3& T_c_w, std::vector<PlaneMatch>& matches) const;
  int search_local_points(const Frame& frame, const SE3& T_c_w, double radius_factor,
                          std::vector<Match>& matches);
  int search_local_lines(const Frame& frame, const SE3& T_c_w, std::vector<LineMatch>& matches);
  /// Pose optimisation on every active association, established landmarks first
  /// (TrackerOptions::established_age); returns the weighted inlier count.
  /// `rolling_shutter`: also correct the frame's angular velocity from its own rolling-shutter
  /// distortion and solve again (tracker.refine_rolling_shutter; the final solves only).
  int optimize(const Frame& frame, Associations& assoc, SE3& T_c_w, bool rolling_shutter = false);
  /// The angular velocity's correction (optim/rolling_shutter.hpp) estimated at `result`'s pose
  /// and inliers, the keypoints of `problem` moved by it and the pose solved again.
  void refine_rolling_shutter(const Frame& frame, optim::PoseProblem& problem,
                              optim::PoseOptimizationResult& result) const;
  /// Which of the optimised point and line associations (by index) are established landmarks.
  /// Call under the map's read lock.
  std::pair<std::vector<bool>, std::vector<bool>> established_flags(
      double timestamp, const Associations& assoc, const std::vector<std::size_t>& point_index,
      const std::vector<std::size_t>& line_index) const;
  /// Inliers as tracking success counts them: points + lines + plane_inlier_weight * planes.
  int weighted_inliers(const Associations& assoc) const;
  void update_local_map(const Associations& assoc, const SE3& T_c_w);
  /// Keyframes within tracker.spatial_radius of the camera that look its way (not yet `chosen`),
  /// the nearest tracker.spatial_keyframes of them, to the local keyframes.
  void add_nearby_keyframes(const SE3& T_c_w, std::unordered_set<map::KeyFrameId>& chosen);
  /// The local keyframes' point and line landmarks, each once.
  void collect_local_landmarks();
  bool need_keyframe(const Frame& frame, const Associations& assoc, bool mapper_idle,
                     std::size_t mapper_queue) const;
  KeyFrameRequest make_keyframe(const Frame& frame, const Associations& assoc, const SE3& T_c_w);
  void remember_last_frame(const Frame& frame, const Associations& assoc, const SE3& T_c_w,
                           map::KeyFrameId reference);
  std::optional<SE3> last_frame_pose() const;
  /// Pose of a keyframe in the map, or of one still queued for the mapper.
  std::optional<SE3> keyframe_pose(map::KeyFrameId id) const;
  double close_depth() const { return baselines(options_.close_depth_factor); }
  double keyframe_close_depth() const { return baselines(options_.keyframe_close_depth_factor); }
  /// `factor` stereo baselines in metres (bf / fx).
  double baselines(double factor) const { return factor * camera_.bf / camera_.fx; }

  PinholeCamera camera_;
  TrackerOptions options_;
  const map::Map& map_;
  std::shared_ptr<const place::Vocabulary> vocabulary_;
  int direct_levels_up_ = 3;
  RelocalisationInfo relocalisation_;
  std::optional<RelocalisationWork> relocalisation_work_;

  TrackingState state_ = TrackingState::kNotInitialized;
  std::optional<LastFrame> last_;
  std::optional<SE3> velocity_;           // T_cur_last of the last tracked step
  double velocity_dt_ = 0.0;              // its duration in seconds
  std::optional<SE3> previous_velocity_;  // the step before it, when tracked
  double previous_velocity_dt_ = 0.0;
  map::KeyFrameId next_keyframe_id_ = 0;
  bool localize_ = false;
  std::uint64_t last_keyframe_frame_ = 0;
  double last_keyframe_time_ = 0.0;
  std::uint64_t last_relocalisation_frame_ = 0;
  int solver_failures_ = 0;
  // The information of the frame's last pose optimisation, and the filter it goes to.
  Matrix6d pose_information_ = Matrix6d::Zero();
  optim::PoseFilter pose_filter_;
  std::optional<optim::PoseSmoother> pose_smoother_;  // with a lag
  // Local map of the current frame.
  map::KeyFrameId reference_ = map::kNoId;
  LocalMap local_;
  // The local map's points and lines while it is collected; the frame's matched points while
  // the local map is searched.
  IdMarks point_marks_;
  IdMarks line_marks_;
  // Per keyframe id, the landmarks it shares with the frame (zero between frames).
  IdCounts keyframe_counts_;
  // Poses of keyframes requested but possibly not yet in the map.
  std::unordered_map<map::KeyFrameId, SE3> pending_keyframes_;
  // Statistics gathered since the last keyframe request.
  std::unordered_map<map::PointId, LandmarkStatistics> statistics_;
  std::unordered_map<map::LineId, LandmarkStatistics> line_statistics_;
  // Dynamic objects.
  ObjectHandler objects_;
  // Map points seen to move since the last keyframe request, and all of them until the mapper
  // has removed them (tracking no longer matches them).
  std::vector<map::PointId> moved_points_;
  std::unordered_set<map::PointId> moved_set_;
};

}  // namespace mcslam::slam
