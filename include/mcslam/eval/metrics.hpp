#pragma once
// Trajectory evaluation: absolute trajectory error (ATE) and relative pose error (RPE) with the
// definitions of the TUM RGB-D benchmark tools (associate.py, evaluate_ate.py, evaluate_rpe.py)
// and evo. Poses are T_w_c (camera to world); gt and est may live in different world frames.

#include <cstddef>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "mcslam/core/se3.hpp"
#include "mcslam/core/trajectory.hpp"

namespace mcslam::eval {

/// Summary statistics of a list of non-negative errors, as numpy computes them: rmse, mean,
/// median (mean of the two middle values for an even count), std (population, ddof = 0), min,
/// max. An empty list gives all zeros with count 0.
struct ErrorStats {
  double rmse = 0, mean = 0, median = 0, std = 0, min = 0, max = 0;
  std::size_t count = 0;
};

ErrorStats compute_error_stats(const std::vector<double>& errors);

/// TUM associate.py semantics: every (gt, est) pair with |t_gt - t_est| < max_dt is a candidate;
/// candidates are taken greedily by increasing |dt| (ties: earlier gt, then earlier est stamp),
/// each pose being used at most once. Returns (gt_index, est_index) pairs sorted by est
/// timestamp. Inputs need not be sorted. Throws InputError unless max_dt > 0 and finite.
std::vector<std::pair<std::size_t, std::size_t>> associate(const Trajectory& gt,
                                                           const Trajectory& est, double max_dt);

/// Closed-form rigid alignment (Horn / Umeyama without scale, as evaluate_ate.py's align()):
/// returns T_gt_est minimising sum_i |gt_i - T * est_i|^2. The reflection case is handled so the
/// rotation always has det +1.
/// Degenerate input: with no points the identity is returned; with 1 or 2 points the rotation is
/// not determined (2 points leave the roll about their axis free), so only the translation
/// between the centroids is estimated (rotation = identity). With >= 3 collinear (or coincident)
/// points the result is still a minimiser, but its rotation about the line is arbitrary.
/// Throws InputError when the two lists differ in size.
SE3 align_se3(const std::vector<Eigen::Vector3d>& est_positions,
              const std::vector<Eigen::Vector3d>& gt_positions);

struct EvalOptions {
  /// Association tolerance in seconds (associate.py --max_difference).
  double max_time_difference = 0.02;
  /// RPE frame delta: pairs (i, i + rpe_delta_frames) among the associated poses.
  int rpe_delta_frames = 1;
  /// RPE time delta in seconds (evaluate_rpe.py --fixed_delta --delta 1 --delta_unit s).
  double rpe_delta_seconds = 1.0;

  /// A description of the first invalid field, or nullopt when the options are usable.
  std::optional<std::string> check() const;
};

struct AteResult {
  ErrorStats translation;          ///< metres
  SE3 T_gt_est;                    ///< alignment applied to the estimated positions
  std::vector<double> timestamps;  ///< est timestamp of each associated pair, increasing
  std::vector<double> errors;      ///< |p_gt - T_gt_est * p_est| per associated pair (m)
};

struct RpeResult {
  ErrorStats translation;  ///< metres
  ErrorStats rotation;     ///< radians
  std::string delta;       ///< "1 frame" / "1 s"
};

struct EvalReport {
  AteResult ate;
  RpeResult rpe_frame;
  RpeResult rpe_time;
  std::size_t gt_poses = 0, est_poses = 0, matched = 0;
  double coverage = 0;                       ///< matched / est_poses
  double gt_duration = 0, est_duration = 0;  ///< seconds, last minus first timestamp
};

/// Associates est with gt, then computes ATE and RPE (frame and time delta) over the associated
/// pairs. RPE uses E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) (Q gt, P est, as evo); translation error is
/// |trans(E)|, rotation error the angle of rot(E). RPE statistics have count 0 when no pair
/// exists (e.g. a single associated pose). Throws InputError on invalid options, an empty
/// trajectory, non-finite timestamps, or when no pose associates.
EvalReport evaluate(const Trajectory& gt, const Trajectory& est, const EvalOptions& options = {});

/// Flat object of all numbers: ate_rmse_m, ate_mean_m, ..., rpe_frame_trans_rmse_m,
/// rpe_frame_rot_rmse_rad, rpe_frame_rot_rmse_deg, ..., rpe_time_*, gt_poses, est_poses,
/// matched, coverage, gt_duration_s, est_duration_s, ate_T_gt_est (4x4, row-major rows).
nlohmann::json to_json(const EvalReport& report);

/// A short human-readable table.
std::string to_text(const EvalReport& report);

}  // namespace mcslam::eval
