#pragma once
// An inverted index of bag-of-words vectors (keyframes, for relocalisation and loop detection):
// per word, the entries holding it and their weight, so that a query touches only the entries
// that share a word with it. Scores are exactly place::score (the L1 score, which for
// L1-normalised vectors is the sum over shared words of the smaller weight).
//
// Not synchronised: one writer; readers hold the owner's lock.

#include <cstdint>
#include <functional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "mcslam/place/vocabulary.hpp"

namespace mcslam::place {

using EntryId = std::uint64_t;

struct DatabaseResult {
  EntryId id = 0;
  double score = 0.0;
  int shared_words = 0;
};

class Database {
 public:
  /// `words`: the vocabulary's size (word ids are below it).
  explicit Database(int words);

  /// Adds the entry, or replaces its vector when the id is already there. Words beyond the
  /// vocabulary's size are ignored.
  void add(EntryId id, const BowVector& bow);
  void erase(EntryId id);
  bool contains(EntryId id) const { return entries_.count(id) != 0; }
  std::size_t size() const { return entries_.size(); }

  /// The entries sharing at least one word with `bow` and scoring at least `min_score`, best
  /// first (ties by id), at most `max_results` of them (0: all), leaving out those for which
  /// `skip` (when given) is true.
  std::vector<DatabaseResult> query(const BowVector& bow, std::size_t max_results,
                                    double min_score = 0.0,
                                    const std::function<bool(EntryId)>& skip = {}) const;

 private:
  std::vector<std::vector<std::pair<EntryId, double>>> inverted_;  // word -> (entry, weight)
  std::unordered_map<EntryId, BowVector> entries_;
};

}  // namespace mcslam::place
