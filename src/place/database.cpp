#include "mcslam/place/database.hpp"

#include <algorithm>

namespace mcslam::place {

Database::Database(int words) : inverted_(static_cast<std::size_t>(std::max(0, words))) {}

void Database::add(EntryId id, const BowVector& bow) {
  erase(id);
  BowVector kept;
  for (const auto& [word, weight] : bow)
    if (word < inverted_.size()) {
      inverted_[word].emplace_back(id, weight);
      kept.emplace_back(word, weight);
    }
  entries_.emplace(id, std::move(kept));
}

void Database::erase(EntryId id) {
  const auto it = entries_.find(id);
  if (it == entries_.end()) return;
  for (const auto& [word, weight] : it->second) {
    auto& list = inverted_[word];
    list.erase(std::remove_if(list.begin(), list.end(),
                              [id](const std::pair<EntryId, double>& e) { return e.first == id; }),
               list.end());
  }
  entries_.erase(it);
}

std::vector<DatabaseResult> Database::query(const BowVector& bow, std::size_t max_results,
                                            double min_score,
                                            const std::function<bool(EntryId)>& skip) const {
  std::unordered_map<EntryId, DatabaseResult> found;
  for (const auto& [word, weight] : bow) {
    if (word >= inverted_.size()) continue;
    for (const auto& [id, entry_weight] : inverted_[word]) {
      DatabaseResult& r = found[id];
      r.id = id;
      r.score += std::min(weight, entry_weight);
      ++r.shared_words;
    }
  }
  std::vector<DatabaseResult> out;
  out.reserve(found.size());
  for (const auto& [id, r] : found)
    if (r.score >= min_score && !(skip && skip(id))) out.push_back(r);
  std::sort(out.begin(), out.end(), [](const DatabaseResult& a, const DatabaseResult& b) {
    return a.score != b.score ? a.score > b.score : a.id < b.id;
  });
  if (max_results > 0 && out.size() > max_results) out.resize(max_results);
  return out;
}

}  // namespace mcslam::place
