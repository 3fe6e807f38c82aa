#pragma once
// Smoothing of a finished run's camera positions with a motion prior.
//
// Each frame's pose is estimated from that frame's observations alone, and its position carries
// a noise of a few millimetres from frame to frame (freiburg1_rpy: 2.5 mm per axis, Bonn crowd:
// 3-4 mm; the ground truth's second differences are 10-30x smaller than the estimate's), while
// a camera is a body whose velocity changes smoothly. The smoother finds the positions p_i that
// minimise
//   sum_i w_i |p_i - y_i|^2 / sigma^2  +  sum_i |dv_i|^2 / (q * dt_i),
// where y_i are the estimated positions, dv_i the change of velocity between the intervals
// before and after frame i (dt_i their mean length), q the spectral density of the camera's
// acceleration (white-noise-acceleration model: the velocity is a random walk, Var(dv) = q dt
// per axis) and sigma the positions' noise per axis, estimated from the trajectory's own second
// differences. It is the maximum a posteriori path of that model (a Rauch-Tung-Striebel
// smoother's result), solved as one banded linear system per axis. The weights w_i (Huber)
// let a pose far from the smooth path count less, so that a few frames pulled off by movers
// do not bend the path around them. Rotations are left as estimated: their second differences
// are those of the ground truth (0.67 against 0.49 degrees on freiburg1_rpy, 0.37 against
// 0.40 on Bonn crowd part 1).

#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/trajectory.hpp"

namespace mcslam::optim {

struct TrajectorySmoothingOptions {
  /// Smooth the positions of the final trajectory (off: the poses as tracked, corrected by the
  /// map's keyframes).
  bool enabled = true;
  /// q, the spectral density of the camera's acceleration per axis (m^2/s^3). The ground truth
  /// of the two handheld sequences at hand measures 0.006 (freiburg1_rpy) and 0.003 (Bonn crowd
  /// part 1, 30 Hz); 0.01 lets the path follow motions a little livelier than both. Smaller
  /// smooths more; ATE changes by less than 10 % between 0.003 and 0.03 (docs/crowd.md).
  double acceleration_density = 0.01;
  /// A pose further than this many noise sigmas (per axis) from the smoothed path is given the
  /// weight of a pose at that distance (Huber). At 3, 3 % of the poses of a Gaussian trajectory
  /// (chi-square with 3 degrees of freedom above 9) are down-weighted, and only slightly.
  double outlier_sigmas = 3.0;
  /// A longer time without a pose (tracking lost), or a timestamp that does not increase,
  /// starts a new segment, smoothed on its own: across a second the motion model leaves the
  /// path free by sqrt(q / 3) ~ 6 cm, so joining the segments would add nothing.
  double max_gap = 1.0;
  /// Reweighting rounds (each one solve per segment).
  int iterations = 5;

  std::optional<std::string> check() const;
};

struct TrajectorySmoothingReport {
  /// False when smoothing is off or the trajectory is too short to estimate its noise.
  bool applied = false;
  /// The positions' estimated noise per axis (metres).
  double position_noise = 0.0;
  int segments = 0;
  /// Poses beyond outlier_sigmas from the smoothed path after the last round.
  int downweighted = 0;
  /// RMS of the change of position (metres).
  double rms_change = 0.0;
};

/// The trajectory with its positions smoothed (rotations and timestamps unchanged); the input
/// as it is when options.enabled is false or fewer than kMinSecondDifferences second
/// differences can be formed. `breaks`: indices of poses that start a new segment besides those
/// after a gap (e.g. the first pose after tracking was lost: the poses before and after a
/// relocalisation are not one continuous estimate). Throws InputError when options.check()
/// fails.
Trajectory smooth_trajectory(const Trajectory& trajectory,
                             const TrajectorySmoothingOptions& options,
                             TrajectorySmoothingReport* report = nullptr,
                             const std::vector<std::size_t>& breaks = {});

/// Second differences needed to estimate the positions' noise.
inline constexpr int kMinSecondDifferences = 10;

}  // namespace mcslam::optim
