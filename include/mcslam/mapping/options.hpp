#pragma once
// Settings of the dense occupancy map (the `mapping.` settings): the octree's resolution, the
// depth sensor's range and noise, the log-odds of a hit and a miss, the sampling of keyframe
// depth and the height band of the 2D grid.

#include <optional>
#include <string>

#include "mcslam/core/camera.hpp"

namespace mcslam::mapping {

struct OccupancyOptions {
  /// Edge of a voxel and of a grid cell (metres). 5 cm: a person's leg or a chair leg is one or
  /// two voxels, a 10 x 10 x 3 m room is 2.4 M voxels at most (far fewer leaves: free space is
  /// pruned into large nodes).
  double resolution = 0.05;
  /// Depth (z, metres) beyond which a measurement is not an obstacle: its ray frees space up to
  /// this depth and marks nothing. Structured-light sensors (Kinect v1, Xtion) report depth well
  /// beyond 4 m, but its noise grows with z^2 (below): at 4 m it reaches 2.3 cm, half a voxel.
  double max_range = 4.0;
  /// Depth noise of a structured-light sensor, sigma_z = depth_noise_k * z^2 (metres, z in
  /// metres). Depth comes from disparity, d = f * b / z, so a disparity error sigma_d gives
  /// sigma_z = z^2 * sigma_d / (f * b): k = sigma_d / (f * b). 1.425e-3 per metre is the figure
  /// given for the Kinect v1 by Khoshelham & Elberink (2012), "Accuracy and resolution of Kinect
  /// depth data for indoor mapping applications" (Sensors 12, 1437-1454), whose random error
  /// grows with z^2 to about 4 cm at 5 m; with the Kinect's IR camera (f ~ 580 px) and baseline
  /// (b ~ 7.5 cm) it means sigma_d ~ 0.06 px, half of the 1/8-pixel step in which the sensor
  /// measures disparity. 1.4 mm at 1 m, 1.3 cm at 3 m, 2.3 cm at 4 m. 0: exact depth.
  double depth_noise_k = 1.425e-3;
  /// The hit of a measurement goes to every voxel within +-sigma_z of its point along its ray,
  /// and its free ray stops free_margin_sigmas * sigma_z before the point, so that a
  /// measurement that overshoots the surface does not free (erode) the surface's voxel.
  /// Measured on the tests' analytic room (a person walking, 12 keyframes, depth noise
  /// sigma = 1.425e-3 z^2; evaluation_test.cpp): ghost rate 0.24 % and completeness 99.6 % at 1
  /// sigma; 0.23 % and 99.7 % at 0; 0.27 % at 2; 1.8 % at 3 (the margin keeps the other
  /// keyframes' rays from clearing the voxels in front of a surface that noisy hits marked).
  /// Without the +-sigma spread: 0.01 % ghosts but 98.8 % complete (97.3 % with exact depth:
  /// surfaces seen at grazing angles are eroded by the rays that pass over them).
  double free_margin_sigmas = 1.0;
  /// A voxel that only the +-sigma spread of a keyframe's hits reached (no sample's point lies
  /// in it) is freed when its spread hits number fewer than this ratio times the samples of
  /// the same keyframe whose free ray crossed it; a direct hit always marks its voxel. The
  /// spread puts a surface's hit in its voxel when the measured point overshoots into the next
  /// one; where rays pass through a voxel far more often than points land within sigma of it,
  /// the surface is not there. Seen face-on (Gaussian depth error sigma_z, as
  /// depth_noise_k says, up to max_range, from a third of it to all of it left in a sample
  /// after the block median): the voxel holding the surface has spread/rays >= 2.3, a voxel
  /// whose centre is more than 5.5 cm (1.1 voxels) in front of it <= 0.45, only one whose centre
  /// is within 5-5.5 cm gets up to 0.68. Seen obliquely, rays aimed at the neighbouring voxels
  /// clip a voxel that holds a sliver of the surface (measured: a wall 2.5-3 m away, voxels with
  /// no direct hit, spread/rays 0.25-1 in each keyframe), so the ratio sits at the low end.
  /// Synthetic rooms (scripts/bench_mapping.sh), ghost rate / completeness: four people 1.49 %
  /// / 96.6 % at 0 (any spread hit marks its voxel, OctoMap's rule that an end point wins within
  /// a scan), 0.53 / 95.9 at 0.25, 0.34 / 95.2 at 0.5, 0.25 / 94.7 at 1; the pushed chair 1.30 /
  /// 97.5, 0.38 / 97.3, 0.24 / 97.2, 0.21 / 97.0. With noise one draw per 3 x 3 pixels (none
  /// averaged away) 2.5-4 m from a wall: ghosts 21.1 -> 1.9 % (evaluation_test.cpp).
  double spread_yield_ratio = 0.5;
  /// A static sample's hit is the tail of the depth noise when its voxel lies behind the surface:
  /// behind a surface no ray of any keyframe passes to free it, so one such hit would stay. A
  /// keyframe's hits in a voxel (direct and spread) are dropped when its samples whose point lies
  /// there number fewer than this ratio times the most in one voxel in front of it along the ray,
  /// up to 3 sigma_z nearer (the tail's reach: one voxel up to 2.9 m, two beyond). Negative (the
  /// default): the ratio a voxel whose centre lies one voxel behind the surface gets, seen face-on
  /// at max_range with Gaussian depth error sigma_z (depth_noise_k): Q(a) - Q(3a) of the samples
  /// against 1 - 2 Q(a) in the voxel holding the surface, a = resolution / (2 sigma_z), Q the
  /// normal tail: 0.187 at 5 cm and 4 m (effective_tail_yield_ratio()). Nearer, sigma_z is smaller
  /// and such a voxel gets fewer; a voxel that holds the surface gets about as many as the one in
  /// front of it or more. 0: off. Synthetic rooms (scripts/bench_mapping.sh, each keyframe
  /// integrated as it came), ghost rate / completeness off -> auto: a person walking 0.05 / 99.0 ->
  /// 0.05 / 98.9 %, four people 0.37 / 96.4 -> 0.23 / 95.5, one person without a box 1.14 / 95.8 ->
  /// 0.91 / 95.3, the pushed chair 0.24 / 99.0 -> 0.22 / 98.7. The surface voxels it empties (41 in
  /// the room with the unboxed person) hold the true surface within 3 mm of their front face, where
  /// the run's samples lie 0.8-1.9 cm nearer (the poses' error): the voxel in front keeps the
  /// surface. Comparing with the voxel behind as well (the tail in front of a surface, which rays
  /// cross) left the ghosts nearly where they were (0.21 and 0.90 %) and took completeness to 94.9
  /// and 94.7 %.
  double tail_yield_ratio = -1.0;
  /// Occupancy probabilities (OctoMap's and octomap_server's defaults): a hit adds
  /// logodds(prob_hit) = +0.85, a miss logodds(prob_miss) = -0.41, each once per keyframe and
  /// voxel; a voxel is occupied above prob_occupied. Its value is clamped to
  /// [clamp_min, clamp_max] so that the map can change: a voxel at clamp_max (+3.48) becomes
  /// free after 9 keyframes that see through it (the place a pushed chair left), one at
  /// clamp_min (-1.99) occupied after 3 keyframes that hit it.
  double prob_hit = 0.7;
  double prob_miss = 0.4;
  double prob_occupied = 0.5;
  double clamp_min = 0.12;
  double clamp_max = 0.97;
  /// Keyframe depth is sampled in blocks of pixel_step x pixel_step pixels. A sample is the
  /// median of its block's valid depths: one of them, so that a block across an edge takes one
  /// side and never a depth in between, and less noisy than one pixel (with the noise above at
  /// 3 px and a 3 sigma margin: 21 % ghost voxels from the centre pixel, 1.8 % from the median).
  /// A sample is dynamic when any pixel of its block is. The samples are integrated and stored
  /// (for rebuilds). 0, auto: the sparsest step whose samples are still at most half a voxel
  /// apart at max_range (effective_pixel_step()): at depth z a step of s pixels spans
  /// s * z / fx metres, so s = max(1, floor(resolution * fx / (2 * max_range))): 3 for a
  /// 525 px camera at 5 cm and 4 m (samples 2.3 cm apart at 4 m, 5.7 mm at 1 m), 213 x 160
  /// samples of a 640 x 480 image.
  int pixel_step = 0;
  /// Dynamic-mask pixels are grown by this many pixels (full image) before sampling: the
  /// outline of a person mixes its depth with the background's and a mask is seldom exact
  /// there. Grown pixels only free their ray; 0 keeps the masks as given.
  int mask_dilation_px = 3;
  /// Use the keyframes' dynamic and mover masks (people only free space, a pushed chair is
  /// forgotten where it was). false inserts every pixel as a static surface, as a map without
  /// object knowledge would: the ablation that measures what the masks buy (scripts/
  /// bench_mapping.sh prints both). The tracker still excludes the people either way.
  bool use_masks = true;
  /// Keep each sample's colour (3 bytes a sample) for the voxels' colours.
  bool store_colour = true;
  /// The 2D grid's height band above the floor (metres): a cell is occupied when an occupied
  /// voxel's centre lies in [floor + band_min, floor + band_max]. 0.15 m leaves out the floor
  /// and its error where it is seen farthest: at max_range (4 m) a pose 1 degree off in pitch
  /// puts the floor 7 cm high, a voxel adds up to 5 cm and the depth noise about 1 cm (measured
  /// on Bonn crowd part 1: the floor voxels seen 2-4 m away reach 0.13 m, p90; with 0.1 they
  /// made 88 of the 2443 grid cells that appeared where the first 240 frames saw free, with
  /// 0.15 8). Obstacles lower than that are not in the grid (they are in the 3D map). 1.8 m is
  /// above a mobile robot and below most ceilings and lamps.
  double band_min = 0.15;
  double band_max = 1.8;
  /// Nice value added to the mapping thread (Linux; best effort). 0 (the frame's priority) by
  /// default, measured: at 10 the frames ran faster offline (Bonn crowd part1 0.91x the frame
  /// rate without the map, against about 0.85x at 0) but then outran the local mapper, which made
  /// fewer keyframes: from frame 240, 36-44 keyframes and ATE 0.0115-0.0166 m (5 runs) against
  /// 58-62 and 0.0114-0.0119 m at 0 (3 runs). In real time the camera sets the pace and both
  /// processed 99 % of the frames. What is integrated, and in which order, does not depend on
  /// it. At most 19.
  int niceness = 0;
  /// In localisation only (`--localize`, no keyframes are made), a tracked view is integrated
  /// into the dense map (not stored) at most this often (seconds), so that it still forgets a
  /// chair that moved and sees new obstacles. 0.5 s gives the mapping thread the load it has
  /// when mapping: 2-5 keyframes a second were inserted on freiburg1_rpy and Bonn crowd part1.
  double localize_view_period = 0.5;
  /// A pose change (translation in metres, or rotation angle times max_range) below this
  /// fraction of a voxel does not rebuild the map on correct().
  double rebuild_tolerance = 0.25;
  /// Threads that rebuild the map when a correction moved its keyframes: the mapping thread
  /// and rebuild_threads - 1 helpers gather the keyframes' voxel marks in parallel, and the
  /// mapping thread applies them to the octree in the keyframes' order (the map is the same
  /// for any count). 2: the rebuild after the final bundle adjustment comes when the frames are
  /// done and every core is free; on Bonn crowd part1 it is the largest single cost of the map
  /// (0.5-0.7 s for 58 keyframes, 0.9-1.1 s for 115, one thread). At most 16.
  int rebuild_threads = 2;
  /// When keyframes are integrated into the octree. "live": each as it comes, so that the map
  /// can be read during the run (the viewer, the ROS node, Python). "at_end": each is sampled
  /// and stored as it comes, and they are all integrated together when the map is next
  /// settled (MappingWorker::wait() and finish(), OccupancyMap::integrate_pending()), with
  /// their poses then: the same final map as "live" wherever the final bundle adjustment moved
  /// a keyframe by more than rebuild_tolerance (which rebuilds the map from them: on every
  /// Bonn crowd part1 run), without the integrations that rebuild throws away (57-62 keyframes
  /// at ~34 ms each on 2 cores). "auto" is "live" here; `mcslam run` makes it "at_end" when
  /// neither a viewer watches nor the run localises (nothing reads its map before the end).
  std::string integration = "auto";

  /// The sampling step used for a camera: pixel_step, or with 0 (auto) the rule above.
  int effective_pixel_step(const PinholeCamera& camera) const;
  /// sigma_z at depth z (metres).
  double depth_sigma(double z) const { return depth_noise_k * z * z; }
  /// tail_yield_ratio, or when it is negative the ratio from the noise model (above).
  double effective_tail_yield_ratio() const;

  /// An empty optional when the settings are usable; otherwise what is wrong, naming the
  /// setting.
  std::optional<std::string> check() const;
};

}  // namespace mcslam::mapping
