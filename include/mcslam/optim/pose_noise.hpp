#pragma once
// The noise a sequence of tracked poses shows, against the covariance their optimiser gives.
//
// The pose optimiser's covariance counts the keypoints' own noise (1 pixel at a keypoint's
// level, independent from point to point). A frame's error that is common to all its keypoints
// is not in it: the angular velocity its rolling shutter was corrected with, its timestamp, the
// map points it was solved against. Measured on the handheld sequences at hand, a frame's pose
// is off by several times the optimiser's sigma in the directions the frame fixes well, while
// the noise-free renders stay within it.
//
// A camera, a body with mass, moves smoothly: over four frames at 30 Hz its path is a quadratic
// in time to within jerk * dt^3 (0.3 mm for the render accelerating at 2.4 m/s^2, 2.4 mm for
// freiburg1_rpy's ground truth, against 16 mm for its tracked poses), so the third difference of
// four consecutive poses is their noise alone: for independent noise of covariance C per pose,
// the difference sum_i a_i x_i (the third divided difference, for any spacing of the
// timestamps) has covariance (sum_i a_i^2) C. Normalised by the optimiser's covariance, its
// squared norm follows chi-square with 6 degrees of freedom when the optimiser is right, and
// that times the factor by which it understates the noise when it is not. The median over a
// window, divided by chi-square's median (5.35), estimates that factor; the median, because a
// few frames far off (a blurred frame, a jump of the map) would lift a mean.

#include <Eigen/Core>
#include <deque>
#include <optional>
#include <utility>

#include "mcslam/core/se3.hpp"

namespace mcslam::optim {

class PoseNoiseEstimate {
 public:
  /// `window`: the seconds of third differences whose median gives the estimate.
  explicit PoseNoiseEstimate(double window = 1.0);

  /// Adds a pose (rotation R_c_w, camera centre c in the world) and its information on the
  /// centre and the rotation's left perturbation (y = [dc; dtheta], theta in the camera frame).
  void add(double timestamp, const Eigen::Matrix3d& R_c_w, const Eigen::Vector3d& c,
           const Matrix6d& information);

  /// The next pose does not continue the last one (a gap, a relocalisation): the differences
  /// start again; the values measured so far stay (the noise is the camera's and the scene's).
  void break_sequence() { poses_.clear(); }

  /// The map moved under the tracker: W maps positions of the old world to the new one. The
  /// poses kept for the differences move with it, so that a move of the map is not taken for
  /// the frames' noise.
  void move_world(const SE3& W);

  /// The factor by which the optimiser's covariance understates the poses' noise: the median of
  /// the normalised third differences in the window over chi-square's median (6 dof); 1 before
  /// `kMinValues` of them.
  double variance_factor() const;

  /// The number of normalised differences in the window.
  std::size_t values() const { return values_.size(); }

  static constexpr std::size_t kMinValues = 5;

 private:
  struct Pose {
    double timestamp;
    Eigen::Matrix3d R_c_w;
    Eigen::Vector3d c;
    Matrix6d information;
  };
  double window_;
  std::deque<Pose> poses_;                        // the last four
  std::deque<std::pair<double, double>> values_;  // (timestamp, normalised difference)
};

/// The coefficients a_i of the third divided difference of values at the four times t, scaled
/// so that equally spaced times give (-1, 3, -3, 1): sum_i a_i f(t_i) is 0 for any quadratic f.
std::optional<Eigen::Vector4d> third_difference_coefficients(const Eigen::Vector4d& t);

}  // namespace mcslam::optim
