#include "mcslam/synth/scene.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "dynamic.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/core/parallel.hpp"
#include "random.hpp"
#include "texture.hpp"

namespace mcslam::synth {
namespace {

constexpr double kPi = 3.141592653589793;
constexpr double kDeg = kPi / 180.0;

double wave(double amplitude, double period, double phase, double s) {
  return amplitude * std::sin(2.0 * kPi * s / period + phase);
}

void require_valid(const SynthOptions& options) {
  if (auto problem = options.check()) throw InputError("synth options: " + *problem);
}

/// What to generate for one texture: one layer per {size_u, size_v} face.
struct TextureJob {
  std::vector<std::pair<double, double>> faces;
  detail::SurfaceKind kind;
  std::uint64_t seed;
};

/// Generates the textures in parallel (each from its own seed, so the result does not depend on
/// the number of threads).
std::vector<std::shared_ptr<const Texture>> make_textures(const std::vector<TextureJob>& jobs,
                                                          TextureLevel level) {
  std::vector<std::pair<int, int>> layers;  // (job, face)
  for (std::size_t j = 0; j < jobs.size(); ++j)
    for (std::size_t f = 0; f < jobs[j].faces.size(); ++f)
      layers.emplace_back(static_cast<int>(j), static_cast<int>(f));
  std::vector<std::vector<cv::Mat>> mips(layers.size());
  parallel_for(0, static_cast<int>(layers.size()), [&](int first, int last) {
    for (int k = first; k < last; ++k) {
      const TextureJob& job = jobs[layers[k].first];
      const auto [su, sv] = job.faces[layers[k].second];
      const std::uint64_t seed = detail::hash_combine(job.seed, layers[k].second);
      mips[k] = detail::build_mips(detail::generate_texture_image(su, sv, level, job.kind, seed));
    }
  });
  std::vector<std::shared_ptr<const Texture>> textures;
  std::size_t k = 0;
  for (const TextureJob& job : jobs) {
    auto texture = std::make_shared<Texture>();
    texture->texel_size = detail::kTexelSize;
    for (std::size_t f = 0; f < job.faces.size(); ++f) texture->layers.push_back(mips[k++]);
    textures.push_back(std::move(texture));
  }
  return textures;
}

/// "1.6", "0.3", "3" (for messages).
std::string format_number(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%g", v);
  return buffer;
}

struct BoxSpec {
  const char* class_name;
  Eigen::Vector3d centre;  // of the box; z = half height for a box standing on the floor
  Eigen::Vector3d half_extents;
  double yaw_deg;
};

}  // namespace

std::optional<std::string> SynthOptions::check() const {
  auto finite = [](double v) { return std::isfinite(v); };
  if (width <= 0) return "width must be positive (got " + std::to_string(width) + ")";
  if (height <= 0) return "height must be positive (got " + std::to_string(height) + ")";
  if (!finite(fx) || fx <= 0.0) return "fx must be positive";
  if (!finite(fy) || fy <= 0.0) return "fy must be positive";
  if (!finite(cx)) return "cx must be finite";
  if (!finite(cy)) return "cy must be finite";
  if (frames <= 0) return "frames must be positive (got " + std::to_string(frames) + ")";
  if (!finite(fps) || fps <= 0.0) return "fps must be positive";
  if (!finite(speed) || speed < 0.0) return "speed must be finite and >= 0";
  if (!finite(loop_period) || loop_period <= 0.0) return "loop_period must be positive";
  if (!finite(room_scale) || room_scale < 1.0 || room_scale > 4.0)
    return "room_scale must be in [1, 4]";
  if (path == CameraPath::kOrbit && room_scale < 2.0)
    return "the orbit path needs room_scale >= 2 (it goes 3.5 m from the centre)";
  if (!finite(rgb_noise_sigma) || rgb_noise_sigma < 0.0)
    return "rgb_noise_sigma must be finite and >= 0";
  if (!finite(readout_time) || std::abs(readout_time) > 0.1)
    return "readout_time must be finite and in [-0.1, 0.1] s";
  // Checked even when disabled, so that a bad value is reported rather than silently ignored.
  using D = DynamicObjects;
  auto in = [&](double v, double lo, double hi) { return finite(v) && v >= lo && v <= hi; };
  auto range = [](double lo, double hi) {
    return " [" + format_number(lo) + ", " + format_number(hi) + "]";
  };
  if (!in(dynamic.person_speed, 0.0, D::kMaxSpeed))
    return "dynamic.person_speed must be finite and in" + range(0.0, D::kMaxSpeed) + " m/s";
  if (!in(dynamic.chair_speed, 0.0, D::kMaxSpeed))
    return "dynamic.chair_speed must be finite and in" + range(0.0, D::kMaxSpeed) + " m/s";
  if (!in(dynamic.person_scale, D::kMinScale, D::kMaxPersonScale))
    return "dynamic.person_scale must be finite and in" + range(D::kMinScale, D::kMaxPersonScale);
  if (!in(dynamic.chair_scale, D::kMinScale, D::kMaxChairScale))
    return "dynamic.chair_scale must be finite and in" + range(D::kMinScale, D::kMaxChairScale);
  if (!in(dynamic.chair_push, 0.0, D::max_chair_push(dynamic.chair_scale)))
    return "dynamic.chair_push must be finite and in" +
           range(0.0, D::max_chair_push(dynamic.chair_scale)) + " m at chair_scale " +
           format_number(dynamic.chair_scale);
  if (!finite(dynamic.start_time) || dynamic.start_time < 0.0)
    return "dynamic.start_time must be finite and >= 0 s";
  if (dynamic.people < 0 || dynamic.people > D::kMaxPeople)
    return "dynamic.people must be in [0, " + std::to_string(D::kMaxPeople) + "] (got " +
           std::to_string(dynamic.people) + ")";
  if (dynamic.undetected_people < 0 || dynamic.undetected_people > dynamic.people)
    return "dynamic.undetected_people must be in [0, dynamic.people] = [0, " +
           std::to_string(dynamic.people) + "] (got " + std::to_string(dynamic.undetected_people) +
           ")";
  return std::nullopt;
}

PinholeCamera SynthOptions::camera() const {
  PinholeCamera camera;
  camera.fx = fx;
  camera.fy = fy;
  camera.cx = cx;
  camera.cy = cy;
  camera.width = width;
  camera.height = height;
  camera.depth_factor = 5000.0;
  camera.bf = 40.0;
  camera.readout_time = readout_time;
  return camera;
}

const char* motion_kind_name(MotionKind kind) {
  switch (kind) {
    case MotionKind::kStatic:
      return "static";
    case MotionKind::kFree:
      return "free";
    case MotionKind::kSlide:
      return "slide";
  }
  return "static";
}

std::vector<Eigen::Vector3d> SceneObject::corners_at(double t) const {
  const SE3 T_w_o = pose_at(t);
  std::vector<Eigen::Vector3d> corners;
  corners.reserve(8);
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d sign((k & 1) ? 1.0 : -1.0, (k & 2) ? 1.0 : -1.0, (k & 4) ? 1.0 : -1.0);
    corners.push_back(T_w_o * Eigen::Vector3d(sign.cwiseProduct(half_extents)));
  }
  return corners;
}

double Scene::clearance(const Eigen::Vector3d& p_w, double t) const {
  double d = std::min((p_w - room_min).minCoeff(), (room_max - p_w).minCoeff());
  for (const SceneObject& object : objects) {
    const Eigen::Vector3d q = object.pose_at(t).inverse() * p_w;
    const Eigen::Vector3d e = q.cwiseAbs() - object.half_extents;
    const double outside = e.cwiseMax(0.0).norm();
    d = std::min(d, outside > 0.0 ? outside : e.maxCoeff());
  }
  return d;
}

namespace {

Surface make_surface(std::string name, const Eigen::Vector3d& origin, const Eigen::Vector3d& u,
                     const Eigen::Vector3d& v, double size_u, double size_v) {
  Surface s;
  s.name = std::move(name);
  s.origin = origin;
  s.u_axis = u;
  s.v_axis = v;
  s.size_u = size_u;
  s.size_v = size_v;
  return s;
}

/// The floor, the ceiling and the four walls of the box [lo, hi]; normals (u x v) into the room.
std::vector<Surface> room_surfaces(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  const Eigen::Vector3d size = hi - lo;
  const Eigen::Vector3d ex = Eigen::Vector3d::UnitX(), ey = Eigen::Vector3d::UnitY(),
                        ez = Eigen::Vector3d::UnitZ();
  return {
      make_surface("floor", lo, ex, ey, size.x(), size.y()),
      make_surface("ceiling", Eigen::Vector3d(lo.x(), lo.y(), hi.z()), ey, ex, size.y(), size.x()),
      make_surface("wall_x_min", lo, ey, ez, size.y(), size.z()),
      make_surface("wall_x_max", Eigen::Vector3d(hi.x(), lo.y(), lo.z()), ez, ey, size.z(),
                   size.y()),
      make_surface("wall_y_min", lo, ez, ex, size.z(), size.x()),
      make_surface("wall_y_max", Eigen::Vector3d(lo.x(), hi.y(), lo.z()), ex, ez, size.x(),
                   size.z()),
  };
}

/// The static furniture. Objects stand on the floor, mostly along the +x wall and the +-y walls
/// (where the camera looks), all at least ~1 m from the camera path. Their COCO class names
/// roughly fit their shapes, so that an oracle detector labels them as (static) objects.
std::vector<BoxSpec> furniture() {
  return {
      {"dining table", {2.2, 1.0, 0.375}, {0.4, 0.6, 0.375}, 0.0},
      {"microwave", {2.2, 1.1, 0.87}, {0.15, 0.2, 0.12}, -15.0},  // on the table
      {"refrigerator", {2.6, -0.3, 0.6}, {0.25, 0.35, 0.6}, 0.0},
      {"tv", {2.2, -1.5, 0.25}, {0.25, 0.25, 0.25}, 25.0},
      {"oven", {0.8, 2.0, 0.35}, {0.35, 0.25, 0.35}, 10.0},
      {"suitcase", {1.0, -2.0, 0.2}, {0.4, 0.3, 0.2}, -5.0},
      {"sink", {-0.9, 1.95, 0.45}, {0.3, 0.3, 0.45}, 30.0},
      {"couch", {-2.2, -1.0, 0.4}, {0.3, 0.5, 0.4}, 0.0},
  };
}

/// A scene and the texture jobs of its surfaces and objects, in order.
struct SceneBuild {
  Scene scene;
  std::vector<TextureJob> jobs;
  std::uint64_t seed = 0;

  /// Each object's texture is the next job, with one face per layer; the seeds depend only on
  /// the job's position, so adding the moving objects last leaves every other texture unchanged.
  void add_object(SceneObject object) {
    object.texture_id = static_cast<int>(jobs.size());
    TextureJob job{{}, detail::SurfaceKind::kBoxFace, detail::hash_combine(seed, jobs.size())};
    for (int f = 0; f < 6; ++f) {
      const int axis = f / 2;
      job.faces.emplace_back(2.0 * object.half_extents[(axis + 1) % 3],
                             2.0 * object.half_extents[(axis + 2) % 3]);
    }
    jobs.push_back(std::move(job));
    scene.objects.push_back(std::move(object));
  }

  /// The people and the chair of options.dynamic. Person 1 and the chair keep their indices (8
  /// and 9) and textures whatever the crowd; the other people follow them.
  void add_movers(const SynthOptions::DynamicObjects& dynamic) {
    const int people = dynamic.people_in_scene();
    const int first_undetected = people - dynamic.undetected_people + 1;
    auto add_person = [&](int number, SceneObject person) {
      person.detectable = number < first_undetected;
      add_object(std::move(person));
    };
    if (people >= 1) add_person(1, detail::make_person(dynamic));
    if (dynamic.chair) add_object(detail::make_chair(dynamic));
    for (int number = 2; number <= people; ++number)
      add_person(number, detail::make_crowd_person(number, dynamic));
  }
};

}  // namespace

Scene make_room_scene(const SynthOptions& options) {
  require_valid(options);
  SceneBuild build;
  Scene& scene = build.scene;
  for (int axis = 0; axis < 2; ++axis) {
    scene.room_min[axis] *= options.room_scale;
    scene.room_max[axis] *= options.room_scale;
  }
  scene.surfaces = room_surfaces(scene.room_min, scene.room_max);
  build.seed = detail::hash_combine(options.seed, 0x5CE7E);
  for (std::size_t i = 0; i < scene.surfaces.size(); ++i) {
    Surface& s = scene.surfaces[i];
    s.texture_id = static_cast<int>(build.jobs.size());
    const detail::SurfaceKind kind = i == 0   ? detail::SurfaceKind::kFloor
                                     : i == 1 ? detail::SurfaceKind::kCeiling
                                              : detail::SurfaceKind::kWall;
    build.jobs.push_back(
        {{{s.size_u, s.size_v}}, kind, detail::hash_combine(build.seed, build.jobs.size())});
  }
  for (const BoxSpec& spec : furniture()) {
    SceneObject object;
    object.class_name = spec.class_name;
    object.half_extents = spec.half_extents;
    const SE3 T_w_o(
        Eigen::Quaterniond(Eigen::AngleAxisd(spec.yaw_deg * kDeg, Eigen::Vector3d::UnitZ())),
        spec.centre);
    object.pose_at = [T_w_o](double) { return T_w_o; };
    build.add_object(std::move(object));
  }
  if (options.dynamic.enabled) build.add_movers(options.dynamic);
  scene.textures = make_textures(build.jobs, options.texture);
  return std::move(build.scene);
}

namespace {

/// A camera at `position` turned by yaw (about world z), then pitched down and rolled from
/// looking along world +x upright (x_c = -y_w, y_c = -z_w, z_c = +x_w).
SE3 pose_from_angles(const Eigen::Vector3d& position, double yaw, double pitch, double roll) {
  Eigen::Matrix3d R_w_c0;
  R_w_c0 << 0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0;
  const Eigen::Matrix3d R_w_c =
      (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
       Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()))
          .toRotationMatrix() *
      R_w_c0 * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return SE3(R_w_c, position);
}

}  // namespace

SE3 camera_pose_at(double t, double speed) {
  const double s = speed * t;
  const Eigen::Vector3d position(0.1 + wave(0.50, 9.0, 0.0, s) + wave(0.12, 3.7, 1.0, s),
                                 wave(0.60, 11.0, 0.5, s) + wave(0.12, 4.3, 2.0, s),
                                 1.4 + wave(0.12, 7.0, 0.3, s) + wave(0.04, 2.9, 1.1, s));
  const double yaw = (wave(36.0, 10.0, 0.0, s) + wave(5.0, 3.3, 0.4, s)) * kDeg;
  const double pitch = (12.0 + wave(6.0, 6.3, 0.7, s) + wave(2.0, 2.3, 1.9, s)) * kDeg;  // down
  const double roll = (wave(4.0, 5.1, 1.3, s) + wave(1.5, 1.9, 0.2, s)) * kDeg;
  return pose_from_angles(position, yaw, pitch, roll);
}

SE3 loop_pose_at(double t, double speed, double period) {
  const double a = 2.0 * M_PI * speed * t / period;  // lap angle
  const Eigen::Vector3d position(0.7 * std::cos(a), 0.6 * std::sin(a),
                                 1.4 + 0.05 * std::sin(3.0 * a));
  // Heading: outwards (the lap angle), with a wobble that repeats every lap.
  const double yaw = a + 8.0 * kDeg * std::sin(2.0 * a);
  const double pitch = (12.0 + 4.0 * std::sin(5.0 * a)) * kDeg;  // down
  const double roll = 3.0 * kDeg * std::sin(4.0 * a + 0.5);
  return pose_from_angles(position, yaw, pitch, roll);
}

SE3 orbit_pose_at(double t, double speed, double period) {
  const double a = 2.0 * M_PI * speed * t / period;
  const Eigen::Vector3d position(3.5 * std::cos(a), 3.0 * std::sin(a),
                                 1.5 + 0.05 * std::sin(3.0 * a));
  const Eigen::Vector3d target(0.3, 0.0, 0.6);
  // z along the view direction, x to the right (horizontal), y down; then a small wobble.
  const Eigen::Vector3d z = (target - position).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R_w_c;
  R_w_c << x, y, z;
  const Eigen::Matrix3d wobble =
      (Eigen::AngleAxisd(6.0 * kDeg * std::sin(2.0 * a), Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(3.0 * kDeg * std::sin(5.0 * a), Eigen::Vector3d::UnitX()) *
       Eigen::AngleAxisd(2.0 * kDeg * std::sin(4.0 * a + 0.5), Eigen::Vector3d::UnitZ()))
          .toRotationMatrix();
  return SE3(Eigen::Matrix3d(R_w_c * wobble), position);
}

SE3 path_pose_at(const SynthOptions& options, double t) {
  switch (options.path) {
    case CameraPath::kLoop:
      return loop_pose_at(t, options.speed, options.loop_period);
    case CameraPath::kOrbit:
      return orbit_pose_at(t, options.speed, options.loop_period);
    case CameraPath::kWander:
      break;
  }
  return camera_pose_at(t, options.speed);
}

Trajectory camera_path(const SynthOptions& options) {
  require_valid(options);
  Trajectory path;
  path.reserve(options.frames);
  for (int i = 0; i < options.frames; ++i) {
    const double t = i / options.fps;
    path.push_back({1.0 + t, path_pose_at(options, t)});
  }
  return path;
}

}  // namespace mcslam::synth
