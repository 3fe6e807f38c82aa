#include "mapping/key_marks.hpp"

#include <algorithm>
#include <bit>

namespace mcslam::mapping::detail {

namespace {

std::uint64_t pack(const octomap::OcTreeKey& k) {
  return (static_cast<std::uint64_t>(k[0]) << 32) | (static_cast<std::uint64_t>(k[1]) << 16) |
         static_cast<std::uint64_t>(k[2]);
}

/// Fibonacci hashing: the product's top `bits` bits index a table of 2^bits slots.
std::size_t hash(std::uint64_t packed, int bits) {
  return static_cast<std::size_t>((packed * 0x9E3779B97F4A7C15ull) >> (64 - bits));
}

}  // namespace

KeyMarks::KeyMarks() : slots_(std::size_t{1} << 16), bits_(16) {}

void KeyMarks::set_window(const octomap::OcTreeKey& lo, const octomap::OcTreeKey& hi) {
  nx_ = ny_ = nz_ = 0;
  if (hi[0] < lo[0] || hi[1] < lo[1] || hi[2] < lo[2]) return;
  const std::size_t nx = std::size_t{hi[0]} - lo[0] + 1, ny = std::size_t{hi[1]} - lo[1] + 1,
                    nz = std::size_t{hi[2]} - lo[2] + 1;
  if (nx * ny * nz > kMaxWindowCells) return;
  // Every cell is 0 here (clear() zeroes what was marked), new ones too.
  if (cells_.size() < nx * ny * nz) cells_.resize(nx * ny * nz, 0);
  lo_ = lo;
  nx_ = nx;
  ny_ = ny;
  nz_ = nz;
}

std::size_t KeyMarks::find(std::uint64_t packed) const {
  const std::size_t mask = slots_.size() - 1;
  std::size_t i = hash(packed, bits_);
  while (slots_[i].generation == generation_ && slots_[i].key != packed) i = (i + 1) & mask;
  return i;
}

KeyMarks::Marked KeyMarks::mark_in_table(const octomap::OcTreeKey& key, std::uint8_t role) {
  const std::uint64_t packed = pack(key);
  Slot& slot = slots_[find(packed)];
  if (slot.generation == generation_) return add_role(slot.entry, role);
  const std::size_t entry = entries_.size();
  slot = {packed, static_cast<std::uint32_t>(entry), generation_};
  entries_.push_back({key, role, 0, 0, 0, 0});
  ++in_table_;
  if (2 * in_table_ > slots_.size()) grow();  // at most half full: short probes
  return {entry, true};
}

std::uint8_t KeyMarks::roles(const octomap::OcTreeKey& key) const {
  const auto entry = find_entry(key);
  return entry ? entries_[*entry].roles : std::uint8_t{0};
}

std::optional<std::size_t> KeyMarks::find_entry(const octomap::OcTreeKey& key) const {
  const std::size_t cell = window_cell(key);
  if (cell != kNoCell) {
    if (cells_[cell] == 0) return std::nullopt;
    return cells_[cell] - 1;
  }
  const Slot& slot = slots_[find(pack(key))];
  if (slot.generation != generation_) return std::nullopt;
  return slot.entry;
}

void KeyMarks::grow() {
  slots_.assign(2 * slots_.size(), Slot{});
  ++bits_;
  generation_ = 1;
  for (std::size_t e = 0; e < entries_.size(); ++e) {
    if (window_cell(entries_[e].key) != kNoCell) continue;
    const std::uint64_t packed = pack(entries_[e].key);
    slots_[find(packed)] = {packed, static_cast<std::uint32_t>(e), generation_};
  }
}

void KeyMarks::begin_crossings(std::uint8_t role, std::uint8_t counted) {
  crossing_role_ = role;
  const std::size_t words = (nx_ * ny_ * nz_ + 63) / 64;
  crossed_bits_.assign(words, 0);
  counted_bits_.assign(words, 0);
  if (words == 0) return;
  for (const Entry& e : entries_) {
    const std::size_t cell = window_cell(e.key);
    if ((e.roles & counted) != 0 && cell != kNoCell)
      counted_bits_[cell >> 6] |= std::uint64_t{1} << (cell & 63);
  }
}

void KeyMarks::end_crossings() {
  for (std::size_t w = 0; w < crossed_bits_.size(); ++w) {
    for (std::uint64_t bits = crossed_bits_[w]; bits != 0; bits &= bits - 1) {
      const std::size_t cell = 64 * w + static_cast<std::size_t>(std::countr_zero(bits));
      std::uint32_t& slot = cells_[cell];
      if (slot != 0) {
        add_role(slot - 1, crossing_role_);
        continue;
      }
      const std::size_t x = cell % nx_, y = cell / nx_ % ny_, z = cell / (nx_ * ny_);
      const octomap::OcTreeKey key(static_cast<octomap::key_type>(lo_[0] + x),
                                   static_cast<octomap::key_type>(lo_[1] + y),
                                   static_cast<octomap::key_type>(lo_[2] + z));
      slot = static_cast<std::uint32_t>(entries_.size() + 1);
      entries_.push_back({key, crossing_role_, 0, 0, 0, 0});
    }
  }
  crossed_bits_.clear();
  counted_bits_.clear();
}

void KeyMarks::clear() {
  for (const Entry& e : entries_) {
    const std::size_t cell = window_cell(e.key);
    if (cell != kNoCell) cells_[cell] = 0;
  }
  nx_ = ny_ = nz_ = 0;
  entries_.clear();
  in_table_ = 0;
  if (++generation_ == 0) {  // wrapped: no slot may look used
    std::fill(slots_.begin(), slots_.end(), Slot{});
    generation_ = 1;
  }
}

}  // namespace mcslam::mapping::detail
