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

/// The camera's path through the room: kWander looks mostly at the +x wall and its objects (the
/// default); kLoop goes round the room once every SynthOptions::loop_period seconds (at speed 1)
/// looking outwards, so that it sees every wall and comes back to where it started, with the
/// same view (for loop closing); kOrbit goes round the objects on a 3.5 x 3 m ellipse looking
/// in at the room's centre (with room_scale >= 2, so that the walls fit round it), a lap of
/// about 20 m.
enum class CameraPath { kWander, kLoop, kOrbit };

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
  CameraPath path = CameraPath::kWander;
  /// Duration of one lap of CameraPath::kLoop at speed 1 (seconds).
  double loop_period = 24.0;
  /// Scales the room's floor plan (6 x 5 m at 1; the height, objects and camera path stay):
  /// at 2 the walls are 5-6 m from the loop path, beyond the Kinect-like depth range of
  /// depth_noise (4.5 m), so that their features have no depth and odometry drifts as it does
  /// in a large real room.
  double room_scale = 1.0;
  /// Standard deviation of the per-frame Gaussian RGB noise, in grey levels (0 disables it).
  double rgb_noise_sigma = 2.0;
  /// Rolling-shutter readout time in seconds (first to last row), in [-0.1, 0.1]; 0 renders a
  /// global shutter, a negative time reads the rows bottom to top. When not 0, frame i's row r
  /// (colour and registered depth alike, as for a Kinect-like sensor that reads both with the same
  /// row timing) is rendered with the camera pose at t + (r + 0.5 - height / 2) / height *
  /// readout_time on the same camera path (t = i / fps; see Renderer::render with a pose function);
  /// the ground-truth pose of the frame stays the pose at t (the middle of the readout).
  double readout_time = 0.0;

  /// Moving objects for dynamic-scene tests: "people" that move freely in 3D (one by default, up
  /// to kMaxPeople: a crowd) and a "chair" that slides on the floor (see make_room_scene).
  /// Disabled by default; then the scene is exactly the static room.
  struct DynamicObjects {
    /// Valid range of people.
    static constexpr int kMaxPeople = 6;
    /// Valid range of person_scale and chair_scale (the chair has less room to slide in).
    static constexpr double kMinScale = 0.3;
    static constexpr double kMaxPersonScale = 1.6;
    static constexpr double kMaxChairScale = 1.4;
    /// Valid range of person_speed and chair_speed.
    static constexpr double kMaxSpeed = 3.0;
    /// Seconds over which each object's motion ramps up smoothly from rest after start_time.
    static constexpr double kRampTime = 1.0;

    bool enabled = false;
    bool person = true;  ///< add the people (when enabled); false is the same as people = 0
    bool chair = true;   ///< add the chair (when enabled)
    /// How many people walk through the room, 0 .. kMaxPeople (when enabled and person): person 1
    /// is the original one; persons 2 .. 6 are the crowd of make_room_scene.
    int people = 1;
    /// How many of the people the oracle detector misses, 0 .. people: the last ones (persons
    /// people - undetected_people + 1 .. people) never get a box in oracle_detections (nor in
    /// detections.json), though their pixels are labelled like everyone else's.
    int undetected_people = 0;
    /// Time scale of the people's motion: person 1's peak horizontal speed in m/s (the vertical
    /// bobbing and tilting speed up by the same factor; each crowd person walks at its own
    /// multiple of it); 0 keeps them still.
    double person_speed = 1.0;
    /// Time scale of the chair's motion: its peak speed on the floor in m/s.
    double chair_speed = 0.5;
    /// 0: the chair slides back and forth for ever (below). > 0: it is pushed once, straight
    /// along +x by this many metres (peak speed chair_speed, smoothly from rest to rest, no
    /// turning), and then stands still: the case of a map whose obstacle moved, with a first
    /// place that must become free and a final one that must be occupied. At most
    /// max_chair_push(chair_scale) (what the chair's corner of the room leaves).
    double chair_push = 0.0;
    /// Size factors of person 1 (0.5 x 0.35 x 1.7 m at 1) and the chair (0.5 x 0.5 x 0.9 m). The
    /// crowd (persons 2 .. 6) keeps its own sizes: their paths are fitted between the camera and
    /// the furniture, with no room to grow.
    double person_scale = 1.0;
    double chair_scale = 1.0;
    /// Scene time (seconds) at which all objects start moving; before it they are static.
    double start_time = 1.0;

    /// The number of people in the scene: people when enabled and person, else 0.
    int people_in_scene() const { return enabled && person ? people : 0; }
    /// The longest chair_push the chair's corner leaves at chair_scale (1.21 m at scale 1).
    static double max_chair_push(double chair_scale);
  };
  DynamicObjects dynamic;

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

/// How an object moves (ground truth for dynamic-object tests):
///  - kStatic: never moves;
///  - kFree: moves freely in 3D (translation in x, y and z, and rotation about horizontal axes), so
///    the heights of its points above the floor change;
///  - kSlide: slides on the floor (translation in x and y, rotation about the vertical z axis
///    only): the heights of its points above the floor never change.
enum class MotionKind { kStatic, kFree, kSlide };

/// "static", "free" or "slide".
const char* motion_kind_name(MotionKind kind);

/// An object, rendered as a textured box of half_extents centred at the origin of its frame o.
/// Faces are numbered 2 * axis + (positive side ? 1 : 0) (axis 0 = x, 1 = y, 2 = z); face f uses
/// layer f of Scene::textures[texture_id], with texture coordinates (p[(axis + 1) % 3] + h,
/// p[(axis + 2) % 3] + h) in the object frame.
struct SceneObject {
  /// A COCO class name ("dining table", "refrigerator", ..., "person", "chair"), so that an
  /// oracle detector reports it like a real one would.
  std::string class_name;
  Eigen::Vector3d half_extents = Eigen::Vector3d::Constant(0.5);
  std::function<SE3(double)> pose_at;  ///< T_w_o at scene time t
  int texture_id = 0;
  MotionKind motion = MotionKind::kStatic;
  /// Whether the oracle detector (synth::oracle_detections) reports it; false for the people it
  /// misses (SynthOptions::DynamicObjects::undetected_people).
  bool detectable = true;

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

/// The room scene with its procedural textures (deterministic from options.seed,
/// options.texture and options.dynamic; the camera options are not used). Throws InputError on
/// bad options.
///
/// Static objects (indices 0-7, COCO class names): "dining table" (x 1.8-2.6, y 0.4-1.6), a
/// "microwave" on it, a "refrigerator" (x 2.35-2.85, y -0.65-0.05, 1.2 m tall) and a "tv" near the
/// +x wall, an "oven" and a "sink" by the +y wall, a "suitcase" by the -y wall and a "couch" behind
/// the camera's start.
///
/// With options.dynamic.enabled, person 1 (when people_in_scene() >= 1), the chair (when
/// requested) and then persons 2 .. people follow as objects 8, 9, ... (so person 1 is 8 and the
/// chair 9 whatever the crowd; without person 1 or the chair the later objects move up). All are
/// at rest until start_time, then their motion ramps up smoothly over kRampTime seconds and
/// continues for ever, without pauses (all motions are sums of sinusoids in the object's own
/// motion time, which runs at the object's speed factor). All stay inside the room and clear of
/// the static objects and of each other (their areas are disjoint), at every scale and speed in
/// range; person 1 and the chair stay at least 0.8 m from every camera position of camera_path
/// (at any speed), the crowd 0.4 m:
///  - "person" 1 (MotionKind::kFree): a box 0.35 (x) x 0.5 (y) x 1.7 (z) m times person_scale,
///  pacing
///    in the free area in front of the refrigerator (x 1.57-2.30, y -1.11-0.35, which the camera
///    sees when it looks straight ahead or right): a figure-of-eight walk, mainly across the view
///    (along y), whose peak horizontal speed is exactly person_speed m/s; while it walks it bobs up
///    and down (up to 0.4 m, less when the ceiling is near at large scales, at a mean vertical
///    speed of 0.67 * person_speed m/s), leans sideways (rotation about the horizontal x axis,
///    +-6 deg) and turns (+-6 deg about z). Its lowest point stays 1 cm or more above the floor.
///  - "chair" (MotionKind::kSlide): a box 0.5 x 0.5 x 0.9 m times chair_scale standing on the
///    floor (bottom exactly at z = 0) in the corner beyond the table (x 1.24-2.95, y 1.65-2.45,
///    seen when the camera looks left), sliding back and forth mainly along x (peak speed exactly
///    chair_speed m/s) and turning about the vertical axis (+-25 deg up to scale 1.2; less above,
///    so that it fits the corner: +-15 deg at 1.3, +-9 deg at 1.4, where it only slides along x).
///    It stops for an instant where it reverses (a frame may then count as not moving). With
///    chair_push > 0 it stands instead at the corner's -x end until start_time, is pushed along
///    +x by chair_push metres (a smooth rest-to-rest motion of peak speed chair_speed, taking
///    1.5 * chair_push / chair_speed seconds, without turning) and then stands still.
///  - persons 2 .. 6, the crowd (MotionKind::kFree, each with its own texture): boxes of about
///    person 1's size (fixed: person_scale is person 1's only), each walking straight back and
///    forth along its own lane at its own fixed multiple (0.6-1.0) of person_speed, from its own
///    starting point, bobbing, leaning and turning as person 1 does but out of step with it:
///     2: close in front of the camera, across the whole view (along y at x 1.12-1.55, 0.4-1.3 m
///        from the camera), so that it fills a large part of the image when it passes;
///     3: along x on the camera's right (y -1.61 to -1.15), seen at the image's right and top
///        borders when the camera looks right;
///     4: the same on the left (y 1.15-1.62, in front of the oven);
///     5: along x behind the tv (y -2.45 to -1.89), 2-3 m away;
///     6: a slim one (1.5 m) along y behind the dining table, against the +x wall.
///    A person counted in undetected_people gets detectable = false.
/// At scale 1 and default speeds, over the default 300 frames, the person is in view (at least
/// oracle_min_pixels) in 55% of the frames and the chair in 48% (the camera yaws by +-40 deg and
/// little free floor lies 0.8 m away from it), one of them or both in 94%; see the measurements of
/// tests/synth/dynamic_scene_test.cpp for other scales. With people = 3 (tests/synth/
/// crowd_test.cpp), person 2 is in view in 50% of the frames and fills 40% of the image or more
/// in 8.7% (57% at most), and person 3 is in view in 32%, always touching the image border.
Scene make_room_scene(const SynthOptions& options);

/// The camera path: T_w_c for frames i = 0 .. frames - 1 at scene time t = i / fps, with
/// timestamps 1.0 + t. Smooth (sums of sinusoids); at speed 1 about 0.3-0.5 m/s and up to about
/// 40 deg/s, height 1.2-1.6 m, looking mostly at the +x wall and the objects (yaw +-40 deg, some
/// pitch down and roll), at least 0.8 m from every surface. Throws InputError on bad options.
Trajectory camera_path(const SynthOptions& options);

/// The camera pose of camera_path at scene time t (for any t, speed applied).
SE3 camera_pose_at(double t, double speed = 1.0);

/// The pose of CameraPath::kLoop at scene time t: an ellipse of 0.7 x 0.6 m round (0, 0) at a
/// height of 1.4 m (+-5 cm), the camera looking outwards (its heading turns once per lap) and
/// 12 deg down, with a few degrees of wobble that repeats every lap, so that lap k + 1 sees
/// what lap k saw from the same poses. At speed 1 and the default period: 0.17 m/s, 15 deg/s.
SE3 loop_pose_at(double t, double speed = 1.0, double period = 24.0);

/// The pose of CameraPath::kOrbit at scene time t: an ellipse of 3.5 x 3 m round (0, 0) at
/// 1.5 m (+-5 cm), looking at (0.3, 0, 0.6) with a few degrees of wobble that repeats every lap.
SE3 orbit_pose_at(double t, double speed = 1.0, double period = 24.0);

/// The pose of the options' path at scene time t.
SE3 path_pose_at(const SynthOptions& options, double t);

}  // namespace mcslam::synth
