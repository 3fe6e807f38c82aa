#pragma once
// CRC-32 (IEEE 802.3, reflected, polynomial 0xEDB88320) as MCAP records carry it; slicing by 8.

#include <cstddef>
#include <cstdint>

namespace mcslam::rosbag2::detail {

/// Continues `crc` (0 to start) over the bytes.
std::uint32_t crc32(std::uint32_t crc, const void* data, std::size_t size);

}  // namespace mcslam::rosbag2::detail
