// The occupancy map's octree walks (src/mapping/octree_walk.hpp), against OctoMap's own search.
#include "mapping/octree_walk.hpp"

#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <optional>
#include <random>
#include <vector>

namespace mcslam::mapping::detail {
namespace {

TEST(LeafFinder, FindsWhatSearchFindsForKeysInAnyOrderWhileTheTreeGrows) {
  octomap::OcTree tree(0.05);
  std::mt19937 rng(11);
  // Keys around the centre, as a keyframe's are: runs along rays (neighbours), jumps, repeats,
  // keys in unknown space; some updates between searches grow the tree (and expand pruned
  // leaves) under the finder's remembered path.
  std::uniform_int_distribution<int> coord(32768 - 40, 32768 + 40), step(-1, 1), pick(0, 9);
  // An aligned block of 8^3 voxels in one state, pruned into one leaf 3 levels up.
  const auto block_key = [](int x, int y, int z) {
    return octomap::OcTreeKey(static_cast<octomap::key_type>(32768 + x),
                              static_cast<octomap::key_type>(32768 + y),
                              static_cast<octomap::key_type>(32768 + z));
  };
  const auto fill_block = [&tree, &block_key] {
    for (int x = 0; x < 8; ++x)
      for (int y = 0; y < 8; ++y)
        for (int z = 0; z < 8; ++z) tree.setNodeValue(block_key(x, y, z), -2.0f, true);
    tree.updateInnerOccupancy();
    tree.prune();
  };
  fill_block();
  std::optional<LeafFinder> finder(std::in_place, tree);
  octomap::OcTreeKey key(32768, 32768, 32768);
  std::size_t found = 0, unknown = 0, pruned = 0;
  for (int i = 0; i < 200000; ++i) {
    const int what = pick(rng);
    if (what == 0) {
      key = octomap::OcTreeKey(coord(rng), coord(rng), coord(rng));
    } else if (what == 9) {  // in the block
      key = block_key(pick(rng) % 8, pick(rng) % 8, pick(rng) % 8);
    } else if (what < 8) {
      for (int a = 0; a < 3; ++a) key[a] = static_cast<octomap::key_type>(key[a] + step(rng));
    }
    if (pick(rng) < 3) tree.updateNode(key, what < 5 ? -0.4f : 0.85f, true);
    if (i % 50000 == 49999) {  // pruning deletes nodes: a new finder after it
      fill_block();
      finder.emplace(tree);
    }
    const octomap::OcTreeNode* expected = tree.search(key);
    ASSERT_EQ(finder->find(key), expected) << "key " << key[0] << " " << key[1] << " " << key[2];
    (expected != nullptr ? found : unknown) += 1;
    if (expected != nullptr && i % 16 == 0) {  // the found node's depth: the least that finds it
      unsigned depth = 1;
      while (tree.search(key, depth) != expected) ++depth;
      ASSERT_EQ(finder->depth(), static_cast<int>(depth));
      pruned += depth < tree.getTreeDepth() ? 1 : 0;
    }
  }
  EXPECT_GT(found, 10000u);
  EXPECT_GT(unknown, 10000u);
  EXPECT_GT(pruned, 0u);  // leaves above the finest depth were met
  const octomap::OcTree empty(0.05);
  EXPECT_EQ(LeafFinder(empty).find(key), nullptr);
}

}  // namespace
}  // namespace mcslam::mapping::detail
