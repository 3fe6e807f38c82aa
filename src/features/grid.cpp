#include "mcslam/features/grid.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>

namespace mcslam::features {
namespace {

int cell_index(float coordinate, float inv_cell, int cells) {
  const float c = std::floor(coordinate * inv_cell);
  return static_cast<int>(std::clamp(c, 0.0f, static_cast<float>(cells - 1)));
}

}  // namespace

KeypointGrid::KeypointGrid(const std::vector<Keypoint>& keypoints, int width, int height) {
  cols_ = std::max(1, static_cast<int>(std::lround(double(std::max(width, 0)) / kCellWidth)));
  rows_ = std::max(1, static_cast<int>(std::lround(double(std::max(height, 0)) / kCellHeight)));
  inv_cell_w_ = width > 0 ? static_cast<float>(cols_) / static_cast<float>(width) : 0.0f;
  inv_cell_h_ = height > 0 ? static_cast<float>(rows_) / static_cast<float>(height) : 0.0f;

  // Counting sort of the keypoints by cell.
  const std::size_t num_cells = static_cast<std::size_t>(cols_ * rows_);
  std::vector<int> cell_of(keypoints.size(), -1);
  cell_start_.assign(num_cells + 1, 0);
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    const Eigen::Vector2f& uv = keypoints[i].uv;
    if (!std::isfinite(uv.x()) || !std::isfinite(uv.y())) continue;
    const int c =
        cell_index(uv.y(), inv_cell_h_, rows_) * cols_ + cell_index(uv.x(), inv_cell_w_, cols_);
    cell_of[i] = c;
    ++cell_start_[static_cast<std::size_t>(c) + 1];
  }
  for (std::size_t c = 0; c < num_cells; ++c) cell_start_[c + 1] += cell_start_[c];
  points_.resize(static_cast<std::size_t>(cell_start_[num_cells]));
  std::vector<int> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    if (cell_of[i] < 0) continue;
    const int slot = fill[static_cast<std::size_t>(cell_of[i])]++;
    points_[static_cast<std::size_t>(slot)] = {keypoints[i].uv.x(), keypoints[i].uv.y(),
                                               keypoints[i].level, static_cast<int>(i)};
  }
  // Within a cell, by level (then index, the order the counting sort left): a query reads only
  // the levels it asks for.
  for (std::size_t c = 0; c < num_cells; ++c)
    std::stable_sort(points_.begin() + cell_start_[c], points_.begin() + cell_start_[c + 1],
                     [](const Entry& a, const Entry& b) { return a.level < b.level; });
  num_indices_ = keypoints.size();
}

std::vector<int> KeypointGrid::query(float u, float v, float radius, int min_level,
                                     int max_level) const {
  std::vector<int> out;
  query(u, v, radius, min_level, max_level, out);
  return out;
}

void KeypointGrid::query(float u, float v, float radius, int min_level, int max_level,
                         std::vector<int>& out) const {
  out.clear();
  if (points_.empty() || !(radius >= 0.0f) || !std::isfinite(u) || !std::isfinite(v)) return;
  const int c0 = cell_index(u - radius, inv_cell_w_, cols_);
  const int c1 = cell_index(u + radius, inv_cell_w_, cols_);
  const int r0 = cell_index(v - radius, inv_cell_h_, rows_);
  const int r1 = cell_index(v + radius, inv_cell_h_, rows_);
  const bool check_max = max_level >= 0;
  const auto below_min = [min_level](const Entry& e, int) { return e.level < min_level; };
  for (int r = r0; r <= r1; ++r) {
    for (int c = c0; c <= c1; ++c) {
      const std::size_t cell = static_cast<std::size_t>(r * cols_ + c);
      const auto end = points_.begin() + cell_start_[cell + 1];
      for (auto e = std::lower_bound(points_.begin() + cell_start_[cell], end, 0, below_min);
           e != end && (!check_max || e->level <= max_level); ++e) {
        if (std::abs(e->u - u) > radius || std::abs(e->v - v) > radius) continue;
        out.push_back(e->index);
      }
    }
  }
  sort_indices(out);
}

void KeypointGrid::sort_indices(std::vector<int>& indices) const {
  // A window over many cells returns hundreds of indices: set bits of a bitmap over the frame's
  // keypoints and read them back in order, instead of a comparison sort.
  constexpr std::size_t kMaxWords = 64;
  constexpr std::size_t kMinForBitmap = 32;
  const std::size_t words = (num_indices_ + 63) / 64;
  if (indices.size() < kMinForBitmap || words > kMaxWords) {
    std::sort(indices.begin(), indices.end());
    return;
  }
  std::array<std::uint64_t, kMaxWords> bits{};
  for (const int i : indices)
    bits[static_cast<std::size_t>(i) / 64] |= std::uint64_t{1} << (static_cast<unsigned>(i) % 64);
  indices.clear();
  for (std::size_t w = 0; w < words; ++w)
    for (std::uint64_t word = bits[w]; word != 0; word &= word - 1)
      indices.push_back(static_cast<int>(64 * w) + std::countr_zero(word));
}

}  // namespace mcslam::features
