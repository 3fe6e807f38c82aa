#pragma once
// The lagged pose: each frame's pose smoothed with the frames after it, given out `lag` frames
// late (a fixed-lag smoother over the pose filter of pose_filter.hpp).
//
// The filter's pose at frame k uses the frames up to k; the frames after k tell more about it
// (where the camera went next says where it was). The smoother keeps the filter's last lag + 1
// steps and runs the Rauch-Tung-Striebel recursion backwards over them each frame, on the error
// state of the filter:
//   G_j = P_j F_{j+1}^T (P^-_{j+1})^-1,   x^s_j = x_j (+) G_j (x^s_{j+1} (-) x^-_{j+1}),
// with x_j, P_j the filtered state, x^-_{j+1}, P^-_{j+1} the prediction of the next step and
// F_{j+1} its transition; (+) and (-) add and subtract on the centre, the velocities and, for
// the rotation, exp(dtheta) R. The pose lag frames back is then given out. A step where the
// filter restarted is not linked to the one before: the recursion starts afresh there, so that a
// relocalisation's jump is not smoothed into the poses before it. Only the mean is smoothed (no
// smoothed covariance is needed for the pose).

#include <deque>
#include <optional>
#include <vector>

#include "mcslam/core/se3.hpp"
#include "mcslam/optim/pose_filter.hpp"

namespace mcslam::optim {

struct LaggedPose {
  double timestamp = 0.0;  ///< the frame's own time (lag frames before the newest)
  SE3 T_c_w;
};

class PoseSmoother {
 public:
  /// lag >= 1 frames (PoseFilterOptions::lag).
  explicit PoseSmoother(int lag);

  /// Adds the filter's newest step; returns the smoothed pose of the step lag steps back, once
  /// there is one.
  std::optional<LaggedPose> add(const PoseFilterStep& step);

  /// A pose the filter did not see (the map's first frame): held and given out as it is, the
  /// recursion starting afresh after it.
  std::optional<LaggedPose> add_unfiltered(double timestamp, const SE3& T_c_w);

  /// The poses still held (the last lag steps), smoothed with what came: the end of a run.
  std::vector<LaggedPose> flush();

  /// The map moved under the tracker and the filter moved with it (PoseFilterOptions::
  /// follow_map): the held states move too.
  void move_world(const SE3& W);

 private:
  /// The smoothed states of the held steps, oldest first.
  std::vector<PoseFilterState> smoothed() const;

  int lag_;
  std::deque<PoseFilterStep> window_;
};

}  // namespace mcslam::optim
