#include "mapping/key_marks.hpp"

#include <algorithm>

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

std::size_t KeyMarks::find(std::uint64_t packed) const {
  const std::size_t mask = slots_.size() - 1;
  std::size_t i = hash(packed, bits_);
  while (slots_[i].generation == generation_ && slots_[i].key != packed) i = (i + 1) & mask;
  return i;
}

KeyMarks::Marked KeyMarks::mark(const octomap::OcTreeKey& key, std::uint8_t role) {
  const std::uint64_t packed = pack(key);
  Slot& slot = slots_[find(packed)];
  if (slot.generation == generation_) {
    std::uint8_t& roles = entries_[slot.entry].roles;
    const bool added = (roles | role) != roles;
    roles |= role;
    return {slot.entry, added};
  }
  const std::size_t entry = entries_.size();
  slot = {packed, static_cast<std::uint32_t>(entry), generation_};
  entries_.push_back({key, role, 0, 0, 0});
  if (2 * entries_.size() > slots_.size()) grow();  // at most half full: short probes
  return {entry, true};
}

std::uint8_t KeyMarks::roles(const octomap::OcTreeKey& key) const {
  const Slot& slot = slots_[find(pack(key))];
  return slot.generation == generation_ ? entries_[slot.entry].roles : std::uint8_t{0};
}

void KeyMarks::grow() {
  slots_.assign(2 * slots_.size(), Slot{});
  ++bits_;
  generation_ = 1;
  for (std::size_t e = 0; e < entries_.size(); ++e) {
    const std::uint64_t packed = pack(entries_[e].key);
    slots_[find(packed)] = {packed, static_cast<std::uint32_t>(e), generation_};
  }
}

void KeyMarks::clear() {
  entries_.clear();
  if (++generation_ == 0) {  // wrapped: no slot may look used
    std::fill(slots_.begin(), slots_.end(), Slot{});
    generation_ = 1;
  }
}

}  // namespace mcslam::mapping::detail
