#pragma once
// Synthetic ORB descriptors for the place tests: random prototypes ("landmarks"), noisy views of
// them, and "images" that show a range of prototypes.

#include <cstdint>
#include <random>
#include <set>
#include <vector>

#include "mcslam/features/orb.hpp"

namespace mcslam::place::test {

using features::OrbDescriptor;

/// `count` random 256-bit prototypes (fixed seed).
inline std::vector<OrbDescriptor> prototypes(int count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<OrbDescriptor> out(static_cast<std::size_t>(count));
  for (auto& d : out)
    for (auto& b : d.bytes) b = static_cast<std::uint8_t>(rng() & 0xFF);
  return out;
}

/// A copy of `d` with `flips` distinct random bits flipped.
inline OrbDescriptor noisy(const OrbDescriptor& d, int flips, std::mt19937_64& rng) {
  OrbDescriptor out = d;
  std::set<int> bits;
  std::uniform_int_distribution<int> bit(0, 255);
  while (static_cast<int>(bits.size()) < flips) bits.insert(bit(rng));
  for (int b : bits)
    out.bytes[static_cast<std::size_t>(b / 8)] ^= static_cast<std::uint8_t>(1u << (b % 8));
  return out;
}

/// An "image": `per` noisy views (up to 12 bits off) of each of the prototypes in [first, last).
inline std::vector<OrbDescriptor> image(const std::vector<OrbDescriptor>& protos, int first,
                                        int last, int per, std::mt19937_64& rng) {
  std::vector<OrbDescriptor> out;
  std::uniform_int_distribution<int> flips(0, 12);
  for (int p = first; p < last; ++p)
    for (int k = 0; k < per; ++k)
      out.push_back(noisy(protos[static_cast<std::size_t>(p)], flips(rng), rng));
  return out;
}

/// 100 prototypes; training image i shows prototypes [10 (i % 10), 10 (i % 10) + 10): ten
/// "places" of ten features each, seen twice over 20 images.
struct Training {
  std::vector<OrbDescriptor> protos = prototypes(100, 7);
  std::vector<std::vector<OrbDescriptor>> images;
  Training() {
    std::mt19937_64 rng(11);
    for (int i = 0; i < 20; ++i)
      images.push_back(image(protos, 10 * (i % 10), 10 * (i % 10) + 10, 4, rng));
  }
};

}  // namespace mcslam::place::test
