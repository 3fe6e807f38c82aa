#pragma once
// Synthetic RGB-D world: a textured room with box-shaped objects, and the camera path through it.
//
// World frame: metres, z up; the room spans [-3, 3] x [-2.5, 2.5] x [0, 3] (floor at z = 0).
// Camera frame: x right, y down, z forward (optical axis). Scene time t is in seconds from the
// start of the sequence (frame i is at t = i / fps; its timestamp is 1.0 + t).

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/core/trajectory.hpp"

namespace mcslam::synth {

/// kRich: dense, high-contrast procedural texture everywhere (hundreds of ORB corners per view).
/// kLow: plain, nearly uniform walls/floor/boxes with only a few large shapes (posters, a rug),
/// so that corners come mostly from the geometry (for line/plane tests).
enum class TextureLevel { kRich, kLow };

struct SynthOptions {
  int width = 640;
  int height = 480;
  double fx = 525.0;
  double fy = 525.0;
  double cx = 319.5;
  double cy = 239.5;
  int frames = 300;
  double fps = 30.0;
  std::uint64_t seed = 1;
  TextureLevel texture = TextureLevel::kRich;
  /// Kinect-like depth (see RenderOptions::depth_noise): Gaussian noise with
  /// sigma(z) = 0.0012 + 0.0019 (z - 0.4)^2 m, quantisation to 1 / 5000 m, and 0 (invalid) outside
  /// [0.4, 4.5] m and next to depth discontinuities (> 0.1 m between 4-neighbours).
  bool depth_noise = false;
  /// Scales the speed of the camera along its path (0 gives a static camera).
  double speed = 1.0;
  /// Standard deviation of the per-frame Gaussian RGB noise, in grey levels (0 disables it).
  double rgb_noise_sigma = 2.0;
  /// Rolling-shutter readout time in seconds (first to last row), in [0, 0.1]; 0 renders a global
  /// shutter. When > 0, frame i's row r (colour and registered depth alike, as for a Kinect-like
  /// sensor that reads both with the same row timing) is rendered with the camera pose at
  /// t + (r + 0.5 - height / 2) / height * readout_time on the same camera path (t = i / fps; see
  /// Renderer::render with a pose function); the ground-truth pose of the frame stays the pose
  /// at t (the middle of the readout).
  double readout_time = 0.0;

  /// An empty optional when usable; otherwise a message naming the bad field.
  std::optional<std::string> check() const;
  /// The intrinsics: depth_factor 5000, bf 40, no distortion, and readout_time.
  PinholeCamera camera() const;
};

/// A procedural image in texture space with its mip pyramid. Texel (i, j) of level 0 covers
/// [i, i + 1) x [j, j + 1) * texel_size metres of the surface; level l halves the resolution.
struct Texture {
  double texel_size = 0.003;
  /// layers[k][level]: CV_8UC3 (BGR) albedo. Room surfaces use one layer; a box uses six, one per
  /// face (see SceneObject).
  std::vector<std::vector<cv::Mat>> layers;
};

/// A textured rectangle {origin + s * u_axis + t * v_axis : s in [0, size_u], t in [0, size_v]}.
/// u_axis and v_axis are orthonormal; normal() = u_axis x v_axis points to the visible side.
/// Texture coordinates (metres) are (s, t).
struct Surface {
  std::string name;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d u_axis = Eigen::Vector3d::UnitX();
  Eigen::Vector3d v_axis = Eigen::Vector3d::UnitY();
  double size_u = 1.0;
  double size_v = 1.0;
  int texture_id = 0;  ///< index into Scene::textures (layer 0)

  Eigen::Vector3d normal() const { return u_axis.cross(v_axis); }
};

/// An object, rendered as a textured box of half_extents centred at the origin of its frame o.
/// Faces are numbered 2 * axis + (positive side ? 1 : 0) (axis 0 = x, 1 = y, 2 = z); face f uses
/// layer f of Scene::textures[texture_id], with texture coordinates (p[(axis + 1) % 3] + h,
/// p[(axis + 2) % 3] + h) in the object frame.
struct SceneObject {
  std::string class_name;  ///< "box", "table", ... later also "person", "chair"
  Eigen::Vector3d half_extents = Eigen::Vector3d::Constant(0.5);
  std::function<SE3(double)> pose_at;  ///< T_w_o at scene time t
  int texture_id = 0;

  /// The 8 corners in the world frame at time t.
  std::vector<Eigen::Vector3d> corners_at(double t) const;
};

struct Scene {
  Eigen::Vector3d room_min = Eigen::Vector3d(-3.0, -2.5, 0.0);
  Eigen::Vector3d room_max = Eigen::Vector3d(3.0, 2.5, 3.0);
  /// The room: floor, ceiling, then the walls at x = min, x = max, y = min, y = max; normals point
  /// into the room.
  std::vector<Surface> surfaces;
  std::vector<SceneObject> objects;
  std::vector<std::shared_ptr<const Texture>> textures;
  /// Lambertian shading, the same for every view: shade = ambient + diffuse * max(0, n . light).
  Eigen::Vector3d light_direction = Eigen::Vector3d(0.35, 0.5, 0.8).normalized();
  double ambient = 0.6;
  double diffuse = 0.4;

  /// Euclidean distance from a world point to the nearest surface or object at time t (negative
  /// inside an object or outside the room).
  double clearance(const Eigen::Vector3d& p_w, double t) const;
};

/// The room scene with its procedural textures (deterministic from options.seed and
/// options.texture; the camera options are not used). Throws InputError on bad options.
Scene make_room_scene(const SynthOptions& options);

/// The camera path: T_w_c for frames i = 0 .. frames - 1 at scene time t = i / fps, with
/// timestamps 1.0 + t. Smooth (sums of sinusoids); at speed 1 about 0.3-0.5 m/s and up to about
/// 40 deg/s, height 1.2-1.6 m, looking mostly at the +x wall and the objects (yaw +-40 deg, some
/// pitch down and roll), at least 0.8 m from every surface. Throws InputError on bad options.
Trajectory camera_path(const SynthOptions& options);

/// The camera pose of camera_path at scene time t (for any t, speed applied).
SE3 camera_pose_at(double t, double speed = 1.0);

}  // namespace mcslam::synth
