#pragma once
// The line band descriptor (LBD; L. Zhang and R. Koch, "An efficient and robust line segment
// matching approach based on LBD descriptor and pairwise geometric consistency", JVCIR 2013),
// in its binary form, computed from one gradient image per frame (internal to the features
// module).

#include <Eigen/Core>
#include <array>
#include <opencv2/core/mat.hpp>

#include "mcslam/features/lines.hpp"

namespace mcslam::features::detail {

/// Bands of the line support region, and rows (pixels across the segment) per band: the values
/// of the paper, which found them the best trade-off between distinctiveness and cost.
constexpr int kLbdBands = 9;
constexpr int kLbdBandWidth = 7;
constexpr int kLbdRows = kLbdBands * kLbdBandWidth;

/// Describes segments of one image. set_image() computes the image's gradients once; describe()
/// then costs about (rows x segment length) gradient lookups. Not thread-safe: one per thread.
class LineBandDescriber {
 public:
  LineBandDescriber();

  /// An 8-bit grey image (CV_8UC1) of at least 3x3 pixels; the segments given to describe() are
  /// in its pixel-centre coordinates. Returns false for anything else.
  bool set_image(const cv::Mat& gray);

  /// The 256-bit descriptor of the segment start -> end. The support region is the rectangle of
  /// kLbdRows rows of pixels parallel to the segment, centred on it, as long as the segment; row
  /// k's sample at step s along the segment is the gradient of the pixel nearest to
  /// start + s d + (k - (kLbdRows - 1) / 2) n, with d the unit direction and n = d turned by
  /// +90 degrees (samples off the image count zero). Each gradient is split into its components
  /// along n and d, and each row sums, separately, their positive and negative parts, weighted
  /// by a Gaussian of the row's distance to the segment (sigma half the region's width), which
  /// plays down the rows far from the line. Band j's statistics are the mean and the standard
  /// deviation of these four sums over the rows of bands j - 1, j and j + 1, each row weighted
  /// by a Gaussian of its distance to band j's centre (sigma one band width): 8 values a band,
  /// 72 in all. The means and the deviations are each scaled to unit length, values above 0.4
  /// are clipped (a single strong edge must not dominate) and the whole is scaled to unit length
  /// again. The 256 bits compare these values between pairs of bands: the 8 values of band i
  /// against those of band j, for the 32 pairs nearest apart (all pairs 1 to 4 bands apart, then
  /// those 5 and 6 apart from the first band). The descriptor depends on the direction: the
  /// reversed segment describes the other side of the edge first.
  LineDescriptor describe(const Eigen::Vector2d& start, const Eigen::Vector2d& end) const;

  /// The 72 normalised band statistics behind describe()'s bits (for tests and measurements):
  /// band j's means of the four sums (n positive, n negative, d positive, d negative) at
  /// 8 j .. 8 j + 3 and their deviations at 8 j + 4 .. 8 j + 7.
  std::array<float, 8 * kLbdBands> statistics(const Eigen::Vector2d& start,
                                              const Eigen::Vector2d& end) const;

 private:
  /// Per row of the support region: the weighted sums of the gradient's positive and negative
  /// parts across the segment, then along it (the negative parts as magnitudes). All zero for a
  /// segment that is degenerate, not finite or longer than any image.
  using RowSums = std::array<std::array<float, 4>, kLbdRows>;
  RowSums row_sums(const Eigen::Vector2d& start, const Eigen::Vector2d& end) const;

  cv::Mat gx_;
  cv::Mat gy_;
  std::array<float, kLbdRows> row_weight_{};
  /// Weight of row k in band j's statistics, 0 outside bands j - 1 .. j + 1.
  std::array<std::array<float, kLbdRows>, kLbdBands> band_weight_{};
};

}  // namespace mcslam::features::detail
