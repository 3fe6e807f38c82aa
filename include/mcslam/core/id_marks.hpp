#pragma once
// Marks over dense ids, for the per-frame passes that must visit each landmark once.

#include <algorithm>
#include <cstddef>
#include <cstdint>
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

}  // namespace mcslam
