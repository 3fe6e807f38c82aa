#include "mcslam/place/vocabulary.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <deque>
#include <fstream>
#include <iterator>
#include <random>
#include <set>
#include <sstream>

#include "mcslam/core/error.hpp"
#include "mcslam/io/files.hpp"

namespace mcslam::place {

using features::hamming_distance;
using features::OrbDescriptor;

namespace {

constexpr char kMagic[8] = {'M', 'C', 'S', 'L', 'V', 'O', 'C', '\0'};
constexpr std::uint32_t kFormatVersion = 1;
constexpr std::size_t kHeaderBytes = sizeof(kMagic) + 5 * sizeof(std::uint32_t);
constexpr std::size_t kNodeBytes = 32 + sizeof(std::uint32_t) + 1 + sizeof(float);
constexpr int kMaxBranching = 255;  // a node's child count is one byte in the file
constexpr int kMaxDepth = 16;

std::uint64_t fnv1a(const char* data, std::size_t size) {
  return file_checksum(std::string_view(data, size));
}

template <typename T>
void put(std::string& out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  out.append(bytes, sizeof(T));
}

template <typename T>
T get(const std::string& in, std::size_t& at) {
  T value;
  std::memcpy(&value, in.data() + at, sizeof(T));
  at += sizeof(T);
  return value;
}

/// Bitwise majority of the descriptors `members` (ties give 0).
OrbDescriptor majority(const std::vector<OrbDescriptor>& all, const std::vector<int>& members) {
  std::array<int, 256> ones{};
  for (int m : members) {
    const auto& bytes = all[static_cast<std::size_t>(m)].bytes;
    for (int b = 0; b < 256; ++b)
      ones[static_cast<std::size_t>(b)] += (bytes[b / 8] >> (b % 8)) & 1;
  }
  OrbDescriptor centre;
  const auto half = members.size();
  for (int b = 0; b < 256; ++b)
    if (2 * static_cast<std::size_t>(ones[static_cast<std::size_t>(b)]) > half)
      centre.bytes[static_cast<std::size_t>(b / 8)] |= static_cast<std::uint8_t>(1u << (b % 8));
  return centre;
}

/// k-majority clustering of `members` (indices into `all`): at most k clusters, none empty.
/// k-means++ seeding under the Hamming distance, then alternating assignment and majority
/// update until no assignment changes or `iterations` are done.
std::vector<std::vector<int>> cluster(const std::vector<OrbDescriptor>& all,
                                      const std::vector<int>& members, int k, int iterations,
                                      std::mt19937_64& rng) {
  // Distinct descriptors: fewer of them than k make one cluster each.
  std::vector<int> distinct;
  {
    std::set<std::array<std::uint8_t, 32>> seen;
    for (int m : members)
      if (seen.insert(all[static_cast<std::size_t>(m)].bytes).second) distinct.push_back(m);
  }
  std::vector<OrbDescriptor> centres;
  if (static_cast<int>(distinct.size()) <= k) {
    for (int m : distinct) centres.push_back(all[static_cast<std::size_t>(m)]);
  } else {
    std::uniform_int_distribution<std::size_t> first(0, members.size() - 1);
    centres.push_back(all[static_cast<std::size_t>(members[first(rng)])]);
    std::vector<double> d2(members.size());
    while (static_cast<int>(centres.size()) < k) {
      double total = 0.0;
      for (std::size_t i = 0; i < members.size(); ++i) {
        int best = 257;
        for (const auto& c : centres)
          best = std::min(best, hamming_distance(all[static_cast<std::size_t>(members[i])], c));
        d2[i] = static_cast<double>(best) * best;
        total += d2[i];
      }
      if (total <= 0.0) break;
      std::uniform_real_distribution<double> pick(0.0, total);
      double r = pick(rng);
      std::size_t chosen = members.size() - 1;
      for (std::size_t i = 0; i < members.size(); ++i) {
        r -= d2[i];
        if (r <= 0.0 && d2[i] > 0.0) {
          chosen = i;
          break;
        }
      }
      centres.push_back(all[static_cast<std::size_t>(members[chosen])]);
    }
  }
  std::vector<int> assignment(members.size(), -1);
  std::vector<std::vector<int>> groups;
  for (int it = 0; it < std::max(1, iterations); ++it) {
    bool changed = false;
    for (std::size_t i = 0; i < members.size(); ++i) {
      int best = 257, best_c = 0;
      for (std::size_t c = 0; c < centres.size(); ++c) {
        const int d = hamming_distance(all[static_cast<std::size_t>(members[i])], centres[c]);
        if (d < best) {
          best = d;
          best_c = static_cast<int>(c);
        }
      }
      changed = changed || assignment[i] != best_c;
      assignment[i] = best_c;
    }
    groups.assign(centres.size(), {});
    for (std::size_t i = 0; i < members.size(); ++i)
      groups[static_cast<std::size_t>(assignment[i])].push_back(members[i]);
    if (!changed && it > 0) break;
    for (std::size_t c = 0; c < centres.size(); ++c)
      if (!groups[c].empty()) centres[c] = majority(all, groups[c]);
  }
  groups.erase(std::remove_if(groups.begin(), groups.end(),
                              [](const std::vector<int>& g) { return g.empty(); }),
               groups.end());
  return groups;
}

}  // namespace

std::uint64_t file_checksum(std::string_view bytes) {
  std::uint64_t h = 14695981039346656037ULL;
  for (const char c : bytes) {
    h ^= static_cast<unsigned char>(c);
    h *= 1099511628211ULL;
  }
  return h;
}

std::optional<std::string> VocabularyOptions::check() const {
  if (branching < 2 || branching > kMaxBranching)
    return "vocabulary branching must be in 2.." + std::to_string(kMaxBranching);
  if (depth < 1 || depth > kMaxDepth)
    return "vocabulary depth must be in 1.." + std::to_string(kMaxDepth);
  if (iterations < 1) return "vocabulary iterations must be >= 1";
  return std::nullopt;
}

double score(const BowVector& a, const BowVector& b) {
  // For L1-normalised vectors: 1 - |a - b|_1 / 2 = sum over shared words of min(a_w, b_w).
  double s = 0.0;
  auto i = a.begin();
  auto j = b.begin();
  while (i != a.end() && j != b.end()) {
    if (i->first < j->first) {
      ++i;
    } else if (j->first < i->first) {
      ++j;
    } else {
      s += std::min(i->second, j->second);
      ++i;
      ++j;
    }
  }
  return s;
}

Vocabulary Vocabulary::train(const std::vector<std::vector<OrbDescriptor>>& images,
                             const VocabularyOptions& options) {
  if (auto problem = options.check()) throw InputError(*problem);
  std::vector<OrbDescriptor> all;
  for (const auto& image : images) all.insert(all.end(), image.begin(), image.end());
  if (all.empty()) throw InputError("vocabulary: no descriptors to train on");

  Vocabulary voc;
  voc.branching_ = options.branching;
  voc.depth_ = options.depth;
  voc.nodes_.push_back(Node{});
  // Breadth first, so that every node's children are contiguous.
  std::deque<std::pair<NodeId, std::vector<int>>> queue;
  std::vector<int> everything(all.size());
  for (std::size_t i = 0; i < all.size(); ++i) everything[i] = static_cast<int>(i);
  queue.emplace_back(0, std::move(everything));
  while (!queue.empty()) {
    auto [id, members] = std::move(queue.front());
    queue.pop_front();
    if (voc.nodes_[id].level >= options.depth || members.size() <= 1) continue;  // a word
    std::mt19937_64 rng(options.seed * 0x9E3779B97F4A7C15ULL + id);
    auto groups = cluster(all, members, options.branching, options.iterations, rng);
    if (groups.size() <= 1 && members.size() > 1) {
      // One distinct descriptor: nothing to split.
      bool identical = true;
      for (int m : members)
        identical = identical &&
                    all[static_cast<std::size_t>(m)] == all[static_cast<std::size_t>(members[0])];
      if (identical) continue;
    }
    voc.nodes_[id].first_child = static_cast<NodeId>(voc.nodes_.size());
    voc.nodes_[id].children = static_cast<std::uint32_t>(groups.size());
    const int level = voc.nodes_[id].level + 1;
    for (auto& g : groups) {
      Node child;
      child.descriptor = majority(all, g);
      child.level = level;
      queue.emplace_back(static_cast<NodeId>(voc.nodes_.size()), std::move(g));
      voc.nodes_.push_back(child);
    }
  }
  voc.finish();
  // IDF weights, rounded to the file's precision so that a loaded copy scores the same.
  std::vector<int> images_with(voc.words_.size(), 0);
  int n_images = 0;
  for (const auto& image : images) {
    if (image.empty()) continue;
    ++n_images;
    std::set<WordId> seen;
    for (const auto& d : image) seen.insert(voc.word_of(d));
    for (WordId w : seen) ++images_with[w];
  }
  for (std::size_t w = 0; w < voc.words_.size(); ++w) {
    const double idf = images_with[w] > 0 ? std::log(static_cast<double>(n_images) / images_with[w])
                                          : std::log(static_cast<double>(n_images));
    voc.nodes_[voc.words_[w]].weight = static_cast<float>(idf);
  }
  const std::string body = voc.serialise_body();
  voc.id_ = fnv1a(body.data(), body.size());
  return voc;
}

void Vocabulary::finish() {
  words_.clear();
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    Node& n = nodes_[i];
    for (std::uint32_t c = 0; c < n.children; ++c) nodes_[n.first_child + c].level = n.level + 1;
    if (n.children == 0) {  // a leaf; the root too when it has nothing below it
      n.word = static_cast<WordId>(words_.size());
      words_.push_back(static_cast<NodeId>(i));
    }
  }
}

NodeId Vocabulary::closest_child(NodeId parent, const OrbDescriptor& descriptor) const {
  const Node& n = nodes_[parent];
  NodeId best = n.first_child;
  int best_d = 257;
  for (std::uint32_t c = 0; c < n.children; ++c) {
    const int d = hamming_distance(descriptor, nodes_[n.first_child + c].descriptor);
    if (d < best_d) {
      best_d = d;
      best = n.first_child + c;
    }
  }
  return best;
}

WordId Vocabulary::word_of(const OrbDescriptor& descriptor) const {
  NodeId id = 0;
  while (nodes_[id].children > 0) id = closest_child(id, descriptor);
  return nodes_[id].word;
}

BowImage Vocabulary::transform(const std::vector<OrbDescriptor>& descriptors, int levels_up,
                               const std::vector<std::uint8_t>& skip) const {
  BowImage out;
  if (words_.empty()) return out;
  const int direct_level = std::max(0, depth_ - std::max(0, levels_up));
  std::map<WordId, double> bow;
  for (std::size_t i = 0; i < descriptors.size(); ++i) {
    if (i < skip.size() && skip[i] != 0) continue;
    NodeId id = 0;
    NodeId at_level = 0;
    while (nodes_[id].children > 0) {
      id = closest_child(id, descriptors[i]);
      if (nodes_[id].level <= direct_level) at_level = id;
    }
    out.direct[at_level].push_back(static_cast<int>(i));
    const Node& leaf = nodes_[id];
    if (leaf.weight > 0.0) bow[leaf.word] += leaf.weight;
  }
  double total = 0.0;
  for (const auto& [w, v] : bow) total += v;
  if (total > 0.0)
    for (const auto& [w, v] : bow) out.bow.emplace_back(w, v / total);
  return out;
}

std::string Vocabulary::serialise_body() const {
  std::string out;
  out.reserve(kHeaderBytes + nodes_.size() * kNodeBytes);
  out.append(kMagic, sizeof(kMagic));
  put<std::uint32_t>(out, kFormatVersion);
  put<std::uint32_t>(out, static_cast<std::uint32_t>(branching_));
  put<std::uint32_t>(out, static_cast<std::uint32_t>(depth_));
  put<std::uint32_t>(out, static_cast<std::uint32_t>(nodes_.size()));
  put<std::uint32_t>(out, static_cast<std::uint32_t>(words_.size()));
  for (const Node& n : nodes_) {
    out.append(reinterpret_cast<const char*>(n.descriptor.bytes.data()), 32);
    put<std::uint32_t>(out, n.first_child);
    put<std::uint8_t>(out, static_cast<std::uint8_t>(n.children));
    put<float>(out, static_cast<float>(n.weight));
  }
  return out;
}

void Vocabulary::save(const std::string& path) const {
  std::string body = serialise_body();
  put<std::uint64_t>(body, fnv1a(body.data(), body.size()));
  io::write_file_atomic(path, body);
}

Vocabulary Vocabulary::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(file_error(path, "cannot open the vocabulary file"));
  const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (data.size() < sizeof(kMagic) || std::memcmp(data.data(), kMagic, sizeof(kMagic)) != 0)
    throw InputError(file_error(path, "not an mcslam vocabulary (bad magic)"));
  if (data.size() < kHeaderBytes + sizeof(std::uint64_t))
    throw InputError(file_error(path, "truncated vocabulary file"));
  std::size_t at = sizeof(kMagic);
  const auto version = get<std::uint32_t>(data, at);
  if (version != kFormatVersion)
    throw InputError(file_error(path, "vocabulary format version " + std::to_string(version) +
                                          ", this build reads version " +
                                          std::to_string(kFormatVersion)));
  const auto branching = get<std::uint32_t>(data, at);
  const auto depth = get<std::uint32_t>(data, at);
  const auto n_nodes = get<std::uint32_t>(data, at);
  const auto n_words = get<std::uint32_t>(data, at);
  const std::size_t expected =
      kHeaderBytes + static_cast<std::size_t>(n_nodes) * kNodeBytes + sizeof(std::uint64_t);
  if (data.size() != expected)
    throw InputError(file_error(path, "vocabulary file has " + std::to_string(data.size()) +
                                          " bytes, its header announces " +
                                          std::to_string(expected) + " (truncated or corrupt)"));
  std::size_t sum_at = data.size() - sizeof(std::uint64_t);
  const auto stored = get<std::uint64_t>(data, sum_at);
  if (stored != fnv1a(data.data(), data.size() - sizeof(std::uint64_t)))
    throw InputError(file_error(path, "vocabulary checksum mismatch (corrupt file)"));
  if (branching < 2 || branching > kMaxBranching || depth < 1 || depth > kMaxDepth || n_nodes < 1)
    throw InputError(file_error(path, "vocabulary header out of range"));

  Vocabulary voc;
  voc.branching_ = static_cast<int>(branching);
  voc.depth_ = static_cast<int>(depth);
  voc.nodes_.resize(n_nodes);
  std::vector<int> parents(n_nodes, 0);
  for (std::uint32_t i = 0; i < n_nodes; ++i) {
    Node& n = voc.nodes_[i];
    std::memcpy(n.descriptor.bytes.data(), data.data() + at, 32);
    at += 32;
    n.first_child = get<std::uint32_t>(data, at);
    n.children = get<std::uint8_t>(data, at);
    n.weight = get<float>(data, at);
    if (n.children == 0) continue;
    // Children come after their parent (breadth first) and inside the node array.
    if (n.first_child <= i || n.children > branching ||
        static_cast<std::uint64_t>(n.first_child) + n.children > n_nodes)
      throw InputError(file_error(path, "vocabulary tree is malformed"));
    for (std::uint32_t c = 0; c < n.children; ++c) ++parents[n.first_child + c];
  }
  for (std::uint32_t i = 1; i < n_nodes; ++i)
    if (parents[i] != 1) throw InputError(file_error(path, "vocabulary tree is malformed"));
  voc.finish();
  for (const Node& n : voc.nodes_)
    if (n.level > voc.depth_ || !std::isfinite(n.weight) || n.weight < 0.0)
      throw InputError(file_error(path, "vocabulary tree is malformed"));
  if (voc.words_.size() != n_words)
    throw InputError(file_error(path, "vocabulary word count does not match its tree"));
  voc.id_ = fnv1a(data.data(), data.size() - sizeof(std::uint64_t));
  return voc;
}

}  // namespace mcslam::place
