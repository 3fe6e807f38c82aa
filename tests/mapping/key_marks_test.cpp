// The per-keyframe voxel marks of the occupancy map's integration, against std::map.
#include "mapping/key_marks.hpp"

#include <gtest/gtest.h>

#include <map>
#include <random>
#include <tuple>
#include <utility>
#include <vector>

namespace mcslam::mapping::detail {
namespace {

using Key = std::tuple<int, int, int>;

octomap::OcTreeKey key_of(const Key& k) {
  return octomap::OcTreeKey(static_cast<octomap::key_type>(std::get<0>(k)),
                            static_cast<octomap::key_type>(std::get<1>(k)),
                            static_cast<octomap::key_type>(std::get<2>(k)));
}

TEST(KeyMarks, HoldsTheSameRolesAsAMapAcrossGrowthWindowsAndClears) {
  KeyMarks marks;
  std::mt19937 rng(7);
  // Keys around the octree's centre (32768), as a keyframe's voxels are, some marked many times.
  std::uniform_int_distribution<int> coord(32768 - 60, 32768 + 60);
  std::uniform_int_distribution<int> role_bit(0, 3);
  // Round by round: no window; a window over part of the keys (the rest in the table, which
  // grows); the whole range; a window whose box is too large (the table alone); part again,
  // moved.
  const std::vector<std::pair<Key, Key>> windows = {
      {{1, 1, 1}, {0, 0, 0}},
      {{32768 - 30, 32768 - 60, 32768 - 20}, {32768 + 40, 32768 + 10, 32768 + 60}},
      {{32768 - 60, 32768 - 60, 32768 - 60}, {32768 + 60, 32768 + 60, 32768 + 60}},
      {{0, 0, 0}, {65535, 65535, 65535}},
      {{32768 - 10, 32768 - 20, 32768 - 60}, {32768 + 60, 32768 + 60, 32768 + 5}}};
  for (std::size_t round = 0; round < windows.size(); ++round) {
    marks.set_window(key_of(windows[round].first), key_of(windows[round].second));
    std::map<Key, std::uint8_t> expected;
    std::vector<Key> order;
    const int n = round == 1 || round == 3 ? 200000 : 3000;  // these grow the table
    for (int i = 0; i < n; ++i) {
      const Key k{coord(rng), coord(rng), coord(rng)};
      const auto role = static_cast<std::uint8_t>(1u << role_bit(rng));
      auto [it, inserted] = expected.emplace(k, 0);
      if (inserted) order.push_back(k);
      const bool is_new = (it->second & role) == 0;
      it->second |= role;
      const KeyMarks::Marked m = marks.mark(key_of(k), role);
      ASSERT_EQ(m.added, is_new) << "round " << round << ", mark " << i;
      ASSERT_EQ(marks.entries()[m.entry].key, key_of(k));
    }
    ASSERT_EQ(marks.entries().size(), expected.size());
    for (std::size_t e = 0; e < order.size(); ++e) {  // first-marked order, the roles of each
      EXPECT_EQ(marks.entries()[e].key, key_of(order[e]));
      EXPECT_EQ(marks.entries()[e].roles, expected[order[e]]);
      EXPECT_EQ(marks.roles(key_of(order[e])), expected[order[e]]);
    }
    EXPECT_EQ(marks.roles(key_of({1, 2, 3})), 0);  // never marked
    marks.clear();
    EXPECT_TRUE(marks.entries().empty());
    EXPECT_EQ(marks.roles(key_of(order.front())), 0) << "a cleared key is unmarked";
  }
}

TEST(KeyMarks, CrossingsGiveTheRolesAndCountsOfMarkingEachStep) {
  std::mt19937 rng(9);
  std::uniform_int_distribution<int> coord(32768 - 50, 32768 + 50), pick(0, 3);
  std::uniform_int_distribution<std::uint32_t> count(1, 5);
  constexpr std::uint8_t kRole = 1, kCounted = 16, kOther = 2;
  const std::vector<std::pair<Key, Key>> windows = {
      {{1, 1, 1}, {0, 0, 0}},  // none: every crossing marks at once
      {{32768 - 20, 32768 - 50, 32768 - 30}, {32768 + 50, 32768 + 15, 32768 + 50}},
      {{32768 - 50, 32768 - 50, 32768 - 50}, {32768 + 50, 32768 + 50, 32768 + 50}}};
  for (std::size_t round = 0; round < windows.size(); ++round) {
    KeyMarks marks, expected;  // crossings, and mark() + add_rays() at every step
    const auto lo = key_of(windows[round].first), hi = key_of(windows[round].second);
    marks.set_window(lo, hi);
    expected.set_window(lo, hi);
    const auto random_key = [&] { return key_of({coord(rng), coord(rng), coord(rng)}); };
    for (int i = 0; i < 3000; ++i) {  // marks before the crossings, some with the counted role
      const octomap::OcTreeKey k = random_key();
      const std::uint8_t role = pick(rng) == 0 ? kCounted : kOther;
      marks.mark(k, role);
      expected.mark(k, role);
    }
    marks.begin_crossings(kRole, kCounted);
    for (int i = 0; i < 200000; ++i) {
      const octomap::OcTreeKey k = random_key();
      const std::uint32_t n = count(rng);
      marks.cross(k, n);
      expected.add_rays(expected.mark(k, kRole).entry, n);
    }
    marks.end_crossings();
    ASSERT_EQ(marks.entries().size(), expected.entries().size()) << "round " << round;
    const auto inside = [&](const octomap::OcTreeKey& k) {
      return round > 0 && k[0] >= lo[0] && k[0] <= hi[0] && k[1] >= lo[1] && k[1] <= hi[1] &&
             k[2] >= lo[2] && k[2] <= hi[2];
    };
    std::size_t counted = 0;
    for (const KeyMarks::Entry& e : expected.entries()) {
      const auto found = marks.find_entry(e.key);
      ASSERT_TRUE(found.has_value());
      const KeyMarks::Entry& got = marks.entries()[*found];
      EXPECT_EQ(got.roles, e.roles);
      if ((e.roles & kCounted) != 0 || !inside(e.key)) {
        EXPECT_EQ(got.rays, e.rays);
        counted += e.rays > 0 ? 1 : 0;
      }
    }
    EXPECT_GT(counted, 100u);
  }
}

}  // namespace
}  // namespace mcslam::mapping::detail
