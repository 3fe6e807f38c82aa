#pragma once
// A causal filter on the tracked camera pose: the white-noise-acceleration motion model of the
// final trajectory's smoothing (trajectory_smoothing.hpp), applied frame by frame to the whole
// pose, rotation and position together.
//
// Each frame's pose is estimated from that frame's observations alone. Where the scene leaves a
// direction weakly determined (a small rotation about the image's vertical axis and a sideways
// shift of the camera move the image alike; only depth and the scene's depth range tell them
// apart), the estimate wanders along it from frame to frame by several millimetres, while the
// camera, a body with mass, moved smoothly. The filter keeps the camera centre c and velocity v
// (world frame) and the rotation R_c_w and angular velocity w (camera frame), and fuses each
// frame's pose with the prediction of the motion model, weighted by the pose's information
// matrix (the pose optimiser's J^T W J): a direction the observations fix well follows them, a
// direction they leave loose follows the motion. It is the Kalman filter of that model, on an
// error state:
//   x = [dc, dv, dtheta, dw],   c = c^ + dc,  R_c_w = exp(dtheta) R^,
// predicted over dt as c + v dt, exp(w dt) R with process noise from the spectral densities of
// the acceleration (q_p, m^2/s^3) and the angular acceleration (q_r, rad^2/s^3):
//   Var over dt of (position, velocity) per axis = q [dt^3/3, dt^2/2; dt^2/2, dt].
// A measurement the model explains poorly (normalised innovation squared above chi-square's 95 %
// point) counts less (Huber); one it cannot explain at all (above a gate) is held (the prediction
// given out) and, if the next is beyond the gate too, the pose restarts at that one with the
// velocities the two measurements give (a jump or a change of motion the model cannot follow:
// the velocities before are what failed); so does a frame beyond the gate before the frames'
// noise is known, at once. A jump the map's own move explains keeps the velocities. The tracker
// resets the filter after a relocalisation; small corrections of the map reach the pose through
// the measurements.

#include <Eigen/Core>
#include <optional>
#include <string>

#include "mcslam/core/se3.hpp"
#include "mcslam/optim/pose_noise.hpp"

namespace mcslam::optim {

struct PoseFilterOptions {
  /// On (the default): the pose given out is the frame's own pose fused with the motion model,
  /// with no lag. Default threaded runs with yolov8n_320, medians of 6 against 3 off: online RPE
  /// over one frame Bonn crowd part 1 9.7 -> 3.1 mm, from its frame 240 12.4 -> 4.4 mm,
  /// freiburg1_rpy 6.3 -> 3.1 mm (docs/tracking.md has the online ATE); the renders
  /// (`--sequential`) 1.6-3.8 -> 0.9-1.7 mm and their online ATE within 0.1 mm, but for a camera
  /// accelerating at 2.4 m/s^2 RMS (2.5 times the usual speed: 3.3 -> 3.5 mm).
  /// Off: each frame's own pose (docs/tracking.md).
  bool enabled = true;
  /// q_p, spectral density of the camera centre's acceleration per axis (m^2/s^3). The ground
  /// truth of the handheld sequences at hand measures 0.006 (freiburg1_rpy) and 0.003 (Bonn crowd
  /// part 1); 0.01 lets the camera move a little livelier than both (the final smoothing's value).
  double acceleration_density = 0.01;
  /// q_r, spectral density of the angular acceleration per axis (rad^2/s^3): handheld
  /// freiburg1_rpy's ground truth measures about 1 (its rolls and pitches reach 1.5 rad/s in a
  /// second); 3 lets the camera turn a little livelier than that.
  double angular_acceleration_density = 3.0;
  /// The measurement's covariance is the pose optimiser's (1 pixel at the keypoint's level), times
  /// the measured factor of `noise_window`, times this factor squared: 1, the measured noise.
  /// Larger factors smooth more than the frames' noise asks, which a camera that accelerates pays
  /// for in lag.
  double measurement_noise_scale = 1.0;
  /// Seconds of the poses' own third differences (pose_noise.hpp) from which the filter measures
  /// how far the optimiser's covariance understates a frame's noise; the covariance is multiplied
  /// by that factor where it is above 1 (never below: the optimiser's covariance is what the
  /// keypoints' noise alone gives). The handheld sequences' frames are off by an error common to
  /// their keypoints that the optimiser does not count (the factor's median over a run,
  /// `--sequential`: freiburg1_rpy 85, Bonn crowd part 1 9, from its frame 240 5.5); the renders'
  /// keypoints are more precise than the optimiser's 1 pixel (factors 0.2-0.5, held at 1). One
  /// second holds 30 differences at 30 Hz: the median's relative error is then about 0.14, and
  /// the noise changes with the scene over seconds. Measured against 0 (the optimiser's
  /// covariance as it is; default threaded, medians of 6 side by side): online RPE over one
  /// frame freiburg1_rpy 5.9 -> 3.1 mm, Bonn crowd part 1 4.8 -> 3.1, from frame 240 6.2 -> 4.4,
  /// `--realtime` 4.6 -> 3.0; online ATE within the runs' spread (docs/tracking.md).
  double noise_window = 1.0;
  /// Normalised innovation squared (6 dof) above which a measurement counts less (Huber): its
  /// information is multiplied by sqrt(downweight_chi2 / nis). 12.59 is chi-square's 95 % point:
  /// a frame the model explains keeps its weight, one whose pose is off (a blurred frame, a
  /// subset of map points that drags it) moves the filtered pose as far as a 3.5-sigma frame
  /// would. On freiburg1_rpy and Bonn crowd part 1 this replaces most restarts (below).
  double downweight_chi2 = 12.59;
  /// Normalised innovation squared (6 dof) beyond which a measurement is not noise: a jump (a
  /// loop closure's correction of the map), at which the filter restarts, or the frame's own
  /// failure, which it holds (held_frames). A consistent filter exceeds 50 once in 2e8 frames
  /// (chi-square, 6 dof); `--sequential`, freiburg1_rpy's frames exceed 12.59 at 6 of 692 and 50
  /// at 5, in its first 8 frames, before their noise is measured (noise_window; until then the
  /// gate restarts at once), Bonn crowd part 1's 12.59 at 2 of 458 and 50 at none.
  double gate_chi2 = 50.0;
  /// Frames beyond the gate in a row for which the filter gives out its prediction (the frame
  /// counts for nothing) before it restarts at the measurement. A camera cannot jump: a
  /// correction of the map (a loop closure's) moves every frame after it alike, while one frame's
  /// own failure (a person dragging its pose, a blur) is gone at the next. 1 tells the two apart
  /// at the cost of one frame (33 ms at 30 Hz) of latency on a jump; 0 restarts at once. A jump
  /// the map's own move explains (move_world since the frame before: the measurement, taken back
  /// to the world before the move, is within the gate) restarts at once.
  int held_frames = 1;
  /// false (the default): when bundle adjustment or a loop correction moves the map under the
  /// tracker, the filter keeps its state; the correction reaches the pose through the next
  /// frames' measurements, at the rate the motion model allows, or at once when it is beyond the
  /// gate (a loop closure). Local bundle adjustment moves the map by 5 mm (median, p90 12 mm,
  /// 113 times in Bonn crowd part 1's 460 frames): followed at once, those moves are jumps of the
  /// pose that the camera never made (`--sequential`, online RPE over one frame 4.5 against
  /// 3.2 mm not following). true: the state moves with the map (the pose jumps with it).
  bool follow_map = false;
  /// A longer time between two measurements restarts the filter (seconds).
  double max_gap = 0.5;
  /// Adaptive densities (covariance matching): the recent mean of the normalised innovation
  /// squared, averaged over this many seconds, against the 6 a consistent filter gives; when the
  /// camera moves livelier than the densities allow (the mean above 6), both densities are
  /// multiplied by (mean / 6)^(dt / adaptive_memory) at each frame until it is 6 again, never
  /// below the settings' values: by the ratio over one memory's time. 0: fixed.
  double adaptive_memory = 0.5;
  /// The most the densities may be multiplied by.
  double max_liveliness = 1000.0;
  /// Frames the lagged pose (pose_smoother.hpp) stays behind the newest: each frame's pose is
  /// smoothed with the `lag` frames after it (Rauch-Tung-Striebel over the filter's states) and
  /// given out when the last of them has come, `lag` frame intervals late (at 30 Hz, 33 ms each).
  /// 0 (the default): no lagged pose; the immediate pose is given either way. Needs `enabled`.
  int lag = 0;

  std::optional<std::string> check() const;
};

using Matrix12d = Eigen::Matrix<double, 12, 12>;
using Vector12d = Eigen::Matrix<double, 12, 1>;

/// The filter's state: the camera centre c and velocity v (world), the rotation R_c_w and the
/// angular velocity w (camera frame), and the covariance P of the error state
/// [dc, dv, dtheta, dw] (c = c^ + dc, R_c_w = exp(dtheta) R^).
struct PoseFilterState {
  /// The error state's blocks: centre, velocity, rotation, angular velocity.
  static constexpr int kC = 0, kV = 3, kTheta = 6, kW = 9;

  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d w = Eigen::Vector3d::Zero();
  Matrix12d P = Matrix12d::Identity();

  SE3 T_c_w() const;
  /// This state moved by the error d (x (+) d): c + dc, v + dv, exp(dtheta) R, w + dw.
  PoseFilterState plus(const Vector12d& d) const;
  /// The error that moves b to this state (this (-) b).
  Vector12d minus(const PoseFilterState& b) const;
  /// The state in a world moved by W (positions of the old world to the new one).
  void move_world(const SE3& W);
};

/// One update as a smoother needs it: the prediction from the state before, its transition
/// matrix F (on the error state), and the state after.
struct PoseFilterStep {
  double timestamp = 0.0;
  bool restarted = false;  ///< not linked to the step before: the state was set afresh
  PoseFilterState predicted;
  Matrix12d F = Matrix12d::Identity();
  PoseFilterState filtered;
};

/// What the filter made of a measurement.
enum class FilterOutcome {
  kOff,           ///< the filter is off: the measurement as it is
  kFused,         ///< fused with the prediction
  kDownweighted,  ///< fused, counting less (beyond downweight_chi2)
  kHeld,          ///< beyond the gate, not yet a jump (held_frames): the prediction given out
  kRestarted,     ///< the state set to the measurement (a start, a gap, a jump)
};

/// The outcome's name in summary.json ("off", "fused", "downweighted", "held", "restarted").
const char* to_string(FilterOutcome outcome);

/// What the filter did with one measurement.
struct PoseFilterUpdate {
  SE3 T_c_w;         ///< the filtered pose
  double nis = 0.0;  ///< normalised innovation squared (0 on a start)
  FilterOutcome outcome = FilterOutcome::kOff;
  /// The update's states (with the filter enabled).
  std::optional<PoseFilterStep> step;

  bool restarted() const { return outcome == FilterOutcome::kRestarted; }
  bool held() const { return outcome == FilterOutcome::kHeld; }
};

class PoseFilter {
 public:
  explicit PoseFilter(const PoseFilterOptions& options = {});

  /// Fuses the pose T_c_w measured at `timestamp` with the prediction. `information` is the
  /// measurement's information matrix on the tangent of se3_manifold.hpp (xi = [rho; phi],
  /// T' = exp(xi) T_c_w); it may be singular (a direction the frame does not observe).
  PoseFilterUpdate update(double timestamp, const SE3& T_c_w, const Matrix6d& information);

  /// Forgets the state (tracking lost): the next measurement starts the filter again.
  void reset() { started_ = false; }

  /// The map moved under the tracker (bundle adjustment, a loop correction): W maps positions of
  /// the old world to the new one; the state follows it with `follow_map`, and otherwise stays
  /// (the next measurements bring the correction).
  void move_world(const SE3& W);

  bool started() const { return started_; }
  /// The camera's angular velocity (camera frame, rad/s) as the filter has it, once it has one:
  /// from the first measurement fused after a fresh start on (a restart that keeps the
  /// velocities keeps it).
  std::optional<Eigen::Vector3d> angular_velocity() const {
    return started_ && has_velocity_ ? std::optional<Eigen::Vector3d>(x_.w) : std::nullopt;
  }
  /// The factor the densities are multiplied by now (adaptive_memory; 1: the settings').
  double liveliness() const { return liveliness_; }
  /// The factor the measurements' covariance is multiplied by now (measurement_noise_scale^2
  /// times the measured factor of noise_window, at least 1).
  double measurement_variance_factor() const;

 private:
  void restart(double timestamp, const SE3& T_c_w, const Matrix6d& information,
               bool keep_velocities);
  /// Moves the state over dt; returns the transition matrix of the error state.
  Matrix12d predict(double dt);
  void adapt(double dt, double nis);
  /// The measurement's centre and rotation against the state's ([dc; dtheta]).
  Vector6d innovation(const SE3& T_c_w) const;
  /// Whether a measurement beyond the gate is held (held_frames) rather than restarted at.
  bool holds(const SE3& T_c_w, double nis, const Matrix6d& S_inv, bool& map_jump);
  struct Measurement {
    double timestamp = 0.0;
    SE3 T_c_w;
    Matrix6d information = Matrix6d::Zero();
  };
  /// After a restart at T_c_w whose velocities failed: the velocities from the frame before's
  /// measurement to this one, with their covariance.
  void velocities_between(const Measurement& before, const SE3& T_c_w, const Matrix6d& information,
                          double timestamp);
  PoseFilterUpdate restarted_at(double timestamp, const SE3& T_c_w, double nis);
  /// The covariance of a measurement on [dc; dtheta] at the measured noise, a direction it leaves
  /// free held at 1 m and 1 rad.
  Matrix6d measurement_covariance(const Matrix6d& information, const Eigen::Matrix3d& R_c_w) const;
  /// Whether the frames' noise is measured (noise_window) or not asked for.
  bool noise_known() const;

  PoseFilterOptions options_;
  bool started_ = false;
  double timestamp_ = 0.0;
  PoseFilterState x_;
  double liveliness_ = 1.0;       // the densities' multiplier
  double mean_nis_ = 6.0;         // the recent innovations' mean
  int held_ = 0;                  // frames beyond the gate in a row, held (held_frames)
  bool has_velocity_ = false;     // a measurement was fused since the last fresh start
  std::optional<SE3> map_moved_;  // the map's moves since the last measurement (not followed)
  std::optional<Measurement> last_measurement_;  // the last frame's own pose
  PoseNoiseEstimate noise_;                      // the measurements' noise against their covariance
};

}  // namespace mcslam::optim
