#pragma once

#include <optional>
#include <string>

#include "mcslam/features/lines.hpp"
#include "mcslam/features/orb.hpp"
#include "mcslam/features/planes.hpp"
#include "mcslam/mapping/options.hpp"
#include "mcslam/optim/bundle_adjustment.hpp"
#include "mcslam/optim/pose_filter.hpp"
#include "mcslam/optim/pose_graph.hpp"
#include "mcslam/optim/pose_optimizer.hpp"
#include "mcslam/optim/trajectory_smoothing.hpp"
#include "mcslam/slam/dynamics.hpp"
#include "mcslam/slam/readout.hpp"

namespace mcslam::slam {

struct TrackerOptions {
  /// Depths closer than close_depth_factor * bf / fx metres are "close": a keypoint's depth alone
  /// makes it a landmark (the mapper's new points, the last frame's points searched in the next
  /// frame) and close landmarks decide keyframe culling. 60 is 4.6 m with TUM's bf 40 and fx 517:
  /// where structured-light cameras' depth ends (Bonn crowd part 1 has none beyond 4.4 m). The
  /// depth's error grows as z^2 (1.4e-3 z^2: 3 cm at 4.6 m), as the depth residual's weight
  /// already assumes. ORB-SLAM2's ThDepth is 40 (3.1 m), which leaves out 37 % of Bonn crowd part
  /// 1's depth pixels; docs/tracking.md has the measurements.
  double close_depth_factor = 60.0;
  /// The range of ORB-SLAM2's keyframe rule "fewer than close_tracked_threshold close points
  /// tracked and more than close_untracked_threshold not" (times bf / fx metres), kept at
  /// ORB-SLAM2's 40: the rule asks for a keyframe while near structure is being lost, and counting
  /// points to 4.6 m as near makes it fire too seldom in a small room (a synthetic one: 10
  /// keyframes instead of 13, none in its last 3.3 s).
  double keyframe_close_depth_factor = 40.0;
  /// Depth values outside [min_depth, max_depth] metres are treated as missing.
  double min_depth = 0.1;
  double max_depth = 10.0;
  /// Projection search radius (px at level 0, scaled by the keypoint's level) against the last
  /// frame; doubled once when too few matches are found.
  double motion_search_radius = 15.0;
  /// Hamming threshold for projection matches to the last frame and the local map.
  int max_descriptor_distance = 100;
  double local_map_ratio = 0.8;
  /// Local-map search window factor (times 2.5-4 px, times the level's scale). RGB-D: 3.
  double local_map_search_radius = 3.0;
  /// Weight of the depth residual (the virtual right coordinate u - bf / z, optim::DepthTerm)
  /// relative to u, v in pose optimisation (the tracker's and the loop closer's); 0 uses u, v
  /// only.
  double depth_weight = 1.0;
  /// Move each keypoint's depth from the depth image's capture time to the colour image's with
  /// the tracked velocity (Kinect v1 streams are ~15 ms apart: ~1 degree at 60 deg/s).
  bool compensate_depth_time = true;
  /// In each frame's final pose optimisation, estimate the error of the angular velocity its
  /// keypoints were moved to the middle row's time with from the frame's own rolling-shutter
  /// shear (optim/rolling_shutter.hpp), move them by it and solve the pose again. Only with a
  /// readout (camera.readout_time != 0). On: the prediction from the last frames misses a
  /// handheld camera's turn rate by 0.49 rad/s (freiburg1_rpy), most of its online pose's
  /// frame-to-frame noise (online RPE over one frame 8.35 -> 6.4 mm; docs/rolling-shutter.md).
  bool refine_rolling_shutter = true;
  /// The angular velocity a frame's keypoints are moved to the middle row's time with: the pose
  /// filter's (tracker.pose_filter, when it is on, has one and its densities are the settings':
  /// the camera moves within the motion model), which weighs the frames' turns by their measured
  /// noise and is current to the last frame; otherwise, or false, the mean over the last two
  /// tracked steps, centred a frame and a half back. A camera livelier than the model (the
  /// densities lifted) outruns the filter's rate: taken always, it left the 30 ms rolling-shutter
  /// render at 90 deg/s 61 mm off against 24 (tests/slam/rolling_shutter_test.cpp). Default
  /// threaded runs, yolov8n_320, 12 + 12 side by side: online ATE freiburg1_rpy 9.1 -> 8.4 mm,
  /// Bonn crowd part 1 17.8 -> 17.1, from frame 240 12.6 -> 12.3; `trajectory.txt`
  /// freiburg1_rpy 7.2 -> 6.7 mm; online RPE over one frame the same (docs/rolling-shutter.md).
  bool filtered_angular_velocity = true;
  /// The prior on that correction (rad/s per axis): the prediction's error, 0.49 rad/s RMS over
  /// three axes against freiburg1_rpy's ground truth, 0.3 per axis.
  double angular_velocity_sigma = 0.3;
  /// The refinement runs when the predicted turn rate is at least this (rad/s), or when there is
  /// no prediction (the frame after the map's first). The prediction misses by about 0.4 times
  /// the turn rate (freiburg1_rpy: 0.49 rad/s RMS at 1.26), a shear of 2 px per rad/s between
  /// the middle and the last row of a 20 ms readout at 525 px: below 0.5 rad/s it is under the
  /// keypoints' own 1 px, and the frame's shear then tells it from the map's errors no better
  /// than chance (Bonn crowd, turning at 0.1-0.3 rad/s: online ATE 1-1.6 mm worse refined).
  double refine_min_angular_velocity = 0.5;
  int min_motion_matches = 20;
  int min_pose_inliers = 10;
  int min_local_map_inliers = 30;
  int min_relocalisation_inliers = 50;
  /// Local map: keyframes sharing points with the frame, plus neighbours, at most this many.
  int max_local_keyframes = 60;
  /// Also in the local map: up to this many keyframes within spatial_radius metres of the
  /// camera whose optical axes differ by less than spatial_max_angle_deg (0 disables, the
  /// default). Off, a revisit is left to loop closing, which spreads the drift over the loop;
  /// on, tracking snaps to the old keyframes and the drift stays in the keyframes before the
  /// snap: synthetic 24 s loop 0.0099 m off, 0.0242 m on; freiburg1_rpy threaded with yolov8n
  /// 0.0111 vs 0.0118 m and Bonn crowd part 1 0.0184 vs 0.0194 m (medians of 3; README).
  int spatial_keyframes = 0;
  double spatial_radius = 0.5;
  double spatial_max_angle_deg = 40.0;
  /// Keyframe decision (ORB-SLAM2's rules for RGB-D).
  int max_frames_between_keyframes = 30;
  /// A keyframe once the frame tracks fewer than this share of its reference keyframe's
  /// established landmarks (and the mapper is idle, or the view is being lost): ORB-SLAM2's 0.75
  /// with depth. 0.85 gives the mapper a keyframe as soon as it is idle and the view has changed
  /// (Bonn crowd part 1, threaded: `trajectory.txt` 12.3 -> 10.8 mm, online 14.1 -> 13.4, 0.97x the
  /// frame rate), a gain from one window of one sequence (elsewhere neutral or against), and 2-3
  /// times the keyframes where the mapper keeps up; docs/tracking.md has the measurements.
  double keyframe_ref_ratio = 0.75;
  /// A keyframe also once this many seconds have passed since the last one, whatever share of
  /// the reference's landmarks the frame still tracks (0: off, ORB-SLAM2's rule alone). Panning
  /// back over mapped ground the rule alone leaves Bonn crowd part 1 1.4-1.8 s without one; 0.5
  /// lowers its online ATE 14.2 -> 13.1 mm (--realtime's 14.6 -> 14.1) at 0.95x the frame rate,
  /// but the synthetic dynamic scenes' online pose gets worse (0.1-0.7 mm); docs/tracking.md.
  double keyframe_interval = 0.0;
  int close_tracked_threshold = 100;
  int close_untracked_threshold = 70;
  /// Relocalisation: keyframes tried per lost frame (the keyframe database's best results; the
  /// newest and a spread over the map without a vocabulary).
  int relocalisation_candidates = 30;
  /// A frame lost within this many seconds of the last tracked one is first tracked from that
  /// frame's pose (its points, then the reference keyframe's by descriptor); relocalisation's
  /// place search runs only when that fails, and the result must pass relocalisation's test
  /// (min_relocalisation_inliers). Half a second: at freiburg1_rpy's turn rate (a fast hand-held
  /// sequence: 0.86 rad over a second, median) the camera turns by 0.43 rad, less than half the
  /// field of view (0.55 rad for a 525 px focal length over 640 px), so the reference keyframe's
  /// view still overlaps the frame's (Bonn crowd turns 0.15 rad in a second). A frame lost among
  /// people, whose place search finds few static matches, is found again from the static part
  /// that was being tracked. 0: off.
  double recovery_window = 0.5;
  /// Frames that need this many keypoints with depth to start the map.
  int min_initial_points = 500;
  /// With lines, a frame with fewer points may also start the map when it has at least this
  /// many line segments with depth.
  int min_initial_lines = 10;
  /// In the inlier counts that decide whether tracking succeeded, a line counts as one point
  /// and a plane as this many (a plane fixes three degrees of freedom with thousands of pixels).
  /// Points and lines must still give min_pose_inliers on their own: planes come from the depth
  /// image alone and cannot tell a blank colour image from a good one.
  int plane_inlier_weight = 10;

  // --- established landmarks first ---
  /// A landmark created at least this many seconds before the frame (its first keyframe's
  /// time) is established: a walking person (>= 0.5 m/s) moves half a metre in a second, far
  /// outside the local map's search window, so a point still matched a second after it was made
  /// is not on a walker. Each pose is solved first from established points, lines and the
  /// planes; every other observation (young landmarks, the last frame's points) then enters
  /// only if that pose explains it within established_gate times its chi-square threshold, so
  /// that a mover nobody boxed cannot drag the pose through the points it just gave the map.
  /// This holds when the established landmarks' inliers alone pass the frame's success test
  /// (min_pose_inliers points and lines, min_local_map_inliers with the planes weighted);
  /// otherwise, as at the start of a map or in a new place, everything enters at once.
  /// 0: off (every observation from the start, ORB-SLAM2's way).
  double established_age = 1.0;
  /// 4: a residual twice the chi-square threshold's standard deviations (5.6 sigma for a point
  /// with depth). A person crossing the view 1 m away moves 15 px a frame (chi2 ~ 200).
  double established_gate = 4.0;

  // --- lines ---
  /// Standard deviation (pixels) of an observed line's position, for residual (7).
  double line_sigma = 1.5;
  /// Matching a predicted (projected) segment to an observed one.
  int line_max_descriptor_distance = 80;
  double line_max_angle_deg = 10.0;
  double line_max_distance = 20.0;
  double line_min_overlap = 0.3;

  // --- planes ---
  /// Standard deviations of an observed plane for residual (8): its normal's angles and its
  /// distance.
  double plane_angle_sigma_deg = 2.0;
  double plane_distance_sigma = 0.02;
  /// A frame plane matches a map plane within these (after prediction with the pose).
  double plane_match_angle_deg = 10.0;
  double plane_match_distance = 0.1;
  /// A point with depth lies on a frame plane when within this distance of it (metres).
  double on_plane_distance = 0.02;

  optim::PoseOptimizerOptions pose;
  /// The online pose (what process() returns, trajectory_online.txt): the frame's pose fused with
  /// the motion model (optim/pose_filter.hpp) when enabled, and with a lag the lagged pose too
  /// (optim/pose_smoother.hpp). Tracking, keyframes and the final trajectory always go on from
  /// the frame's own pose.
  optim::PoseFilterOptions pose_filter;
  /// Dynamic objects (Algorithm 1) and moving constraints (Algorithm 2), when frames carry
  /// detections.
  DynamicsOptions dynamics;

  std::optional<std::string> check() const;
};

struct MapperOptions {
  /// New points from depth per keyframe: all close ones, and at least this many overall.
  int min_new_points = 100;
  /// Keyframes whose neighbours' points are fused into a new keyframe.
  int fuse_neighbours = 10;
  double fuse_radius = 3.0;
  /// Hamming threshold for fusing a landmark into a keyframe feature.
  int fuse_descriptor_distance = 50;
  /// Weight of the depth residual in bundle adjustment (local, after a loop and at the end),
  /// relative to u, v at the keypoint's level.
  double depth_weight = 1.0;
  /// Bundle adjustment's depth residual is the disparity bf / z alone instead of the virtual
  /// right coordinate u - bf / z (optim::DepthTerm). With u - bf / z a point's depth follows its
  /// keypoints' u however heavily the depth is weighted; the disparity holds it where the depth
  /// images put it. Off by default: with real depth it made the online pose no better (Bonn crowd
  /// part 1 from frame 240 worse), with the renders' depth noise alone it improves both
  /// trajectories (docs/design.md, "Depth in bundle adjustment").
  bool disparity_residual = false;
  /// Local BA: covisible keyframes optimised together with the new one.
  int ba_keyframes = 20;
  int min_covisibility_weight = 15;
  /// A keyframe is redundant when this fraction of its close points is seen by >= 3 others.
  double redundant_ratio = 0.9;
  bool cull_keyframes = true;
  /// Map planes closer than these are merged into one.
  double plane_merge_angle_deg = 5.0;
  double plane_merge_distance = 0.03;
  /// When the run ends: bundle adjustment of the whole map before the final trajectory is
  /// written (the online trajectory is unaffected). 0 iterations disables it.
  int global_ba_iterations = 15;
  optim::BundleAdjustmentOptions ba;

  std::optional<std::string> check() const;
};

/// Loop closing (its own thread; inline in sequential mode).
struct LoopOptions {
  bool enabled = true;
  /// A map younger than this many keyframes, or this many keyframes after the last loop,
  /// looks for no loop (ORB-SLAM2's 10).
  int min_keyframes = 10;
  /// A candidate place must be found again for this many consecutive keyframes (each one's
  /// candidates covisible with the previous one's) before it is verified.
  int min_consistency = 3;
  /// Matches through the vocabulary's direct index with depth on both sides, needed before
  /// RANSAC; then inliers of the SE(3) found (u, v and the virtual right coordinate within the
  /// chi-square 95 % bound of 3 degrees of freedom at the keypoint's level sigma), and after the
  /// guided search in the matched keyframe's neighbourhood.
  int min_matches = 20;
  int min_ransac_inliers = 15;
  int min_inliers = 40;
  int ransac_iterations = 300;
  /// Covisibility edges of at least this weight join the essential graph (ORB-SLAM2's 100).
  int essential_edge_weight = 100;
  optim::PoseGraphOptions pose_graph;
  /// Bundle adjustment of the whole map after a loop (in the background; 0 disables it).
  int full_ba_iterations = 10;

  std::optional<std::string> check() const;
};

/// Place recognition: the bag-of-words vocabulary, the keyframe database built with it, and
/// loop closing. Without a vocabulary ("") relocalisation falls back to matching descriptors
/// against keyframes directly and loops are not closed.
struct PlaceOptions {
  std::string vocabulary = default_vocabulary_path();
  /// The direct index groups features by their vocabulary node this many levels above the
  /// words (3 of 5: 100 nodes for a 10-way tree; matching compares features under one node).
  int direct_levels_up = 3;
  LoopOptions loop;

  /// The default vocabulary (data/orb_vocabulary.bin of the repository, installed in
  /// share/mcslam): $MCSLAM_VOCABULARY when set, else find_data_file (core/data_files.hpp).
  static std::string default_vocabulary_path();
  std::optional<std::string> check() const;
};

/// Which landmark kinds take part, so that users can compare (all on by default). A kind that is
/// off is not even extracted. Relocalisation matches points, so it needs `points`.
struct FeatureSwitches {
  bool points = true;
  bool lines = true;
  bool planes = true;
};

struct SystemOptions {
  FeatureSwitches use;
  features::OrbOptions orb;
  features::LineOptions lines;
  features::PlaneOptions planes;
  TrackerOptions tracker;
  MapperOptions mapper;
  PlaceOptions place;
  ReadoutOptions readout;
  /// The final trajectory's positions smoothed with a motion prior (System::trajectory,
  /// trajectory.txt); the online poses are never smoothed.
  optim::TrajectorySmoothingOptions trajectory;
  /// The dense occupancy map (mapping::MappingWorker on a thread of its own), fed with each
  /// keyframe's depth and its people's and movers' pixels once the mapper has refined it, and
  /// rebuilt where loop corrections and the final bundle adjustment move keyframes. The
  /// `mapping.` settings; mapping.enabled false: no dense map (`mcslam run --no-occupancy`).
  bool occupancy_enabled = true;
  mapping::OccupancyOptions occupancy;
  /// With a map made earlier (System's initial map): track against it without changing it (no
  /// keyframes, no mapping, no loop closing). Set by `mcslam run --localize`.
  bool localize = false;
  /// Run local mapping inline after each keyframe (deterministic) instead of on its own thread.
  bool sequential = false;
  /// In threaded runs: when the mapper is idle as a keyframe is handed to it, the frame returns
  /// only once the mapper has inserted the keyframe with its new points, lines and planes (not
  /// its fusion or bundle adjustment), so that the next frame is tracked against them, as in a
  /// sequential run. The insertion takes a few milliseconds, the bundle adjustment that follows
  /// tens; a busy mapper is not waited for (its bundle adjustment would have to yield first, and
  /// the keyframe decisions, which ask whether the mapper is idle, would change: 114 keyframes
  /// instead of 60 on Bonn crowd part 1). Measured in docs/tracking.md ("The frame after a
  /// keyframe").
  bool wait_for_keyframe_points = true;
  /// In threaded runs (`mcslam run` without --sequential), extract each frame's points, lines
  /// and planes on the reader's thread (with --realtime once the frame is due and the loop has
  /// taken the frame before) while the frame loop still tracks the frame before
  /// (System::extract_features); the loop then only finishes them with the motion. The
  /// features are the same; the two stages overlap on the two cores. "true", "false" or "auto":
  /// `mcslam run` makes auto true with --realtime and false otherwise; System takes auto as
  /// false. Offline the overlap takes CPU from the other threads (measured on 2 cores,
  /// docs/crowd.md): freiburg1_rpy runs 1.1-1.4x the frames per second but the mapper keeps up
  /// with fewer of them (a fifth fewer keyframes, ATE 1.1-1.2x) and a detector model gets fewer
  /// passes. In real time, where a frame the loop cannot take is lost, Bonn crowd part 1 with
  /// yolov8n_320 had 96-99 % of its frames processed against 90-94 %, latency p95 under 100 ms
  /// in every run (61-97 ms), ATE 1.07x. Not while frames wait for their own boxes (the cold
  /// start); never with orb.moving_density > 0, whose points depend on the frame before.
  std::string extract_ahead = "auto";
  /// A detector model (threaded mode, not waiting for boxes) is given a frame only when at least
  /// this many frames have passed since the last one it was given. Boxes are carried from the
  /// detector's frame to every frame by their features' motion (dynamics.propagate_boxes), so a
  /// detection every second frame keeps them as close to the objects (mean IoU 0.83 against the
  /// next detection on Bonn crowd, 0.85 at 1) while the forward pass, a quarter of the CPU on two
  /// cores, runs half as often. 1: whenever the detector is free.
  int detection_interval = 2;
  /// Nice value added to the threads without a per-frame deadline (local mapping, loop closing
  /// and its full bundle adjustment) in threaded mode. On a machine with fewer cores than busy
  /// threads they then yield to the frame's own threads (extraction and tracking), whose delay
  /// is the frame's latency, while a keyframe's mapping may take a few frames longer: measured
  /// in README ("Speed"). 0: the same priority as the frame; at most 19.
  int background_niceness = 5;
  /// The same for the detector's thread (a model in threaded mode): it then runs at the rate
  /// the CPU leaves it, and boxes are carried between its detections (dynamics.propagate_boxes).
  /// OpenCV's own worker threads, which run most of a forward pass, keep their priority.
  int detector_niceness = 0;
  /// Threads that OpenCV's own parallel loops may use (cv::setNumThreads, process-wide: the
  /// application applies it at start, the library never does). mcslam runs its stages on
  /// threads of its own (reader, ORB / lines / planes, detector, mapper); OpenCV's pool on top
  /// of them makes the detector's forward pass spread over every core and hold the frame's
  /// threads back. 1: each OpenCV call runs on the thread that makes it; 0: OpenCV's default
  /// (one worker per core).
  int opencv_threads = 1;
  /// With a detector model, frames wait for their own boxes (as with --wait-detections) until
  /// the map holds this many keyframes: the first map is built from fresh boxes, so that people
  /// in view from the first frame are not mapped as static. 0: never.
  int cold_start_keyframes = 5;
  /// A detector model runs on the image scaled by this factor, its sides rounded up to multiples
  /// of 32 (perception::input_size_for: 640x480 at 0.35 is 224x192); 0: at the input size the
  /// model was exported for. The work of a forward pass grows with the input's area, and what
  /// it must resolve is a person: at 0.35 a person 1.7 m tall 5 m away (fy 525) is still 62
  /// pixels tall, twice the coarsest head's stride. Measured on Bonn crowd part 1 against
  /// yolov8n at 640x640: people found 0.975 at 224x192 (0.990 at 320x320), a pass 0.43 of the
  /// 320x320 one on one thread (docs/crowd.md).
  double detector_scale = 0.35;

  std::optional<std::string> check() const;
};

}  // namespace mcslam::slam
