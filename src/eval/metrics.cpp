#include "mcslam/eval/metrics.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <numeric>

#include "mcslam/core/error.hpp"

namespace mcslam::eval {
namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

std::string format_number(const char* fmt, double value) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), fmt, value);
  return buf;
}

// Index of the element of the sorted list `values` closest to `target`; ties go to the earlier
// index. `values` must not be empty.
std::size_t closest_index(const std::vector<double>& values, double target) {
  const auto it = std::lower_bound(values.begin(), values.end(), target);
  if (it == values.begin()) return 0;
  if (it == values.end()) return values.size() - 1;
  const auto hi = static_cast<std::size_t>(it - values.begin());
  const std::size_t lo = hi - 1;
  return (target - values[lo] <= values[hi] - target) ? lo : hi;
}

// RPE over index pairs (i, j) into the associated gt / est pose lists.
RpeResult relative_errors(const std::vector<SE3>& gt, const std::vector<SE3>& est,
                          const std::vector<std::pair<std::size_t, std::size_t>>& pairs,
                          std::string delta) {
  std::vector<double> trans, rot;
  trans.reserve(pairs.size());
  rot.reserve(pairs.size());
  for (const auto& [i, j] : pairs) {
    const SE3 gt_rel = gt[i].inverse() * gt[j];
    const SE3 est_rel = est[i].inverse() * est[j];
    const SE3 E = gt_rel.inverse() * est_rel;
    trans.push_back(E.translation().norm());
    rot.push_back(rotation_angle(E.quaternion()));
  }
  RpeResult result;
  result.translation = compute_error_stats(trans);
  result.rotation = compute_error_stats(rot);
  result.delta = std::move(delta);
  return result;
}

std::pair<double, double> time_span(const Trajectory& trajectory) {
  const auto [lo, hi] = std::minmax_element(
      trajectory.begin(), trajectory.end(),
      [](const StampedPose& a, const StampedPose& b) { return a.timestamp < b.timestamp; });
  return {lo->timestamp, hi->timestamp};
}

void check_trajectory(const Trajectory& trajectory, const char* name) {
  if (trajectory.empty()) {
    throw InputError(std::string("evaluate: the ") + name + " trajectory is empty");
  }
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    if (!std::isfinite(trajectory[i].timestamp)) {
      throw InputError(std::string("evaluate: the ") + name + " trajectory has a non-finite " +
                       "timestamp at pose " + std::to_string(i));
    }
  }
}

void add_stats(nlohmann::json& j, const std::string& prefix, const ErrorStats& s,
               const std::string& unit, double unit_scale) {
  j[prefix + "_rmse_" + unit] = s.rmse * unit_scale;
  j[prefix + "_mean_" + unit] = s.mean * unit_scale;
  j[prefix + "_median_" + unit] = s.median * unit_scale;
  j[prefix + "_std_" + unit] = s.std * unit_scale;
  j[prefix + "_min_" + unit] = s.min * unit_scale;
  j[prefix + "_max_" + unit] = s.max * unit_scale;
}

void add_rpe(nlohmann::json& j, const std::string& prefix, const RpeResult& rpe) {
  j[prefix + "_delta"] = rpe.delta;
  j[prefix + "_count"] = rpe.translation.count;
  add_stats(j, prefix + "_trans", rpe.translation, "m", 1.0);
  add_stats(j, prefix + "_rot", rpe.rotation, "rad", 1.0);
  add_stats(j, prefix + "_rot", rpe.rotation, "deg", kRadToDeg);
}

std::string rpe_line(const RpeResult& rpe) {
  char buf[256];
  if (rpe.translation.count == 0) {
    std::snprintf(buf, sizeof(buf), "RPE %-9s  n/a (no pose pair at this delta)\n",
                  rpe.delta.c_str());
  } else {
    std::snprintf(buf, sizeof(buf),
                  "RPE %-9s  trans rmse %.4f m  mean %.4f m  max %.4f m | rot rmse %.5f rad "
                  "(%.3f deg)  mean %.5f rad  max %.5f rad  [%zu pairs]\n",
                  rpe.delta.c_str(), rpe.translation.rmse, rpe.translation.mean,
                  rpe.translation.max, rpe.rotation.rmse, rpe.rotation.rmse * kRadToDeg,
                  rpe.rotation.mean, rpe.rotation.max, rpe.translation.count);
  }
  return buf;
}

}  // namespace

ErrorStats compute_error_stats(const std::vector<double>& errors) {
  ErrorStats s;
  s.count = errors.size();
  if (errors.empty()) return s;
  const auto n = static_cast<double>(errors.size());
  double sum = 0.0, sum_sq = 0.0;
  for (const double e : errors) {
    sum += e;
    sum_sq += e * e;
  }
  s.mean = sum / n;
  s.rmse = std::sqrt(sum_sq / n);
  double var = 0.0;  // two-pass for accuracy
  for (const double e : errors) var += (e - s.mean) * (e - s.mean);
  s.std = std::sqrt(var / n);
  std::vector<double> sorted = errors;
  std::sort(sorted.begin(), sorted.end());
  s.min = sorted.front();
  s.max = sorted.back();
  const std::size_t mid = sorted.size() / 2;
  s.median = (sorted.size() % 2 == 1) ? sorted[mid] : 0.5 * (sorted[mid - 1] + sorted[mid]);
  return s;
}

std::vector<std::pair<std::size_t, std::size_t>> associate(const Trajectory& gt,
                                                           const Trajectory& est, double max_dt) {
  if (!(max_dt > 0.0) || !std::isfinite(max_dt)) {
    throw InputError("associate: max_dt must be a positive finite number of seconds, got " +
                     format_number("%g", max_dt));
  }
  // gt indices in timestamp order, so candidates can be found by binary search instead of
  // testing all gt x est combinations as associate.py does (same candidate set).
  std::vector<std::size_t> gt_order(gt.size());
  std::iota(gt_order.begin(), gt_order.end(), std::size_t{0});
  std::stable_sort(gt_order.begin(), gt_order.end(),
                   [&](std::size_t a, std::size_t b) { return gt[a].timestamp < gt[b].timestamp; });
  std::vector<double> gt_times(gt.size());
  for (std::size_t k = 0; k < gt.size(); ++k) gt_times[k] = gt[gt_order[k]].timestamp;

  struct Candidate {
    double dt;
    std::size_t gt, est;
  };
  std::vector<Candidate> candidates;
  for (std::size_t e = 0; e < est.size(); ++e) {
    const double t = est[e].timestamp;
    // Scan a window twice as wide as needed so rounding in t +- max_dt cannot drop a candidate;
    // the exact associate.py test below decides.
    auto it = std::lower_bound(gt_times.begin(), gt_times.end(), t - 2.0 * max_dt);
    for (; it != gt_times.end() && *it <= t + 2.0 * max_dt; ++it) {
      const double dt = std::abs(*it - t);
      if (dt < max_dt) {
        candidates.push_back({dt, gt_order[static_cast<std::size_t>(it - gt_times.begin())], e});
      }
    }
  }
  // associate.py sorts (|dt|, t_gt, t_est) tuples; indices break any remaining ties.
  std::sort(candidates.begin(), candidates.end(), [&](const Candidate& a, const Candidate& b) {
    if (a.dt != b.dt) return a.dt < b.dt;
    if (gt[a.gt].timestamp != gt[b.gt].timestamp) return gt[a.gt].timestamp < gt[b.gt].timestamp;
    if (est[a.est].timestamp != est[b.est].timestamp) {
      return est[a.est].timestamp < est[b.est].timestamp;
    }
    return a.gt != b.gt ? a.gt < b.gt : a.est < b.est;
  });

  std::vector<bool> gt_used(gt.size(), false), est_used(est.size(), false);
  std::vector<std::pair<std::size_t, std::size_t>> matches;
  for (const Candidate& c : candidates) {
    if (gt_used[c.gt] || est_used[c.est]) continue;
    gt_used[c.gt] = true;
    est_used[c.est] = true;
    matches.emplace_back(c.gt, c.est);
  }
  std::sort(matches.begin(), matches.end(), [&](const auto& a, const auto& b) {
    if (est[a.second].timestamp != est[b.second].timestamp) {
      return est[a.second].timestamp < est[b.second].timestamp;
    }
    return a.second < b.second;
  });
  return matches;
}

SE3 align_se3(const std::vector<Eigen::Vector3d>& est_positions,
              const std::vector<Eigen::Vector3d>& gt_positions) {
  if (est_positions.size() != gt_positions.size()) {
    throw InputError("align_se3: " + std::to_string(est_positions.size()) +
                     " estimated positions but " + std::to_string(gt_positions.size()) +
                     " ground-truth positions");
  }
  const std::size_t n = est_positions.size();
  if (n == 0) return SE3::identity();

  Eigen::Vector3d mu_est = Eigen::Vector3d::Zero(), mu_gt = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    mu_est += est_positions[i];
    mu_gt += gt_positions[i];
  }
  mu_est /= static_cast<double>(n);
  mu_gt /= static_cast<double>(n);
  if (n < 3) return SE3(Eigen::Matrix3d::Identity(), Eigen::Vector3d(mu_gt - mu_est));

  // W = sum (gt_i - mu_gt)(est_i - mu_est)^T; the rotation maximising trace(R^T W) is
  // U diag(1, 1, s) V^T with s = det(U V^T) so that det(R) = +1.
  Eigen::Matrix3d W = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    W += (gt_positions[i] - mu_gt) * (est_positions[i] - mu_est).transpose();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(W, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d& U = svd.matrixU();
  const Eigen::Matrix3d& V = svd.matrixV();
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if (U.determinant() * V.determinant() < 0.0) S(2, 2) = -1.0;
  const Eigen::Matrix3d R = U * S * V.transpose();
  return SE3(R, Eigen::Vector3d(mu_gt - R * mu_est));
}

std::optional<std::string> EvalOptions::check() const {
  if (!(max_time_difference > 0.0) || !std::isfinite(max_time_difference)) {
    return "max_time_difference must be a positive number of seconds, got " +
           format_number("%g", max_time_difference);
  }
  if (rpe_delta_frames < 1) {
    return "rpe_delta_frames must be at least 1, got " + std::to_string(rpe_delta_frames);
  }
  if (!(rpe_delta_seconds > 0.0) || !std::isfinite(rpe_delta_seconds)) {
    return "rpe_delta_seconds must be a positive number of seconds, got " +
           format_number("%g", rpe_delta_seconds);
  }
  return std::nullopt;
}

EvalReport evaluate(const Trajectory& gt, const Trajectory& est, const EvalOptions& options) {
  if (const auto problem = options.check()) {
    throw InputError("evaluate: invalid options: " + *problem);
  }
  check_trajectory(gt, "ground-truth");
  check_trajectory(est, "estimated");

  const auto [gt_begin, gt_end] = time_span(gt);
  const auto [est_begin, est_end] = time_span(est);

  const auto matches = associate(gt, est, options.max_time_difference);
  if (matches.empty()) {
    throw InputError("evaluate: no estimated pose lies within " +
                     format_number("%g", options.max_time_difference) +
                     " s of a ground-truth pose (ground truth spans " +
                     format_number("%.6f", gt_begin) + " .. " + format_number("%.6f", gt_end) +
                     " s, estimate spans " + format_number("%.6f", est_begin) + " .. " +
                     format_number("%.6f", est_end) +
                     " s); check that both use the same clock and timestamp unit (seconds)");
  }

  EvalReport report;
  report.gt_poses = gt.size();
  report.est_poses = est.size();
  report.matched = matches.size();
  report.coverage = static_cast<double>(matches.size()) / static_cast<double>(est.size());
  report.gt_duration = gt_end - gt_begin;
  report.est_duration = est_end - est_begin;

  // Associated poses in est time order.
  const std::size_t m = matches.size();
  std::vector<SE3> gt_poses(m), est_poses(m);
  std::vector<Eigen::Vector3d> gt_positions(m), est_positions(m);
  std::vector<double> stamps(m);
  for (std::size_t k = 0; k < m; ++k) {
    gt_poses[k] = gt[matches[k].first].T_w_c;
    est_poses[k] = est[matches[k].second].T_w_c;
    gt_positions[k] = gt_poses[k].translation();
    est_positions[k] = est_poses[k].translation();
    stamps[k] = est[matches[k].second].timestamp;
  }

  // ATE (evaluate_ate.py): rigid alignment of the associated positions, then per-pose error.
  AteResult& ate = report.ate;
  ate.T_gt_est = align_se3(est_positions, gt_positions);
  ate.timestamps = stamps;
  ate.errors.resize(m);
  for (std::size_t k = 0; k < m; ++k) {
    ate.errors[k] = (gt_positions[k] - ate.T_gt_est * est_positions[k]).norm();
  }
  ate.translation = compute_error_stats(ate.errors);

  // RPE, frame delta (evo, all pairs): (i, i + d) for every i with i + d inside the list.
  const auto d = static_cast<std::size_t>(options.rpe_delta_frames);
  std::vector<std::pair<std::size_t, std::size_t>> frame_pairs;
  for (std::size_t i = 0; i + d < m; ++i) frame_pairs.emplace_back(i, i + d);
  report.rpe_frame = relative_errors(gt_poses, est_poses, frame_pairs,
                                     std::to_string(d) + (d == 1 ? " frame" : " frames"));

  // RPE, time delta (evaluate_rpe.py --fixed_delta --delta_unit s): for each i, j is the pose
  // whose est timestamp is closest to t_i + delta. evaluate_rpe.py keeps the pair only when j is
  // not the last pose ("if j != len(traj_est)-1"): that is how it drops the pairs that run off
  // the end of the trajectory (their closest pose is the last one), at the price of also dropping
  // the one genuine pair ending exactly at the last pose. We apply the same rule so counts and
  // statistics match, and additionally drop j <= i (only possible when delta is shorter than
  // half the frame interval; evaluate_rpe.py would keep a zero-motion (i, i) pair there).
  // Unlike evaluate_rpe.py, the pairs are taken among the associated poses (gt matched by
  // associate() rather than by nearest gt stamp within twice the median gt interval), as evo.
  std::vector<std::pair<std::size_t, std::size_t>> time_pairs;
  for (std::size_t i = 0; i < m; ++i) {
    const std::size_t j = closest_index(stamps, stamps[i] + options.rpe_delta_seconds);
    if (j == m - 1 || j <= i) continue;
    time_pairs.emplace_back(i, j);
  }
  report.rpe_time = relative_errors(gt_poses, est_poses, time_pairs,
                                    format_number("%g", options.rpe_delta_seconds) + " s");
  return report;
}

nlohmann::json to_json(const EvalReport& report) {
  nlohmann::json j = nlohmann::json::object();
  j["ate_count"] = report.ate.translation.count;
  add_stats(j, "ate", report.ate.translation, "m", 1.0);
  const Eigen::Matrix4d T = report.ate.T_gt_est.matrix();
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
  j["ate_T_gt_est"] = rows;
  add_rpe(j, "rpe_frame", report.rpe_frame);
  add_rpe(j, "rpe_time", report.rpe_time);
  j["gt_poses"] = report.gt_poses;
  j["est_poses"] = report.est_poses;
  j["matched"] = report.matched;
  j["coverage"] = report.coverage;
  j["gt_duration_s"] = report.gt_duration;
  j["est_duration_s"] = report.est_duration;
  return j;
}

std::string to_text(const EvalReport& report) {
  const ErrorStats& a = report.ate.translation;
  char buf[256];
  std::string out;
  std::snprintf(buf, sizeof(buf),
                "ATE            rmse %.4f m  mean %.4f m  median %.4f m  max %.4f m  [%zu poses]\n",
                a.rmse, a.mean, a.median, a.max, a.count);
  out += buf;
  out += rpe_line(report.rpe_frame);
  out += rpe_line(report.rpe_time);
  std::snprintf(buf, sizeof(buf),
                "matched        %zu of %zu estimated poses (coverage %.1f %%); ground truth %zu "
                "poses over %.2f s, estimate over %.2f s\n",
                report.matched, report.est_poses, 100.0 * report.coverage, report.gt_poses,
                report.gt_duration, report.est_duration);
  out += buf;
  return out;
}

}  // namespace mcslam::eval
