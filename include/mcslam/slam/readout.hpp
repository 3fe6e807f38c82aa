#pragma once
// Self-calibration of the colour camera's rolling-shutter readout time (camera.readout_time:
// auto). Row v of an image is exposed (v - H/2) / H * r after its middle row (r < 0: rows read
// bottom to top); while the camera moves its points there have moved by that time times their
// velocity. The estimator pairs each tracked frame's pose inliers with the same landmarks'
// observations (keypoint and depth) in earlier frames (anchors, a third, two thirds and all of
// anchor_age old), linearises the reprojection of the anchor's 3D points into the frame in the
// 6 parameters of the pose between the two and the one shared r (which moves both the anchor's
// points and the frame's keypoints), eliminates the pose (Schur complement) and sums the 1x1
// normal equations of r over the pairs and frames. Neither the map's points nor the tracked
// poses enter but as a linearisation point: both were made from images compensated with the
// readout then in use and absorb part of the skew (against map points, the estimate of a
// synthetic 30 ms readout stayed at 0; against tracked anchor poses it fell 20-30 % short).
// It is owned and fed by the thread that tracks (System::process).

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"

namespace mcslam::slam {

struct ReadoutOptions {
  /// A frame counts when the camera turns at least this fast (rad/s, central difference of the
  /// tracked poses). Over a 20 ms readout at 0.1 rad/s the image rows shift by 0.1 * 0.02 * 520
  /// = 1 px between the top and the bottom, the keypoint noise: slower frames tell nothing.
  double min_angular_velocity = 0.1;
  /// Pose inliers a frame needs: 6 pose parameters and r are eliminated per frame, and 20
  /// points keep that 7x7 system well conditioned (a tracked frame has 100-400).
  int min_points = 20;
  /// Frames (that count) before the estimate may be used: one second of turning at 30 Hz, so
  /// that a turn in one direction and its return both take part.
  int min_frames = 30;
  /// The estimate is confident once its standard deviation is below this (s). 2 ms is a tenth
  /// of a Kinect's 20 ms readout; at the 1.5 rad/s of TUM freiburg1_rpy it leaves at most
  /// 1.5 * 0.001 * 520 = 0.8 px of skew at the image's top and bottom rows.
  double max_std = 0.002;
  /// A confident estimate is used only when it is this many standard deviations from zero;
  /// otherwise 0 (no compensation) is used, so that a guess never costs more than none.
  double min_significance = 3.0;
  /// Huber threshold on a point's whitened reprojection error (sqrt of the 2-dof chi-square at
  /// 95 %, 5.991, as pose optimisation uses): mismatches and movers weigh less.
  double huber = 2.447;
  /// Largest magnitude of the readout time (s) taken as physical: a frame's own estimate beyond
  /// it by more than three of its standard deviations is a tracking failure and is dropped.
  /// 0.1 s is the bound PinholeCamera::check() accepts (a 30 Hz camera reads in < 33 ms).
  double max_readout = 0.1;
  /// Age (s) of the oldest anchor frame (others at a third and two thirds of it). The turn
  /// must differ between a frame and its anchor for r to show: a hand-held camera's turns last
  /// about half a second to a second, so anchors up to 1 s old see the other direction too.
  double anchor_age = 1.0;
  /// With auto on a recorded sequence, at most this much of its start (s) is tracked by the
  /// calibration pass (readout_calibration.hpp) before the run; 0: no pass. The estimate needs
  /// min_frames turning frames: 1-4 s on the hand-held TUM and Bonn sequences; a start that
  /// does not turn for 10 s costs a pass of 300 frames (about 10 s of CPU) and then gives no
  /// estimate (the run starts from the configured value).
  double calibration_seconds = 10.0;

  std::optional<std::string> check() const;
};

/// One pose inlier of a tracked frame (a map landmark's keypoint with a depth).
struct ReadoutPoint {
  std::uint64_t landmark = 0;
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();  // the keypoint, as compensated
  double depth = 0.0;                            // its depth, as compensated (m)
  double information = 1.0;                      // 1 / sigma^2 of its pyramid level (px^-2)
};

/// What a tracked frame tells about the readout time.
struct ReadoutFrame {
  double timestamp = 0.0;
  SE3 T_c_w;
  /// The compensation its keypoints were built with: angular velocity (rad/s, camera frame) and
  /// readout time (s).
  Eigen::Vector3d omega_used = Eigen::Vector3d::Zero();
  double readout_used = 0.0;
  std::vector<ReadoutPoint> points;
};

/// The 1x1 normal equation of r from one frame (the pose eliminated): h r = -g.
struct ReadoutEquation {
  double h = 0.0;
  double g = 0.0;
  int points = 0;
};

/// How the readout time was found, for summary.json.
struct ReadoutReport {
  bool automatic = false;
  double readout_time = 0.0;  // in use at the end (s)
  double estimate = 0.0;      // the estimate (s), when frames_used > 0
  double std = 0.0;           // its standard deviation (s)
  int frames_used = 0;
  int frames_rejected = 0;
  int epochs = 0;  // epochs completed (each restarted from the estimate before it)
  bool confident = false;
  double confident_at = -1.0;  // timestamp the estimate first became confident (-1: never)
  int frames_used_when_confident = 0;
};

/// The camera's motion at a frame's capture time, as the motion of static points in its frame:
/// p(t) = exp(omega t) p + nu t (rad/s and m/s).
struct CameraTwist {
  Eigen::Vector3d omega = Eigen::Vector3d::Zero();
  Eigen::Vector3d nu = Eigen::Vector3d::Zero();
};

/// Jacobian of the residual e = x(r) - pi(exp(xi) T_b_a p_a(r)) at xi = 0, r = 0 of a keypoint
/// of frame b at row v that sees the anchor's point p_a (camera frame of the anchor frame a).
/// Row v was seen tau = s r after the middle row, s = (v - H/2) / H, when the point was at
/// p + tau (omega x p + nu): x(r) is the keypoint moved back to the middle row's time, and
/// p_a(r) = p_a - s_a r (omega_a x p_a + nu_a) the anchor's point likewise (s_a its row factor).
/// Columns 0-2: the translation and 3-5 the rotation of frame b's left pose perturbation;
/// column 6: the readout r (first order in the motion during the readout, < 0.02 rad, < 3 cm).
Eigen::Matrix<double, 2, 7> readout_jacobian(const PinholeCamera& camera, const SE3& T_b_a,
                                             const Eigen::Vector3d& p_a, double s_a,
                                             const CameraTwist& motion_a, double v,
                                             const CameraTwist& motion);

class ReadoutEstimator {
 public:
  /// Until the estimate is confident, readout_time() is camera.readout_time (the starting value:
  /// 0.02 s in the presets of Kinect-class cameras, 0 when nothing is known).
  ReadoutEstimator(const PinholeCamera& camera, const ReadoutOptions& options);

  /// The normal equation of r from one frame moving with `motion` at its capture time,
  /// linearised around the compensation the frame was built with.
  ReadoutEquation equation(const ReadoutFrame& frame, const CameraTwist& motion,
                           double huber_at) const;

  /// An earlier frame's observations (of landmarks with a depth), as compensated: each
  /// point in that camera's frame and its row factor (v - H/2) / H.
  struct AnchorPoint {
    Eigen::Vector3d p_c = Eigen::Vector3d::Zero();
    double s = 0.0;
    double information = 1.0;
  };
  struct AnchorFrame {
    double timestamp = 0.0;
    SE3 T_c_w;
    CameraTwist motion;
    Eigen::Vector3d omega_used = Eigen::Vector3d::Zero();
    double readout_used = 0.0;
    std::unordered_map<std::uint64_t, AnchorPoint> points;
  };

  /// Adds a tracked frame. Frames must be consecutive tracked frames for the central angular
  /// velocity: the frame is held until the next one arrives. `reset()` after a lost frame.
  void add(ReadoutFrame frame);
  void reset() {
    pending_.reset();
    history_.clear();
  }

  /// The readout time to compensate with now: 0 until the estimate is confident, and then the
  /// estimate when it is significantly non-zero.
  double readout_time() const { return in_use_; }
  ReadoutReport report() const;

 private:
  void accumulate(const ReadoutFrame& frame, const CameraTwist& motion);
  void update();

  PinholeCamera camera_;
  ReadoutOptions options_;
  std::optional<ReadoutFrame> pending_;
  /// The normal equation of r from the frame's landmarks seen in one earlier frame, the pose of
  /// the frame relative to it eliminated.
  ReadoutEquation pair_equation(const ReadoutFrame& frame, const CameraTwist& motion,
                                const AnchorFrame& anchor, double huber_at) const;

  std::deque<AnchorFrame> history_;  // the frames of the last anchor_age seconds, oldest first
  CameraTwist pending_back_;
  std::optional<SE3> last_T_c_w_;
  double last_timestamp_ = 0.0;
  double last_frame_timestamp_ = 0.0;  // of the last frame accumulated
  // Sums over the current epoch's frames: sum h, sum g, sum h * r_k^2 (for the scatter).
  double sum_h_ = 0.0, sum_g_ = 0.0, sum_hrr_ = 0.0;
  int frames_ = 0, rejected_ = 0;
  int epoch_ = 0, epoch_frames_ = 0;  // epochs completed, frames in the current one
  double estimate_ = 0.0, std_ = 0.0;
  double in_use_ = 0.0;
  bool confident_ = false;
  double confident_at_ = -1.0;
  int frames_when_confident_ = 0;
};

}  // namespace mcslam::slam
