#include "mcslam/eval/metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "mcslam/core/error.hpp"

namespace mcslam::eval {
namespace {

constexpr double kPi = std::numbers::pi;

SE3 random_se3(std::mt19937& rng, double rot_sigma, double trans_sigma) {
  std::normal_distribution<double> r(0.0, rot_sigma), t(0.0, trans_sigma);
  return SE3(so3_exp(Eigen::Vector3d(r(rng), r(rng), r(rng))),
             Eigen::Vector3d(t(rng), t(rng), t(rng)));
}

SE3 translation(double x, double y, double z) {
  return SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(x, y, z));
}

Trajectory stamps_only(const std::vector<double>& stamps) {
  Trajectory t;
  for (const double s : stamps) t.push_back({s, SE3()});
  return t;
}

// A smoothly moving and rotating ground truth sampled at `rate` Hz.
Trajectory smooth_gt(std::size_t n, double rate, double t0 = 0.0) {
  Trajectory gt;
  for (std::size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) / rate;
    const Eigen::Vector3d p(std::sin(0.5 * t), std::cos(0.3 * t), 0.1 * t);
    const Eigen::Vector3d phi(0.2 * std::sin(t), 0.1 * t, 0.3 * std::cos(0.7 * t));
    gt.push_back({t0 + t, SE3(so3_exp(phi), p)});
  }
  return gt;
}

void expect_stats_near(const ErrorStats& a, const ErrorStats& b, double tol) {
  EXPECT_EQ(a.count, b.count);
  EXPECT_NEAR(a.rmse, b.rmse, tol);
  EXPECT_NEAR(a.mean, b.mean, tol);
  EXPECT_NEAR(a.median, b.median, tol);
  EXPECT_NEAR(a.std, b.std, tol);
  EXPECT_NEAR(a.min, b.min, tol);
  EXPECT_NEAR(a.max, b.max, tol);
}

// ---------------------------------------------------------------- statistics

TEST(ErrorStats, EvenCountMatchesNumpy) {
  // numpy: rmse sqrt(30/4) = 2.7386128, mean 2.5, median (2+3)/2 = 2.5, std sqrt(1.25).
  const ErrorStats s = compute_error_stats({4.0, 1.0, 3.0, 2.0});
  EXPECT_EQ(s.count, 4u);
  EXPECT_NEAR(s.rmse, std::sqrt(7.5), 1e-12);
  EXPECT_NEAR(s.mean, 2.5, 1e-12);
  EXPECT_NEAR(s.median, 2.5, 1e-12);
  EXPECT_NEAR(s.std, std::sqrt(1.25), 1e-12);
  EXPECT_EQ(s.min, 1.0);
  EXPECT_EQ(s.max, 4.0);
}

TEST(ErrorStats, OddCountAndEmpty) {
  const ErrorStats s = compute_error_stats({3.0, 1.0, 8.0});
  EXPECT_NEAR(s.median, 3.0, 1e-12);
  EXPECT_NEAR(s.mean, 4.0, 1e-12);
  EXPECT_NEAR(s.std, std::sqrt((1.0 + 9.0 + 16.0) / 3.0), 1e-12);
  const ErrorStats e = compute_error_stats({});
  EXPECT_EQ(e.count, 0u);
  EXPECT_EQ(e.rmse, 0.0);
  EXPECT_EQ(e.max, 0.0);
}

// ---------------------------------------------------------------- association

TEST(Associate, EachPoseUsedOnce) {
  // Both est stamps are closest to the single gt stamp; only the nearer one (0.005 s) gets it.
  const auto m = associate(stamps_only({1.000}), stamps_only({0.990, 0.995}), 0.02);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0], std::make_pair(std::size_t{0}, std::size_t{1}));
}

TEST(Associate, GreedyBySmallestDifference) {
  // Candidates: (g0,e0) 5 ms, (g0,e1) 10 ms, (g1,e0) 7 ms, (g1,e1) 2 ms. Greedy takes (g1,e1) then
  // (g0,e0).
  auto m = associate(stamps_only({1.000, 1.012}), stamps_only({1.005, 1.010}), 0.02);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0], std::make_pair(std::size_t{0}, std::size_t{0}));
  EXPECT_EQ(m[1], std::make_pair(std::size_t{1}, std::size_t{1}));
  // e0 would prefer g1 (3 ms) but e1 holds it with 1 ms, so e0 falls back to g0 (6 ms); the
  // result is sorted by est stamp.
  m = associate(stamps_only({1.000, 1.009}), stamps_only({1.006, 1.010}), 0.02);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0], std::make_pair(std::size_t{0}, std::size_t{0}));
  EXPECT_EQ(m[1], std::make_pair(std::size_t{1}, std::size_t{1}));
  // With a tolerance of 5 ms, e0 has no gt left and stays unmatched.
  m = associate(stamps_only({1.000, 1.009}), stamps_only({1.006, 1.010}), 0.005);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0], std::make_pair(std::size_t{1}, std::size_t{1}));
}

TEST(Associate, MaxDifferenceIsStrict) {
  EXPECT_TRUE(associate(stamps_only({0.0}), stamps_only({0.02}), 0.02).empty());
  EXPECT_TRUE(associate(stamps_only({0.0}), stamps_only({-0.03}), 0.02).empty());
  EXPECT_EQ(associate(stamps_only({0.0}), stamps_only({0.0199}), 0.02).size(), 1u);
  EXPECT_EQ(associate(stamps_only({0.0}), stamps_only({-0.0199}), 0.02).size(), 1u);
  EXPECT_TRUE(associate(stamps_only({}), stamps_only({0.0}), 0.02).empty());
  EXPECT_THROW(associate(stamps_only({0.0}), stamps_only({0.0}), 0.0), InputError);
  EXPECT_THROW(associate(stamps_only({0.0}), stamps_only({0.0}), std::nan("")), InputError);
}

TEST(Associate, GroundTruth100HzEstimate30Hz) {
  const double base = 1305031102.0;  // TUM-like absolute stamps
  std::vector<double> gt_stamps, est_stamps;
  for (int k = 0; k < 1000; ++k) gt_stamps.push_back(base + 0.01 * k);
  for (int j = 0; j < 300; ++j) est_stamps.push_back(base + j / 30.0 + 0.003);
  // Extra est poses before and after the ground truth that cannot match.
  est_stamps.insert(est_stamps.begin(), base - 0.5);
  est_stamps.push_back(base + 12.0);
  const Trajectory gt = stamps_only(gt_stamps), est = stamps_only(est_stamps);

  const auto m = associate(gt, est, 0.02);
  ASSERT_EQ(m.size(), 300u);
  for (std::size_t k = 0; k < m.size(); ++k) {
    const auto [g, e] = m[k];
    EXPECT_EQ(e, k + 1);  // sorted by est stamp, the first est pose is unmatched
    // The nearest 100 Hz stamp is within 5 ms.
    const auto nearest = static_cast<std::size_t>(std::lround((est_stamps[e] - base) / 0.01));
    EXPECT_EQ(g, nearest);
    EXPECT_LE(std::abs(gt_stamps[g] - est_stamps[e]), 0.005 + 1e-6);
  }
}

TEST(Associate, UnsortedInputGivesSameMatches) {
  const Trajectory gt = stamps_only({0.00, 0.04, 0.02, 0.01, 0.03, 0.05});
  const Trajectory est = stamps_only({0.003, 0.037, 0.021});
  const auto m = associate(gt, est, 0.02);
  ASSERT_EQ(m.size(), 3u);
  EXPECT_EQ(m[0], std::make_pair(std::size_t{0}, std::size_t{0}));
  EXPECT_EQ(m[1], std::make_pair(std::size_t{2}, std::size_t{2}));  // sorted by est stamp
  EXPECT_EQ(m[2], std::make_pair(std::size_t{1}, std::size_t{1}));
}

// ---------------------------------------------------------------- alignment

TEST(AlignSE3, RecoversKnownTransformExactly) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  for (int trial = 0; trial < 10; ++trial) {
    const SE3 T = random_se3(rng, 1.5, 3.0);
    std::vector<Eigen::Vector3d> est, gt;
    for (int i = 0; i < 50; ++i) {
      const Eigen::Vector3d p(u(rng), u(rng), u(rng));
      est.push_back(p);
      gt.push_back(T * p);
    }
    const SE3 A = align_se3(est, gt);
    EXPECT_LT((A.matrix() - T.matrix()).cwiseAbs().maxCoeff(), 1e-9);
  }
}

TEST(AlignSE3, ApproximatelyRecoversTransformWithNoise) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  std::normal_distribution<double> noise(0.0, 0.02);
  const SE3 T = random_se3(rng, 1.0, 2.0);
  std::vector<Eigen::Vector3d> est, gt;
  for (int i = 0; i < 500; ++i) {
    const Eigen::Vector3d p(u(rng), u(rng), u(rng));
    est.push_back(p);
    gt.push_back(T * p + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  }
  const SE3 A = align_se3(est, gt);
  EXPECT_LT(rotation_angle(A.quaternion() * T.quaternion().conjugate()), 2e-3);
  EXPECT_LT((A.translation() - T.translation()).norm(), 1e-2);
  EXPECT_GT((A.matrix() - T.matrix()).cwiseAbs().maxCoeff(), 1e-9);  // not exact: noise
}

// Sum of squared residuals of gt - (R est + t) with the best t for this R.
double alignment_cost(const Eigen::Matrix3d& R, const std::vector<Eigen::Vector3d>& est,
                      const std::vector<Eigen::Vector3d>& gt) {
  Eigen::Vector3d mu_e = Eigen::Vector3d::Zero(), mu_g = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < est.size(); ++i) {
    mu_e += est[i];
    mu_g += gt[i];
  }
  mu_e /= static_cast<double>(est.size());
  mu_g /= static_cast<double>(est.size());
  double cost = 0.0;
  for (std::size_t i = 0; i < est.size(); ++i) {
    cost += (gt[i] - mu_g - R * (est[i] - mu_e)).squaredNorm();
  }
  return cost;
}

TEST(AlignSE3, NeverReturnsAReflection) {
  // gt is a rotated mirror image of anisotropic est points, so the unconstrained optimum is a
  // reflection. The result must be a proper rotation and the best one: no nearby rotation does
  // better.
  std::mt19937 rng(13);
  std::normal_distribution<double> n(0.0, 1.0);
  const Eigen::Matrix3d mirror = Eigen::Vector3d(1, 1, -1).asDiagonal();
  const Eigen::Matrix3d Rr = so3_exp(Eigen::Vector3d(0.4, -1.1, 0.8)).toRotationMatrix();
  std::vector<Eigen::Vector3d> est, gt;
  for (int i = 0; i < 40; ++i) {
    const Eigen::Vector3d p(3.0 * n(rng), 2.0 * n(rng), 1.0 * n(rng));
    est.push_back(p);
    gt.push_back(Rr * mirror * p + Eigen::Vector3d(1, 2, 3));
  }
  const SE3 A = align_se3(est, gt);
  const Eigen::Matrix3d R = A.rotation();
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  const double best = alignment_cost(R, est, gt);
  // The translation is the optimal one for the returned rotation.
  double cost = 0.0;
  for (std::size_t i = 0; i < est.size(); ++i) cost += (gt[i] - A * est[i]).squaredNorm();
  EXPECT_NEAR(cost, best, 1e-9 * (1.0 + best));
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector3d d(0.05 * n(rng), 0.05 * n(rng), 0.05 * n(rng));
    EXPECT_GE(alignment_cost(so3_exp(d).toRotationMatrix() * R, est, gt), best - 1e-9);
  }
}

TEST(AlignSE3, DegenerateInputs) {
  EXPECT_LT((align_se3({}, {}).matrix() - Eigen::Matrix4d::Identity()).norm(), 1e-15);
  // One or two points: translation between the centroids only.
  const SE3 one = align_se3({Eigen::Vector3d(1, 2, 3)}, {Eigen::Vector3d(2, 2, 2)});
  EXPECT_LT((one.translation() - Eigen::Vector3d(1, 0, -1)).norm(), 1e-15);
  EXPECT_NEAR(rotation_angle(one.quaternion()), 0.0, 1e-15);
  const SE3 two = align_se3({Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0)},
                            {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0, 1, 0)});
  EXPECT_LT((two.translation() - Eigen::Vector3d(-0.5, 0.5, 0)).norm(), 1e-15);
  EXPECT_NEAR(rotation_angle(two.quaternion()), 0.0, 1e-15);
  // Collinear points: still a minimiser (zero residual for a rigidly moved line).
  const SE3 T(so3_exp(Eigen::Vector3d(0.3, -0.2, 0.5)), Eigen::Vector3d(1, 2, 3));
  std::vector<Eigen::Vector3d> est, gt;
  for (int i = 0; i < 5; ++i) {
    est.emplace_back(0.5 * i, 0.2 * i, -0.1 * i);
    gt.push_back(T * est.back());
  }
  const SE3 A = align_se3(est, gt);
  for (std::size_t i = 0; i < est.size(); ++i) EXPECT_LT((A * est[i] - gt[i]).norm(), 1e-9);
  EXPECT_THROW(align_se3({Eigen::Vector3d::Zero()}, {}), InputError);
}

// ---------------------------------------------------------------- ATE

TEST(Ate, RigidlyMovedEstimateHasZeroError) {
  std::mt19937 rng(21);
  const Trajectory gt = smooth_gt(300, 30.0);
  const SE3 T = random_se3(rng, 1.0, 5.0);
  Trajectory est;
  for (const auto& p : gt) est.push_back({p.timestamp + 0.004, T * p.T_w_c});
  const EvalReport r = evaluate(gt, est);
  EXPECT_EQ(r.matched, 300u);
  EXPECT_LT(r.ate.translation.rmse, 1e-9);
  EXPECT_LT(r.ate.translation.max, 1e-9);
  // The alignment maps est into gt: T_gt_est = T^-1.
  EXPECT_LT((r.ate.T_gt_est.matrix() - T.inverse().matrix()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT(r.rpe_frame.translation.max, 1e-9);
  EXPECT_LT(r.rpe_frame.rotation.max, 1e-7);
  ASSERT_EQ(r.ate.timestamps.size(), 300u);
  EXPECT_DOUBLE_EQ(r.ate.timestamps.front(), 0.004);
}

TEST(Ate, IsotropicNoiseGivesSigmaSqrt3) {
  std::mt19937 rng(22);
  std::normal_distribution<double> n(0.0, 1.0);
  const double sigma = 0.01;
  const Trajectory gt = smooth_gt(5000, 30.0);
  const SE3 T = random_se3(rng, 0.5, 2.0);
  Trajectory est;
  for (const auto& p : gt) {
    SE3 pose = p.T_w_c;
    pose.set_translation(pose.translation() + sigma * Eigen::Vector3d(n(rng), n(rng), n(rng)));
    est.push_back({p.timestamp, T * pose});
  }
  const EvalReport r = evaluate(gt, est);
  // E|n|^2 = 3 sigma^2; the 6 aligned degrees of freedom remove a negligible 6/5000 share.
  EXPECT_NEAR(r.ate.translation.rmse, sigma * std::sqrt(3.0), 0.03 * sigma * std::sqrt(3.0));
  // Mean of a chi(3) variable: sigma * 2 sqrt(2/pi).
  EXPECT_NEAR(r.ate.translation.mean, sigma * 2.0 * std::sqrt(2.0 / kPi), 0.03 * sigma);
}

TEST(Ate, HandComputedExample) {
  // gt on the axes, est = 1.1 * gt (then moved rigidly). W = 1.1 diag(2, 8, 0) is PSD with rank
  // 2, so the best rotation is the identity (in the un-moved frame) and the centroids are 0.
  // Errors |g - 1.1 g| = 0.1 |g| = 0.1, 0.1, 0.2, 0.2:
  //   rmse sqrt((0.01 + 0.01 + 0.04 + 0.04) / 4) = sqrt(0.025) = 0.158113883
  //   mean 0.15, median (0.1 + 0.2) / 2 = 0.15, std 0.05, min 0.1, max 0.2.
  const std::vector<Eigen::Vector3d> g = {{1, 0, 0}, {-1, 0, 0}, {0, 2, 0}, {0, -2, 0}};
  const SE3 M(so3_exp(Eigen::Vector3d(0.1, 0.7, -0.4)), Eigen::Vector3d(3, -1, 2));
  Trajectory gt, est;
  for (std::size_t i = 0; i < g.size(); ++i) {
    gt.push_back({static_cast<double>(i), translation(g[i].x(), g[i].y(), g[i].z())});
    est.push_back({static_cast<double>(i), SE3(M.quaternion(), M * (1.1 * g[i]))});
  }
  const EvalReport r = evaluate(gt, est);
  const ErrorStats& s = r.ate.translation;
  EXPECT_EQ(s.count, 4u);
  EXPECT_NEAR(s.rmse, std::sqrt(0.025), 1e-12);
  EXPECT_NEAR(s.mean, 0.15, 1e-12);
  EXPECT_NEAR(s.median, 0.15, 1e-12);
  EXPECT_NEAR(s.std, 0.05, 1e-12);
  EXPECT_NEAR(s.min, 0.1, 1e-12);
  EXPECT_NEAR(s.max, 0.2, 1e-12);
  EXPECT_LT((r.ate.T_gt_est.matrix() - M.inverse().matrix()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(r.ate.errors[2], 0.2, 1e-12);
}

// ---------------------------------------------------------------- RPE

TEST(Rpe, HandComputedExample) {
  // gt:  Q0 = I, Q1 = trans(1,0,0), Q2 = trans(2,0,0)
  // est: P0 = I, P1 = [Rz(90 deg), (1,0,0)], P2 = [Rz(90 deg), (1,1.5,0)]
  // E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j):
  //  (0,1): Q_rel = trans(1,0,0), P_rel = P1 -> E = [Rz(90), 0]: trans 0, rot pi/2.
  //         (The other order P_rel Q_rel^-1 would give translation (1,-1,0), |.| = sqrt 2.)
  //  (1,2): P_rel = [I, Rz(-90) (0,1.5,0)] = [I, (1.5,0,0)] -> E = [I, (0.5,0,0)]: 0.5, rot 0.
  //  (0,2): Q_rel = trans(2,0,0), P_rel = P2 -> E = [Rz(90), (-1,1.5,0)]: sqrt(3.25), pi/2.
  const Eigen::Quaterniond rz(Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitZ()));
  const Trajectory gt = {{0.0, SE3()}, {1.0, translation(1, 0, 0)}, {2.0, translation(2, 0, 0)}};
  const Trajectory est = {{0.0, SE3()},
                          {1.0, SE3(rz, Eigen::Vector3d(1, 0, 0))},
                          {2.0, SE3(rz, Eigen::Vector3d(1, 1.5, 0))}};
  EvalOptions opt;
  const EvalReport r = evaluate(gt, est, opt);
  EXPECT_EQ(r.rpe_frame.delta, "1 frame");
  // trans [0, 0.5]: rmse sqrt(0.125), mean = median = std = 0.25.
  const ErrorStats& t = r.rpe_frame.translation;
  EXPECT_EQ(t.count, 2u);
  EXPECT_NEAR(t.rmse, std::sqrt(0.125), 1e-12);
  EXPECT_NEAR(t.mean, 0.25, 1e-12);
  EXPECT_NEAR(t.median, 0.25, 1e-12);
  EXPECT_NEAR(t.std, 0.25, 1e-12);
  EXPECT_NEAR(t.min, 0.0, 1e-12);
  EXPECT_NEAR(t.max, 0.5, 1e-12);
  // rot [pi/2, 0]: rmse pi/(2 sqrt 2), mean = median = std = pi/4.
  const ErrorStats& a = r.rpe_frame.rotation;
  EXPECT_NEAR(a.rmse, kPi / (2 * std::sqrt(2.0)), 1e-12);
  EXPECT_NEAR(a.mean, kPi / 4, 1e-12);
  EXPECT_NEAR(a.std, kPi / 4, 1e-12);
  EXPECT_NEAR(a.max, kPi / 2, 1e-12);

  // 1 s delta: i=0 -> j=1 kept; i=1 -> j=2 is the last pose, dropped as evaluate_rpe.py does;
  // i=2 -> j=2 dropped. One pair: trans 0, rot pi/2.
  EXPECT_EQ(r.rpe_time.delta, "1 s");
  EXPECT_EQ(r.rpe_time.translation.count, 1u);
  EXPECT_NEAR(r.rpe_time.translation.max, 0.0, 1e-12);
  EXPECT_NEAR(r.rpe_time.rotation.max, kPi / 2, 1e-12);

  opt.rpe_delta_frames = 2;
  opt.rpe_delta_seconds = 0.4;  // shorter than half the frame interval: no pair
  const EvalReport r2 = evaluate(gt, est, opt);
  EXPECT_EQ(r2.rpe_frame.delta, "2 frames");
  ASSERT_EQ(r2.rpe_frame.translation.count, 1u);
  EXPECT_NEAR(r2.rpe_frame.translation.rmse, std::sqrt(3.25), 1e-12);
  EXPECT_NEAR(r2.rpe_frame.rotation.rmse, kPi / 2, 1e-12);
  EXPECT_EQ(r2.rpe_time.translation.count, 0u);
  EXPECT_NE(to_text(r2).find("n/a"), std::string::npos);
}

// est accumulates the gt step followed by a constant extra motion D at every frame.
Trajectory drifting_estimate(const Trajectory& gt, const SE3& D, const SE3& start,
                             double time_offset) {
  Trajectory est;
  SE3 P = start;
  for (std::size_t k = 0; k < gt.size(); ++k) {
    if (k > 0) P = P * (gt[k - 1].T_w_c.inverse() * gt[k].T_w_c) * D;
    est.push_back({gt[k].timestamp + time_offset, P});
  }
  return est;
}

TEST(Rpe, ConstantPerFrameDrift) {
  std::mt19937 rng(31);
  const Trajectory gt = smooth_gt(300, 30.0);
  const SE3 D(so3_exp(0.001 * Eigen::Vector3d(1, 2, -2).normalized()),
              0.001 * Eigen::Vector3d(3, -1, 2).normalized());
  const Trajectory est = drifting_estimate(gt, D, random_se3(rng, 1.0, 3.0), 0.003);
  const EvalReport r = evaluate(gt, est);
  EXPECT_EQ(r.matched, 300u);
  // Per frame, E = D exactly.
  EXPECT_EQ(r.rpe_frame.translation.count, 299u);
  EXPECT_NEAR(r.rpe_frame.translation.min, 0.001, 1e-9);
  EXPECT_NEAR(r.rpe_frame.translation.max, 0.001, 1e-9);
  EXPECT_NEAR(r.rpe_frame.rotation.min, 0.001, 1e-9);
  EXPECT_NEAR(r.rpe_frame.rotation.max, 0.001, 1e-9);
  // Over 1 s (30 frames) the drift accumulates: rotation at most 30 * 0.001, close to it as the
  // gt turns slowly; translation about 30 mm plus lever-arm effects of the rotation drift.
  EXPECT_GT(r.rpe_time.rotation.mean, 0.025);
  EXPECT_LT(r.rpe_time.rotation.max, 0.030 + 1e-9);
  EXPECT_GT(r.rpe_time.translation.mean, 0.015);
  EXPECT_LT(r.rpe_time.translation.mean, 0.05);
}

TEST(Rpe, TimeDeltaAccumulatesDriftExactly) {
  // gt moves along x without rotating; D rotates about x and translates along x, so the 30
  // steps of one second compose exactly: E = [Rx(0.03), (0.03, 0, 0)].
  Trajectory gt;
  for (int k = 0; k < 300; ++k) gt.push_back({k / 30.0, translation(0.01 * k, 0, 0)});
  const SE3 D(so3_exp(Eigen::Vector3d(0.001, 0, 0)), Eigen::Vector3d(0.001, 0, 0));
  const Trajectory est = drifting_estimate(gt, D, SE3(), 0.0);
  const EvalReport r = evaluate(gt, est);
  // i = 0 .. 268 pair with i + 30; i = 269 would end at the last pose (dropped, as
  // evaluate_rpe.py), later i run off the end.
  EXPECT_EQ(r.rpe_time.translation.count, 269u);
  EXPECT_NEAR(r.rpe_time.translation.min, 0.03, 1e-9);
  EXPECT_NEAR(r.rpe_time.translation.max, 0.03, 1e-9);
  EXPECT_NEAR(r.rpe_time.rotation.min, 0.03, 1e-9);
  EXPECT_NEAR(r.rpe_time.rotation.max, 0.03, 1e-9);
  // Time-based and frame-based deltas agree at 30 frames.
  EvalOptions opt;
  opt.rpe_delta_frames = 30;
  const EvalReport f = evaluate(gt, est, opt);
  EXPECT_EQ(f.rpe_frame.translation.count, 270u);  // evo keeps the pair ending at the last pose
  EXPECT_NEAR(f.rpe_frame.translation.rmse, 0.03, 1e-9);
}

TEST(Rpe, GlobalTransformOfEstimateChangesNothing) {
  std::mt19937 rng(32);
  const Trajectory gt = smooth_gt(200, 30.0);
  Trajectory est;
  for (const auto& p : gt)
    est.push_back({p.timestamp + 0.002, p.T_w_c * random_se3(rng, 0.01, 0.02)});
  const SE3 G = random_se3(rng, 1.5, 10.0);
  Trajectory moved = est;
  for (auto& p : moved) p.T_w_c = G * p.T_w_c;
  const EvalReport a = evaluate(gt, est), b = evaluate(gt, moved);
  EXPECT_GT(a.rpe_frame.translation.rmse, 1e-3);  // the noise is visible
  expect_stats_near(a.rpe_frame.translation, b.rpe_frame.translation, 1e-9);
  expect_stats_near(a.rpe_frame.rotation, b.rpe_frame.rotation, 1e-9);
  expect_stats_near(a.rpe_time.translation, b.rpe_time.translation, 1e-9);
  expect_stats_near(a.rpe_time.rotation, b.rpe_time.rotation, 1e-9);
  expect_stats_near(a.ate.translation, b.ate.translation, 1e-9);
}

// ---------------------------------------------------------------- evaluate / report

TEST(Evaluate, RejectsBadInput) {
  const Trajectory gt = smooth_gt(10, 30.0);
  EXPECT_THROW(evaluate({}, gt), InputError);
  EXPECT_THROW(evaluate(gt, {}), InputError);
  EvalOptions bad;
  bad.rpe_delta_frames = 0;
  EXPECT_TRUE(bad.check().has_value());
  EXPECT_THROW(evaluate(gt, gt, bad), InputError);
  EXPECT_FALSE(EvalOptions{}.check().has_value());
  bad = EvalOptions{};
  bad.max_time_difference = -1;
  EXPECT_TRUE(bad.check().has_value());
  bad = EvalOptions{};
  bad.rpe_delta_seconds = 0;
  EXPECT_TRUE(bad.check().has_value());
}

TEST(Evaluate, NoOverlapNamesTheProblem) {
  const Trajectory gt = smooth_gt(30, 30.0, 0.0);
  const Trajectory est = smooth_gt(30, 30.0, 100.0);
  try {
    evaluate(gt, est);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("no estimated pose lies within 0.02 s of a ground-truth pose"),
              std::string::npos)
        << msg;
    EXPECT_NE(msg.find("100.0"), std::string::npos) << msg;  // est span is reported
  }
}

TEST(Evaluate, CoverageAndDurations) {
  const Trajectory gt = smooth_gt(100, 30.0);  // 0 .. 3.3 s
  Trajectory est = smooth_gt(150, 30.0);       // 0 .. 4.97 s: the last 50 poses have no gt
  const EvalReport r = evaluate(gt, est);
  EXPECT_EQ(r.gt_poses, 100u);
  EXPECT_EQ(r.est_poses, 150u);
  EXPECT_EQ(r.matched, 100u);
  EXPECT_NEAR(r.coverage, 100.0 / 150.0, 1e-12);
  EXPECT_NEAR(r.gt_duration, 99.0 / 30.0, 1e-12);
  EXPECT_NEAR(r.est_duration, 149.0 / 30.0, 1e-12);
  EXPECT_EQ(r.ate.errors.size(), 100u);
}

TEST(Evaluate, JsonAndText) {
  std::mt19937 rng(41);
  const Trajectory gt = smooth_gt(90, 30.0);
  Trajectory est;
  for (const auto& p : gt) est.push_back({p.timestamp, p.T_w_c * random_se3(rng, 0.01, 0.01)});
  const EvalReport r = evaluate(gt, est);
  const nlohmann::json j = to_json(r);
  for (const char* key : {"ate_rmse_m",
                          "ate_mean_m",
                          "ate_median_m",
                          "ate_std_m",
                          "ate_min_m",
                          "ate_max_m",
                          "ate_count",
                          "ate_T_gt_est",
                          "rpe_frame_delta",
                          "rpe_frame_count",
                          "rpe_frame_trans_rmse_m",
                          "rpe_frame_trans_mean_m",
                          "rpe_frame_trans_median_m",
                          "rpe_frame_trans_max_m",
                          "rpe_frame_rot_rmse_rad",
                          "rpe_frame_rot_rmse_deg",
                          "rpe_frame_rot_mean_deg",
                          "rpe_time_delta",
                          "rpe_time_trans_rmse_m",
                          "rpe_time_rot_rmse_rad",
                          "rpe_time_rot_rmse_deg",
                          "gt_poses",
                          "est_poses",
                          "matched",
                          "coverage",
                          "gt_duration_s",
                          "est_duration_s"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_DOUBLE_EQ(j["ate_rmse_m"].get<double>(), r.ate.translation.rmse);
  EXPECT_NEAR(j["rpe_frame_rot_rmse_deg"].get<double>(), r.rpe_frame.rotation.rmse * 180.0 / kPi,
              1e-12);
  EXPECT_EQ(j["rpe_time_delta"].get<std::string>(), "1 s");
  EXPECT_EQ(j["matched"].get<std::size_t>(), 90u);
  EXPECT_EQ(j["ate_T_gt_est"].size(), 4u);

  const std::string text = to_text(r);
  EXPECT_FALSE(text.empty());
  EXPECT_NE(text.find("ATE"), std::string::npos);
  EXPECT_NE(text.find("1 frame"), std::string::npos);
  EXPECT_NE(text.find("1 s"), std::string::npos);
  EXPECT_NE(text.find("coverage 100.0 %"), std::string::npos) << text;
}

}  // namespace
}  // namespace mcslam::eval
