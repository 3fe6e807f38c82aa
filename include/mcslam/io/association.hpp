#pragma once
// Pairing colour and depth images by time, as TUM's associate.py does: of all pairs closer than
// the limit, the closest first, each image used at most once. One rule for every source (TUM
// folders, ROS 1 bags, ROS 2 recordings), so that one recording read from each gives the same
// frames.

#include <cstddef>
#include <utility>
#include <vector>

namespace mcslam::io {

/// (colour index, depth index) pairs with |t_rgb - t_depth| < max_difference, chosen greedily
/// by increasing difference (ties: the lower colour, then depth index), sorted by colour index.
/// Both lists must be sorted by time.
std::vector<std::pair<std::size_t, std::size_t>> associate_stamps(const std::vector<double>& rgb,
                                                                  const std::vector<double>& depth,
                                                                  double max_difference);

}  // namespace mcslam::io
