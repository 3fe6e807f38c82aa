// The keyframe database: an inverted index whose query scores equal place::score, best first,
// with erase, replace, a minimum score, a skip predicate and a result limit.
#include "mcslam/place/database.hpp"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "place/descriptors.hpp"

namespace mcslam::place {
namespace {

using test::image;
using test::Training;

struct Fixture {
  Training t;
  Vocabulary voc;
  std::vector<BowVector> places;  // one view of each of the 10 places
  Fixture() : voc(make()) {
    std::mt19937_64 rng(21);
    for (int p = 0; p < 10; ++p)
      places.push_back(voc.transform(image(t.protos, 10 * p, 10 * p + 10, 4, rng)).bow);
  }
  Vocabulary make() const {
    VocabularyOptions o;
    o.branching = 5;
    o.depth = 3;
    return Vocabulary::train(t.images, o);
  }
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

TEST(Database, QueryFindsTheSamePlaceFirstWithExactScores) {
  const Fixture& f = fixture();
  Database db(f.voc.words());
  for (std::size_t p = 0; p < f.places.size(); ++p) db.add(100 + p, f.places[p]);
  EXPECT_EQ(db.size(), 10u);
  std::mt19937_64 rng(77);
  for (int p = 0; p < 10; ++p) {
    const BowVector q = f.voc.transform(image(f.t.protos, 10 * p, 10 * p + 10, 4, rng)).bow;
    const auto results = db.query(q, 0);
    ASSERT_FALSE(results.empty());
    EXPECT_EQ(results.front().id, 100u + static_cast<unsigned>(p));
    for (std::size_t k = 0; k < results.size(); ++k) {
      EXPECT_NEAR(results[k].score, score(q, f.places[results[k].id - 100]), 1e-12);
      EXPECT_GT(results[k].shared_words, 0);
      if (k > 0) {
        EXPECT_GE(results[k - 1].score, results[k].score);
      }
    }
  }
}

TEST(Database, EraseReplaceLimitsAndSkip) {
  const Fixture& f = fixture();
  Database db(f.voc.words());
  EXPECT_TRUE(db.query(f.places[0], 0).empty());
  for (std::size_t p = 0; p < f.places.size(); ++p) db.add(p, f.places[p]);
  const BowVector& q = f.places[3];
  EXPECT_EQ(db.query(q, 1).size(), 1u);
  EXPECT_EQ(db.query(q, 1).front().id, 3u);
  EXPECT_NEAR(db.query(q, 1).front().score, 1.0, 1e-12);
  for (const auto& r : db.query(q, 0, 0.5)) EXPECT_GE(r.score, 0.5);
  const auto skipped = db.query(q, 0, 0.0, [](EntryId id) { return id == 3; });
  for (const auto& r : skipped) EXPECT_NE(r.id, 3u);
  db.erase(3);
  EXPECT_FALSE(db.contains(3));
  EXPECT_EQ(db.size(), 9u);
  for (const auto& r : db.query(q, 0)) EXPECT_NE(r.id, 3u);
  db.erase(3);   // erasing twice is harmless
  db.add(5, q);  // replaces entry 5's vector
  EXPECT_EQ(db.size(), 9u);
  EXPECT_EQ(db.query(q, 1).front().id, 5u);
  EXPECT_TRUE(db.query(f.places[5], 0, 0.99).empty()) << "entry 5 no longer holds place 5";
  // Words beyond the vocabulary are ignored, not a crash.
  db.add(42, {{static_cast<WordId>(f.voc.words() + 10), 1.0}});
  EXPECT_TRUE(db.query({{static_cast<WordId>(f.voc.words() + 10), 1.0}}, 0).empty());
}

}  // namespace
}  // namespace mcslam::place
