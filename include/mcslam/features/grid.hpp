#pragma once
// Spatial index of a frame's keypoints for fast window look-ups during projection matching.

#include <vector>

#include "mcslam/features/orb.hpp"

namespace mcslam::features {

class KeypointGrid {
 public:
  /// Nominal cell size in pixels (the actual cells divide the image evenly).
  static constexpr int kCellWidth = 64;
  static constexpr int kCellHeight = 48;

  KeypointGrid() = default;
  /// Indexes keypoints of a width x height image (level-0 coordinates). Keypoints outside the
  /// image are kept in the nearest border cell, so every keypoint can be found.
  KeypointGrid(const std::vector<Keypoint>& keypoints, int width, int height);

  /// Indices of the keypoints with |u_k - u| <= radius and |v_k - v| <= radius (a square
  /// window) whose level is in [min_level, max_level] (max_level < 0: no upper limit), in
  /// increasing index order.
  std::vector<int> query(float u, float v, float radius, int min_level = 0,
                         int max_level = -1) const;
  /// Same, into `out` (cleared first; reuses its capacity).
  void query(float u, float v, float radius, int min_level, int max_level,
             std::vector<int>& out) const;

  std::size_t size() const { return points_.size(); }
  bool empty() const { return points_.empty(); }

 private:
  struct Entry {
    float u = 0.0f;
    float v = 0.0f;
    int level = 0;
    int index = 0;
  };
  /// Sorts the indices of a query's result (each index once) in increasing order.
  void sort_indices(std::vector<int>& indices) const;

  int cols_ = 0;
  int rows_ = 0;
  float inv_cell_w_ = 0.0f;
  float inv_cell_h_ = 0.0f;
  /// Entries sorted by cell (row-major), then level, then index; cell c holds entries
  /// [cell_start_[c], cell_start_[c+1]).
  std::vector<int> cell_start_;
  std::vector<Entry> points_;
  /// The number of keypoints indexed (indices are below it).
  std::size_t num_indices_ = 0;
};

}  // namespace mcslam::features
