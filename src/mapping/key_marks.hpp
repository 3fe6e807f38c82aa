#pragma once
// The voxels one keyframe's samples touch, each with what touched it, for one integration.

// OcTreeKey.h uses uint16_t and size_t without including their headers: they come first.
// clang-format off
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>
#include <octomap/OcTreeKey.h>
// clang-format on

namespace mcslam::mapping::detail {

/// A set of octree keys with a mask of roles per key (a ray crossed it, a static sample hit it,
/// ...) and counts of the samples that did so, kept for one keyframe's integration and then
/// cleared. Keys are listed in the order they were first marked.
///
/// A keyframe touches 10^4-10^5 voxels, each many times (on Bonn crowd part1, 450 000 ray steps
/// over 55 000 voxels a keyframe): inside a window (set_window(), the keyframe's view) a key's
/// entry is found by direct indexing into a dense grid, where the steps of a ray along x are
/// neighbours in memory; outside it, in an open addressing table of the keys packed in 48 bits
/// whose slots carry the generation that wrote them. Clearing touches only the marked cells,
/// and nothing is allocated once both have grown.
class KeyMarks {
 public:
  struct Entry {
    octomap::OcTreeKey key;
    std::uint8_t roles = 0;
    std::uint32_t rays = 0;    ///< samples whose ray crossed it (add_rays)
    std::uint32_t spread = 0;  ///< samples whose hit spread reached it (count_spread)
    std::uint32_t ends = 0;    ///< samples whose free ray ends in it (count_end)
    std::uint32_t hits = 0;    ///< static samples whose point lies in it (count_hit)
  };

  /// The most cells a window may have (16 MiB of them): a larger one is not used, and its keys
  /// go to the table. A 4 m view at 5 cm fits in 160^3 = 4.1 million.
  static constexpr std::size_t kMaxWindowCells = std::size_t{1} << 22;

  KeyMarks();

  /// Keys in [lo, hi] (inclusive, per axis) are looked up in the dense grid from now on (none
  /// when the box is larger than kMaxWindowCells or empty). Call it after clear(), before
  /// marking: the marks of the keyframe before must be cleared.
  void set_window(const octomap::OcTreeKey& lo, const octomap::OcTreeKey& hi);

  struct Marked {
    std::size_t entry;  ///< the key's index in entries()
    bool added;         ///< whether any bit of the role was new to the key
  };
  /// Adds `role` (one or more bits) to the key's roles.
  Marked mark(const octomap::OcTreeKey& key, std::uint8_t role) {
    const std::size_t cell = window_cell(key);
    if (cell == kNoCell) return mark_in_table(key, role);
    std::uint32_t& slot = cells_[cell];
    if (slot != 0) return add_role(slot - 1, role);
    slot = static_cast<std::uint32_t>(entries_.size() + 1);
    entries_.push_back({key, role, 0, 0, 0, 0});
    return {entries_.size() - 1, true};
  }
  /// Adds to the counts of entry `entry` (an index of entries()).
  void add_rays(std::size_t entry, std::uint32_t n) { entries_[entry].rays += n; }
  void count_end(std::size_t entry) { ++entries_[entry].ends; }
  void count_spread(std::size_t entry) { ++entries_[entry].spread; }
  void count_hit(std::size_t entry) { ++entries_[entry].hits; }
  /// Takes `role` (one or more bits) from entry `entry`'s roles.
  void drop_role(std::size_t entry, std::uint8_t role) { entries_[entry].roles &= ~role; }
  /// Crossings: one role marked on keys many times over, where few keys need the count (a
  /// keyframe's rays cross each voxel ~8 times; only the voxels a spread hit reached weigh the
  /// rays). Between begin_crossings() and end_crossings(), cross(key, n) marks `role`: inside
  /// the window it sets the key's bit in a bitmap of the window's cells (a step touches neither
  /// the grid nor the entries) and adds n to `rays` of the keys that held `counted` when the
  /// crossings began; outside it, it marks and adds at once. end_crossings() gives the window's
  /// crossed keys their role, making their entries in the window's order (x fastest, then y,
  /// z). Roles are then those mark() would give, and `rays` those add_rays() would give on every
  /// key that held `counted` or lies outside the window (the others' are not counted).
  void begin_crossings(std::uint8_t role, std::uint8_t counted);
  void cross(const octomap::OcTreeKey& key, std::uint32_t n) {
    const std::size_t cell = window_cell(key);
    if (cell == kNoCell) {
      add_rays(mark(key, crossing_role_).entry, n);
      return;
    }
    const std::uint64_t bit = std::uint64_t{1} << (cell & 63);
    crossed_bits_[cell >> 6] |= bit;
    if ((counted_bits_[cell >> 6] & bit) != 0) entries_[cells_[cell] - 1].rays += n;
  }
  void end_crossings();

  /// The key's entry (an index of entries()), or none.
  std::optional<std::size_t> find_entry(const octomap::OcTreeKey& key) const;
  /// The key's roles (0 when unmarked).
  std::uint8_t roles(const octomap::OcTreeKey& key) const;
  /// The marked keys, in the order they were first marked.
  const std::vector<Entry>& entries() const { return entries_; }
  /// Forgets every key (keeps the memory) and the window.
  void clear();

 private:
  static constexpr std::size_t kNoCell = ~std::size_t{0};
  struct Slot {
    std::uint64_t key = 0;
    std::uint32_t entry = 0;
    std::uint32_t generation = 0;  ///< the slot is used when this is generation_
  };

  /// The key's cell in the window's grid, or kNoCell.
  std::size_t window_cell(const octomap::OcTreeKey& key) const {
    const std::size_t x = static_cast<std::uint16_t>(key[0] - lo_[0]);
    const std::size_t y = static_cast<std::uint16_t>(key[1] - lo_[1]);
    const std::size_t z = static_cast<std::uint16_t>(key[2] - lo_[2]);
    if (x >= nx_ || y >= ny_ || z >= nz_) return kNoCell;
    return (z * ny_ + y) * nx_ + x;
  }
  Marked add_role(std::size_t entry, std::uint8_t role) {
    std::uint8_t& roles = entries_[entry].roles;
    const bool added = (roles | role) != roles;
    roles |= role;
    return {entry, added};
  }
  Marked mark_in_table(const octomap::OcTreeKey& key, std::uint8_t role);
  std::size_t find(
      std::uint64_t packed) const;  ///< its slot, or the empty slot that ends its probe
  void grow();

  std::vector<Slot> slots_;  ///< 2^bits_ of them
  int bits_;
  std::uint32_t generation_ = 1;
  std::vector<std::uint32_t> cells_;  ///< the window's grid: entry + 1, 0 when unmarked
  octomap::OcTreeKey lo_{0, 0, 0};
  std::size_t nx_ = 0, ny_ = 0, nz_ = 0;  ///< the window's size; 0: none
  std::vector<Entry> entries_;
  std::size_t in_table_ = 0;  ///< entries in the table (outside the window)
  /// Crossings: a bit a window cell, crossed, and held the counted role at the start.
  std::vector<std::uint64_t> crossed_bits_, counted_bits_;
  std::uint8_t crossing_role_ = 0;
};

}  // namespace mcslam::mapping::detail
