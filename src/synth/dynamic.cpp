#include "dynamic.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

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

/// One person of the crowd: it walks straight back and forth along one axis of its area.
struct CrowdWalker {
  Area area;     // its footprint stays inside (areas are disjoint, 5 cm from furniture)
  bool along_x;  // walks along world x (else along y)
  double across, along, height;  // box edges (m) across the walk, along it, and upright
  double pace;                   // peak horizontal speed in units of person_speed
  double phase;                  // of the walk at motion time 0 (rad): where it stands at rest
  double gait_phase;  // of its bobbing, leaning and turning (rad), so that nobody is in step
};

// The camera path stays at x <= 0.72 and |y| <= 0.72 and looks at +x with a yaw of +-41 deg
// (horizontal field of view +-31 deg), so everything worth seeing lies at x > 0.72, which the
// furniture, person 1's area (kPersonArea) and the chair's (kChairArea) already crowd. The paths
// below fill the free floor left, each 0.4 m or more from every camera position.
constexpr CrowdWalker kCrowd[] = {
    // 2: close in front of the camera, walking across the whole view between the suitcase
    // (y <= -1.67) and the oven and the chair's corner (y >= 1.65), in the strip between the
    // camera (x <= 0.72) and person 1 (x >= 1.57). Seen from 0.4 to 1.3 m, it fills up to
    // about half of the image (see tests/synth/crowd_test.cpp for the figures).
    {{1.12, 1.55, -1.60, 1.60}, false, 0.35, 0.5, 1.7, 1.0, -1.0, 1.3},
    // 3: along x on the camera's right, in front of the suitcase (y <= -1.67) and short of
    // person 2's strip: seen only when the camera looks right, at 0.5-1.6 m, mostly at the
    // image's right edge and above its top one, so often cut by the border.
    {{-0.60, 1.05, -1.61, -1.15}, true, 0.34, 0.5, 1.65, 0.9, 2.0, 4.1},
    // 4: the same on the left, in front of the oven (y >= 1.69).
    {{0.05, 1.05, 1.15, 1.62}, true, 0.34, 0.48, 1.75, 0.8, 0.5, 2.9},
    // 5: along x behind the tv (y <= -1.89) and beside the suitcase (x >= 1.48), 2-3 m away.
    {{1.48, 2.95, -2.45, -1.89}, true, 0.35, 0.5, 1.8, 0.7, 4.0, 0.6},
    // 6: a slim one (a child) along y behind the dining table (x >= 2.645), against the +x wall.
    {{2.645, 2.955, 0.45, 1.55}, false, 0.24, 0.45, 1.5, 0.6, 1.0, 5.3},
};

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

SceneObject make_crowd_person(int number, const SynthOptions::DynamicObjects& options) {
  constexpr int kCount = static_cast<int>(sizeof(kCrowd) / sizeof(kCrowd[0]));
  static_assert(kCount == SynthOptions::DynamicObjects::kMaxPeople - 1);
  if (number < 2 || number > kCount + 1) throw std::out_of_range("make_crowd_person: bad number");
  const CrowdWalker& w = kCrowd[number - 2];
  SceneObject person;
  person.class_name = "person";
  person.motion = MotionKind::kFree;
  // As person 1, the box's x axis is across the walk and its y axis along it; a walker along
  // world x is turned by 90 deg about z.
  const Eigen::Vector3d h = 0.5 * Eigen::Vector3d(w.across, w.along, w.height);
  person.half_extents = h;
  // The same gait as person 1 (make_person): leaning +-6 deg, turning +-6 deg, bobbing.
  const double lean = 6.0 * kDeg, turn = 6.0 * kDeg;
  const double sl = std::sin(lean), st = std::sin(turn);
  // Half extents of the axis-aligned bounds over all poses (see make_person); across the walk,
  // h.x() + st * (h.y() + sl * h.z()), fits every area of kCrowd (tests/synth/crowd_test.cpp).
  const double bound_along = st * h.x() + h.y() + sl * h.z();
  const double bound_z = sl * h.y() + h.z();
  const Area& area = w.area;
  const double mid_along = w.along_x ? area.mid_x() : area.mid_y();
  const double mid_across = w.along_x ? area.mid_y() : area.mid_x();
  const double half_along = w.along_x ? area.half_x() : area.half_y();
  const double a = std::max(0.0, half_along - bound_along);
  // Peak speed a * rate = 1 m/s of motion time (which runs at pace * person_speed).
  const double rate = 1.0 / std::max(1e-9, a);
  const double bob =
      std::max(0.0, std::min(0.4, kCeiling - kCeilingGap - kFloorGap - 2.0 * bound_z));
  const double bob_period = std::max(0.05, 3.0 * bob);
  const double base_z = bound_z + kFloorGap;
  const double yaw0 = w.along_x ? 0.5 * kPi : 0.0;
  const double start = options.start_time, speed = options.person_speed * w.pace;
  const bool along_x = w.along_x;
  const double phase = w.phase, gait = w.gait_phase;
  person.pose_at = [=](double t) {
    const double s = motion_time(t, start, speed);
    const double along = mid_along + a * std::sin(rate * s + phase);
    const double z = base_z + 0.5 * bob * (1.0 - std::cos(2.0 * kPi * s / bob_period + gait));
    const Eigen::Vector3d p =
        along_x ? Eigen::Vector3d(along, mid_across, z) : Eigen::Vector3d(mid_across, along, z);
    const double theta = lean * std::sin(2.0 * kPi * s / 1.7 + gait);
    const double psi = turn * std::sin(2.0 * kPi * s / 2.3 + 1.0 + gait);
    const Eigen::Quaterniond q(Eigen::AngleAxisd(yaw0 + psi, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitX()));
    return SE3(q, p);
  };
  return person;
}

namespace {

/// The chair pushed once along +x by options.chair_push (SynthOptions::DynamicObjects): from
/// the corner's -x end, a rest-to-rest smoothstep 3u^2 - 2u^3 over 1.5 * push / speed seconds
/// (its peak speed, at the middle, is 1.5 * push / duration = speed), then still.
void set_pushed_chair_motion(SceneObject& chair, const SynthOptions::DynamicObjects& options) {
  const Eigen::Vector3d h = chair.half_extents;
  const double push = options.chair_push, start = options.start_time;
  const double duration = options.chair_speed > 0.0 ? 1.5 * push / options.chair_speed : 0.0;
  const double x0 = kChairArea.x0 + h.x(), y = kChairArea.mid_y();
  chair.pose_at = [=](double t) {
    double u = duration > 0.0 ? std::clamp((t - start) / duration, 0.0, 1.0) : 0.0;
    u = u * u * (3.0 - 2.0 * u);
    return SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(x0 + push * u, y, h.z()));
  };
}

}  // namespace

SceneObject make_chair(const SynthOptions::DynamicObjects& options) {
  SceneObject chair;
  chair.class_name = "chair";
  chair.motion = MotionKind::kSlide;
  const Eigen::Vector3d h = options.chair_scale * Eigen::Vector3d(0.25, 0.25, 0.45);
  chair.half_extents = h;
  if (options.chair_push > 0.0) {
    set_pushed_chair_motion(chair, options);
    return chair;
  }
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

namespace mcslam::synth {

double SynthOptions::DynamicObjects::max_chair_push(double chair_scale) {
  // The chair (half side 0.25 m * scale, not turning) from one x end of its corner to the other.
  return std::max(0.0, 2.0 * detail::kChairArea.half_x() - 0.5 * chair_scale);
}

}  // namespace mcslam::synth
