#include "mcslam/optim/pose_smoother.hpp"

#include <Eigen/Dense>

namespace mcslam::optim {

PoseSmoother::PoseSmoother(int lag) : lag_(lag < 1 ? 1 : lag) {}

std::vector<PoseFilterState> PoseSmoother::smoothed() const {
  std::vector<PoseFilterState> out(window_.size());
  if (window_.empty()) return out;
  std::size_t j = window_.size() - 1;
  out[j] = window_[j].filtered;
  while (j > 0) {
    --j;
    const PoseFilterStep& next = window_[j + 1];
    const PoseFilterState& x = window_[j].filtered;
    if (next.restarted) {
      out[j] = x;  // not linked: a chain of its own ends here
      continue;
    }
    // G = P F^T (P^-)^-1; P and P^- are symmetric, so G^T = (P^-)^-1 F P.
    const Matrix12d G = next.predicted.P.ldlt().solve(next.F * x.P).transpose();
    out[j] = x.plus(G * out[j + 1].minus(next.predicted));
  }
  return out;
}

std::optional<LaggedPose> PoseSmoother::add(const PoseFilterStep& step) {
  window_.push_back(step);
  if (window_.size() <= static_cast<std::size_t>(lag_)) return std::nullopt;
  const std::vector<PoseFilterState> s = smoothed();
  LaggedPose out{window_.front().timestamp, s.front().T_c_w()};
  window_.pop_front();
  return out;
}

std::optional<LaggedPose> PoseSmoother::add_unfiltered(double timestamp, const SE3& T_c_w) {
  PoseFilterStep step;
  step.timestamp = timestamp;
  step.restarted = true;
  step.filtered.R = T_c_w.rotation();
  step.filtered.c = -(step.filtered.R.transpose() * T_c_w.translation());
  step.predicted = step.filtered;
  return add(step);
}

std::vector<LaggedPose> PoseSmoother::flush() {
  const std::vector<PoseFilterState> s = smoothed();
  std::vector<LaggedPose> out;
  out.reserve(window_.size());
  for (std::size_t j = 0; j < window_.size(); ++j)
    out.push_back({window_[j].timestamp, s[j].T_c_w()});
  window_.clear();
  return out;
}

void PoseSmoother::move_world(const SE3& W) {
  for (PoseFilterStep& step : window_) {
    step.predicted.move_world(W);
    step.filtered.move_world(W);
  }
}

}  // namespace mcslam::optim
