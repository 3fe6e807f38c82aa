#pragma once
// A line segment detector that grows regions of pixels whose gradients share a direction and
// fits a rectangle to each (internal to the features module). It follows the method of LSD
// (R. Grompone von Gioi, J. Jakubowicz, J.-M. Morel, G. Randall, "LSD: a Line Segment
// Detector", IPOL 2012) as OpenCV runs it with standard refinement: the same gradient, the same
// alignment test, the same rectangle and the same density refinement, so its segments are
// LSD's within a fraction of a pixel. It is written for speed: integer gradients, the
// alignment test as a dot product of unit vectors instead of angles, buffers kept between
// images, no a-contrario validation (OpenCV's standard refinement does not run it either).

#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <vector>

namespace mcslam::features::detail {

class RegionLineDetector {
 public:
  /// Segments of an 8-bit grey image (CV_8UC1, at least 2x2 pixels) as (x1, y1, x2, y2) in
  /// pixel-centre coordinates, oriented like LSD's: walking from the first endpoint to the
  /// second, the brighter side is on the left (the image's y axis points down). Replaces the
  /// contents of `segments`; nothing for any other image, or one of more than 2^31 pixels.
  /// Not thread-safe: one per thread.
  void detect(const cv::Mat& gray, std::vector<cv::Vec4f>& segments);

 private:
  /// Per-pixel state of the current image. The per-pixel arrays are row-major with a frame of
  /// one undefined pixel around the image (stride width + 2), so that neighbours need no bounds
  /// checks.
  enum : std::uint8_t { kUndefined = 0, kFree = 1, kUsed = 2 };

  struct Rect {
    double x1 = 0.0, y1 = 0.0, x2 = 0.0, y2 = 0.0;
    double width = 0.0;
  };

  void compute_gradients(const cv::Mat& gray);
  void order_pixels();
  /// Grows the region of `seed` with the alignment tolerance cos_tolerance into region_.
  void grow(int seed, double cos_tolerance);
  /// The rectangle of the pixels in region_ (weighted by gradient magnitude), its main axis
  /// oriented like the region's mean level-line direction (region_x_, region_y_). False when
  /// degenerate.
  bool fit_rect(Rect& rect) const;
  double density(const Rect& rect) const;
  /// LSD's standard refinement of region_ when its rectangle is too sparsely filled: regrow
  /// from the seed with a tolerance from the angles near it, then shrink the region's radius
  /// around the seed. False when the region disappears.
  bool refine(Rect& rect);
  bool shrink(Rect& rect);

  int index(int x, int y) const { return (y + 1) * stride_ + x + 1; }
  int x_of(int i) const { return i % stride_ - 1; }
  int y_of(int i) const { return i / stride_ - 1; }

  int width_ = 0;
  int height_ = 0;
  int stride_ = 0;
  float max_magnitude_ = 0.0f;
  std::vector<int> defined_;  ///< pixels with a gradient above the threshold, raster order
  std::vector<float> ux_, uy_, magnitude_;
  std::vector<std::uint8_t> state_;
  std::vector<int> order_;
  std::vector<int> bin_start_;
  std::vector<int> region_;
  double region_x_ = 0.0, region_y_ = 0.0;  ///< sum of the region's unit level-line vectors
};

}  // namespace mcslam::features::detail
