#pragma once
// Planes from an organised depth image: the image is cut into small cells, each cell with a good
// plane fit becomes a node, and neighbouring nodes whose planes agree are merged (agglomerative
// clustering in the manner of PEAC), then every plane is refitted on its pixels.

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/camera.hpp"

namespace mcslam::features {

struct PlaneOptions {
  /// Side of the square cells (pixels of the full image). 12 leaves a cell 4x4 samples at the
  /// default sampling (pixel_step auto: 3).
  int cell_size = 12;
  /// Planes are found from every pixel_step-th pixel of every pixel_step-th row (1: all
  /// pixels). 0, auto (the default): the sparsest sampling, at most every 3rd pixel, that
  /// leaves a cell 3 samples a side (effective_pixel_step()): 3 with the default cells, samples
  /// 6 mm apart at 1 m in a 525-px camera, where a frame's planes (floor, walls, desks) span
  /// metres and the smallest one kept (min_area_fraction) holds 680 samples at 640x480. On
  /// freiburg1_rpy, threaded, the plane thread takes about 2 ms a frame at 3 against 8-11 ms at
  /// 1; the ATE stays within the runs' spread on freiburg1_rpy, Bonn crowd part 1 and 7
  /// synthetic scenes, and part 1 from frame 240 gave 0.0096 against 0.0104 m (6 rounds
  /// interleaved with the build at every pixel, eighteenth stop). Every 4th
  /// pixel (1.3-1.7 ms) classified the synthetic pushed chair as constrained on 74 % of its
  /// moving frames against 83 % at 1-3 (docs/crowd.md, seventeenth stop).
  int pixel_step = 0;
  /// A cell is planar when the RMS distance of its points to their plane is below
  /// max(cell_tolerance, cell_tolerance_per_metre * z^2) metres (depth noise grows with z^2).
  double cell_tolerance = 0.004;
  double cell_tolerance_per_metre = 0.004;
  /// Neighbouring regions merge when their normals differ by less than this angle and each one's
  /// centroid lies within merge_distance (plus the z^2 term above) of the other's plane. (A cell
  /// joining a growing region is tested by its centroid only, its own plane being too uncertain
  /// to extrapolate; the angle allows for the normals' uncertainty, and a far, noise-dominated
  /// cell whose normal means little joins when the region's plane fits its points within half the
  /// cell tolerance.)
  double merge_angle_deg = 10.0;
  double merge_distance = 0.02;
  /// Planes with fewer pixels than min_area_fraction of the image are dropped.
  double min_area_fraction = 0.02;
  /// Planes whose final RMS fit error exceeds this (metres) are dropped.
  double max_fit_rms = 0.03;
  /// At most this many planes are kept, largest first.
  int max_planes = 8;
  /// Regions that are not connected in the image but lie on one plane (a desk on both sides of
  /// a keyboard, the floor on both sides of a chair) become one plane when their normals differ
  /// by less than coplanar_angle_deg and each centroid is within coplanar_distance of the other's
  /// plane: a plane is infinite, and the map must not hold it twice.
  double coplanar_angle_deg = 3.0;
  double coplanar_distance = 0.01;

  /// The sampling step used: pixel_step, or with 0 (auto) the largest step up to 3 that leaves
  /// cell_size / step >= 3.
  int effective_pixel_step() const;

  std::optional<std::string> check() const;
};

struct PlaneFeature {
  /// Hessian form in the camera frame: normal . p + d = 0 with |normal| = 1, oriented towards
  /// the camera (d > 0).
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double d = 1.0;
  /// Mean of the inlier points (camera frame).
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  int num_pixels = 0;
  /// RMS point-to-plane distance of the inlier points (metres).
  double rms = 0.0;
  /// Convex hull of the inlier points projected onto the plane (camera frame, counter-clockwise
  /// seen from the normal side), for display and for the plane's extent in the map.
  std::vector<Eigen::Vector3d> hull;

  /// Signed distance of a camera-frame point to the plane (positive on the camera's side).
  double distance(const Eigen::Vector3d& p_c) const { return normal.dot(p_c) + d; }
};

struct PlaneExtraction {
  std::vector<PlaneFeature> planes;
  /// CV_8SC1 of the depth image's size: the index of the plane each pixel belongs to, -1 none.
  cv::Mat labels;
};

/// The convex hull of points projected onto the plane n . p + d = 0 (|n| = 1), in the same 3D
/// frame, counter-clockwise seen from the normal side. Fewer than three points come back as they
/// are (projected).
std::vector<Eigen::Vector3d> plane_hull(const Eigen::Vector3d& normal, double d,
                                        const std::vector<Eigen::Vector3d>& points);

class PlaneExtractor {
 public:
  /// Throws mcslam::InputError when options.check() or camera.check() fails.
  PlaneExtractor(const PinholeCamera& camera, const PlaneOptions& options);
  ~PlaneExtractor();
  PlaneExtractor(PlaneExtractor&&) noexcept;
  PlaneExtractor& operator=(PlaneExtractor&&) noexcept;

  /// Whether extract() labels the pixels.
  enum class Labels {
    kFull,  ///< PlaneExtraction::labels covers the depth image
    /// labels stays empty. With pixel_step > 1 this skips labelling every pixel of the full image
    /// from its samples, about a third of the extraction's time at 2 (freiburg1_rpy); num_pixels is
    /// then the planes' samples times pixel_step^2, and planes of nearly equal size may come in
    /// the other order.
    kNone,
  };

  /// Planes of a CV_32FC1 depth image in metres (0 or non-finite = missing) of the camera's size;
  /// any other input yields no planes. Deterministic and thread-safe (calls on one extractor
  /// take turns: they share its scratch buffers).
  PlaneExtraction extract(const cv::Mat& depth, Labels labels = Labels::kFull) const;

  const PlaneOptions& options() const { return options_; }

 private:
  struct Workspace;
  PinholeCamera camera_;
  PlaneOptions options_;
  std::unique_ptr<Workspace> workspace_;
};

}  // namespace mcslam::features
