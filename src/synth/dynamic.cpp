#include "dynamic.hpp"

#include <algorithm>
#include <cmath>

namespace mcslam::synth::detail {
namespace {

constexpr double kPi = 3.141592653589793;
constexpr double kDeg = kPi / 180.0;

/// An axis-aligned rectangle of floor (metres) that an object's footprint must stay in.
struct Area {
  double x0, x1, y0, y1;
  double mid_x() const { return 0.5 * (x0 + x1); }
  double mid_y() const { return 0.5 * (y0 + y1); }
  double half_x() const { return 0.5 * (x1 - x0); }
  double half_y() const { return 0.5 * (y1 - y0); }
};

// The areas are disjoint, so the two objects can never meet whatever their speeds. Margins are
// 5 cm. The camera path (camera_path at any speed) stays at x <= 0.72 m and |y| <= 0.72 m.
//
// Person: in front of the refrigerator (x >= 2.35 for y in [-0.65, 0.05]), between the tv
// (y <= -1.168 for x in [1.87, 2.53]) and the dining table (y >= 0.4 for x in [1.8, 2.6]); its
// near side stays beyond x = 0.72 + 0.8 + 0.05, so 0.8 m from the camera even at head height.
constexpr Area kPersonArea{1.57, 2.30, -1.11, 0.35};
// Chair: the corner beyond the table, between the oven (x <= 1.19) and the +x wall, the table
// (y <= 1.6) and the +y wall; at least 1 m from every camera position.
constexpr Area kChairArea{1.24, 2.95, 1.65, 2.45};
constexpr double kCeiling = 3.0;
constexpr double kFloorGap = 0.01;    // the person's lowest point stays this far above the floor
constexpr double kCeilingGap = 0.02;  // and its highest this far below the ceiling

}  // namespace

double motion_time(double t, double start_time, double speed) {
  constexpr double ramp = SynthOptions::DynamicObjects::kRampTime;
  const double u = t - start_time;
  if (!(u > 0.0)) return 0.0;
  if (u < ramp) {
    const double v = u / ramp;
    return speed * ramp * (v * v * v - 0.5 * v * v * v * v);  // integral of 3 v^2 - 2 v^3
  }
  return speed * (u - 0.5 * ramp);
}

SceneObject make_person(const SynthOptions::DynamicObjects& options) {
  SceneObject person;
  person.class_name = "person";
  person.motion = MotionKind::kFree;
  const Eigen::Vector3d h = options.person_scale * Eigen::Vector3d(0.175, 0.25, 0.85);
  person.half_extents = h;
  // Rotation Rz(psi) Rx(theta): it leans sideways (theta, about the horizontal x axis, so that
  // its edges change their angle to the floor) and turns a little (psi).
  const double lean = 6.0 * kDeg, turn = 6.0 * kDeg;
  // Half extents of the axis-aligned bounds of the box over all |theta| <= lean, |psi| <= turn
  // (bounds of the entries of |Rz Rx|), so that no pose leaves the area.
  const double sl = std::sin(lean), st = std::sin(turn);
  const Eigen::Vector3d bound(h.x() + st * (h.y() + sl * h.z()), st * h.x() + h.y() + sl * h.z(),
                              sl * h.y() + h.z());
  const Area& area = kPersonArea;
  const double ax = std::max(0.0, area.half_x() - bound.x());
  const double ay = std::max(0.0, area.half_y() - bound.y());
  // Figure of eight (x at twice the frequency of y): the speed is largest, sqrt(ay^2 + 4 ax^2)
  // times the angular rate, when both coordinates cross their middle together, so this rate makes
  // the peak horizontal speed exactly 1 m/s of motion time.
  const double rate = 1.0 / std::max(1e-9, std::sqrt(ay * ay + 4.0 * ax * ax));
  // Bobbing between the floor and up to 0.4 m above it (less when the ceiling is close), with a
  // mean vertical speed of 2 * bob / period = 0.67 m/s: 2.2 cm per frame at 30 fps, so a height
  // change that the tests can measure between consecutive frames.
  const double bob =
      std::max(0.0, std::min(0.4, kCeiling - kCeilingGap - kFloorGap - 2.0 * bound.z()));
  const double bob_period = std::max(0.05, 3.0 * bob);
  const double base_z = bound.z() + kFloorGap;
  const double start = options.start_time, speed = options.person_speed;
  person.pose_at = [=](double t) {
    const double s = motion_time(t, start, speed);
    const Eigen::Vector3d p(area.mid_x() + ax * std::sin(2.0 * rate * s),
                            area.mid_y() + ay * std::sin(rate * s),
                            base_z + 0.5 * bob * (1.0 - std::cos(2.0 * kPi * s / bob_period)));
    const double theta = lean * std::sin(2.0 * kPi * s / 1.7);
    const double psi = turn * std::sin(2.0 * kPi * s / 2.3 + 1.0);
    const Eigen::Quaterniond q(Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitX()));
    return SE3(q, p);
  };
  return person;
}

SceneObject make_chair(const SynthOptions::DynamicObjects& options) {
  SceneObject chair;
  chair.class_name = "chair";
  chair.motion = MotionKind::kSlide;
  const Eigen::Vector3d h = options.chair_scale * Eigen::Vector3d(0.25, 0.25, 0.45);
  chair.half_extents = h;
  const Area& area = kChairArea;
  // A square of half side a turned by psi spans a (|cos psi| + |sin psi|) = sqrt(2) a
  // sin(|psi| + 45 deg) either side of its centre: the largest swing up to 25 deg that fits the
  // width of the corner.
  const double a = h.x();
  double turn = 25.0 * kDeg;
  const double ratio = area.half_y() / (std::sqrt(2.0) * a);
  if (ratio < 1.0) turn = std::min(turn, std::max(0.0, std::asin(ratio) - 0.25 * kPi));
  const double reach = a * (std::cos(turn) + std::sin(turn));
  const double ax = std::max(0.0, area.half_x() - reach);
  const double ay = std::max(0.0, area.half_y() - reach);
  // Back and forth along x with a small sideways figure of eight (see make_person): peak speed
  // exactly 1 m/s of motion time.
  const double rate = 1.0 / std::max(1e-9, std::sqrt(ax * ax + 4.0 * ay * ay));
  const double start = options.start_time, speed = options.chair_speed;
  chair.pose_at = [=](double t) {
    const double s = motion_time(t, start, speed);
    // The bottom face stays exactly at z = 0 and the rotation is about z only, so every point
    // keeps its height.
    const Eigen::Vector3d p(area.mid_x() + ax * std::sin(rate * s),
                            area.mid_y() + ay * std::sin(2.0 * rate * s), h.z());
    const double psi = turn * std::sin(2.0 * kPi * s / 3.1);
    return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ())), p);
  };
  return chair;
}

}  // namespace mcslam::synth::detail
