#pragma once
// The voxels one keyframe's samples touch, each with what touched it, for one integration.

// OcTreeKey.h uses uint16_t and size_t without including their headers: they come first.
// clang-format off
#include <cstddef>
#include <cstdint>
#include <vector>
#include <octomap/OcTreeKey.h>
// clang-format on

namespace mcslam::mapping::detail {

/// A set of octree keys with a mask of roles per key (a ray crossed it, a static sample hit it,
/// ...) and counts of the samples that did so, kept for one keyframe's integration and then
/// cleared. A keyframe touches 10^4-10^5 voxels, most of them many times (the rays of nearby
/// samples cross the same voxels): an open addressing table of the keys packed in 48 bits, whose
/// slots carry the generation that wrote them, so that clearing is O(1) and nothing is allocated
/// once the table has grown. Keys are listed in the order they were first marked.
class KeyMarks {
 public:
  struct Entry {
    octomap::OcTreeKey key;
    std::uint8_t roles = 0;
    std::uint32_t rays = 0;    ///< samples whose ray crossed it (add_rays)
    std::uint32_t spread = 0;  ///< samples whose hit spread reached it (count_spread)
    std::uint32_t ends = 0;    ///< samples whose free ray ends in it (count_end)
  };

  KeyMarks();

  struct Marked {
    std::size_t entry;  ///< the key's index in entries()
    bool added;         ///< whether any bit of the role was new to the key
  };
  /// Adds `role` (one or more bits) to the key's roles.
  Marked mark(const octomap::OcTreeKey& key, std::uint8_t role);
  /// Adds to the counts of entry `entry` (an index of entries()).
  void add_rays(std::size_t entry, std::uint32_t n) { entries_[entry].rays += n; }
  void count_end(std::size_t entry) { ++entries_[entry].ends; }
  void count_spread(std::size_t entry) { ++entries_[entry].spread; }
  /// The key's roles (0 when unmarked).
  std::uint8_t roles(const octomap::OcTreeKey& key) const;
  /// The marked keys, in the order they were first marked.
  const std::vector<Entry>& entries() const { return entries_; }
  /// Forgets every key (keeps the memory).
  void clear();

 private:
  struct Slot {
    std::uint64_t key = 0;
    std::uint32_t entry = 0;
    std::uint32_t generation = 0;  ///< the slot is used when this is generation_
  };
  std::size_t find(
      std::uint64_t packed) const;  ///< its slot, or the empty slot that ends its probe
  void grow();

  std::vector<Slot> slots_;  ///< 2^bits_ of them
  std::vector<Entry> entries_;
  int bits_;
  std::uint32_t generation_ = 1;
};

}  // namespace mcslam::mapping::detail
