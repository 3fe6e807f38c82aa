#pragma once
// Pairing colour and depth images by time, as TUM's associate.py does: of all pairs closer than
// the limit, the closest first, each image used at most once. One rule for every source (TUM
// folders, ROS 1 bags, ROS 2 recordings), so that one recording read from each gives the same
// frames.

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "mcslam/core/trajectory.hpp"
#include "mcslam/io/sequence.hpp"

namespace mcslam::io {

/// (colour index, depth index) pairs with |t_rgb - t_depth| < max_difference, chosen greedily
/// by increasing difference (ties: the lower colour, then depth index), sorted by colour index.
/// Both lists must be sorted by time.
std::vector<std::pair<std::size_t, std::size_t>> associate_stamps(const std::vector<double>& rgb,
                                                                  const std::vector<double>& depth,
                                                                  double max_difference);

/// A recording's frames (ROS 1 bag, ROS 2 recording): its colour and depth messages paired as
/// above; each frame's paths are "<path>:<topic>#<message index>". InputError naming `path`
/// when no pair exists; a warning (appended) for colour images left without depth.
struct RecordingPairs {
  std::vector<std::pair<std::size_t, std::size_t>> pairs;  ///< (colour, depth) message indices
  std::vector<FrameEntry> frames;
};
RecordingPairs pair_recording(const std::string& path, const std::string& rgb_topic,
                              const std::string& depth_topic, const std::vector<double>& rgb,
                              const std::vector<double>& depth, double max_difference,
                              std::vector<std::string>& warnings);

/// A recording's image topic as read: its name, its number of messages, its images' size.
struct RecordedImages {
  std::string topic;
  std::size_t messages = 0;
  int width = 0, height = 0;
};
/// InputError naming `path` when the colour or the depth topic has no messages, or when their
/// images differ in size (the depth must be registered to the colour camera).
void check_recorded_images(const std::string& path, const RecordedImages& rgb,
                           const RecordedImages& depth);

/// Ground truth read from messages, in time order, one pose per time stamp (the first).
void sort_by_time_unique(Trajectory& poses);

}  // namespace mcslam::io
