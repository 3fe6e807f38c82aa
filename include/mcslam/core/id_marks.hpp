#pragma once
// Marks and counts over dense ids, for the per-frame passes over landmarks and keyframes.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace mcslam {

/// Which ids the current pass has marked. The map's ids count up from 0, so a vector indexed by
/// id replaces a hash set: marking is an array write, and a new pass (clear()) is a new stamp
/// rather than a sweep. Memory: 4 bytes per id ever handed out.
class IdMarks {
 public:
  /// Starts a new pass: nothing is marked.
  void clear() {
    if (++stamp_ == 0) {  // after 2^32 passes: the old stamps could match again
      std::fill(marks_.begin(), marks_.end(), 0u);
      stamp_ = 1;
    }
  }
  /// Marks `id`; true when it was not yet marked in this pass.
  bool insert(std::uint64_t id) {
    if (id >= marks_.size()) marks_.resize(std::max<std::size_t>(id + 1, 2 * marks_.size()), 0u);
    std::uint32_t& mark = marks_[static_cast<std::size_t>(id)];
    if (mark == stamp_) return false;
    mark = stamp_;
    return true;
  }
  bool contains(std::uint64_t id) const {
    return id < marks_.size() && marks_[static_cast<std::size_t>(id)] == stamp_;
  }

 private:
  std::vector<std::uint32_t> marks_;
  std::uint32_t stamp_ = 1;
};

/// Counts per id over one pass, in a vector indexed by id (see IdMarks), with the ids counted
/// kept in the order they were first seen.
class IdCounts {
 public:
  void add(std::uint64_t id) {
    if (id >= counts_.size()) counts_.resize(std::max<std::size_t>(id + 1, 2 * counts_.size()), 0);
    if (counts_[static_cast<std::size_t>(id)]++ == 0) seen_.push_back(id);
  }
  /// The (count, id) pairs of the pass, in first-seen order; the counts start again from zero.
  std::vector<std::pair<int, std::uint64_t>> take() {
    std::vector<std::pair<int, std::uint64_t>> out;
    out.reserve(seen_.size());
    for (const std::uint64_t id : seen_) {
      int& count = counts_[static_cast<std::size_t>(id)];
      out.emplace_back(count, id);
      count = 0;
    }
    seen_.clear();
    return out;
  }

 private:
  std::vector<int> counts_;
  std::vector<std::uint64_t> seen_;
};

}  // namespace mcslam
