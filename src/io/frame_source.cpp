#include "mcslam/io/frame_source.hpp"

#include "mcslam/io/trajectory_io.hpp"

namespace mcslam::io {

RgbdImages FolderSource::load(std::size_t index, double depth_factor) const {
  return load_rgbd(sequence_.frames().at(index), depth_factor);
}

std::optional<Trajectory> FolderSource::groundtruth() const {
  if (const auto path = sequence_.groundtruth_path()) return read_tum_trajectory(*path);
  return std::nullopt;
}

}  // namespace mcslam::io
