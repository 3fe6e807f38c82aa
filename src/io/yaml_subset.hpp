#pragma once
// Internal to the io module: a small, strict parser of the YAML subset that settings files use
// (block and flow maps and sequences, plain and quoted scalars, tags, comments, OpenCV's
// "%YAML:1.0" header). Anchors, aliases, block scalars and complex keys are rejected with a
// message naming the construct. It replaces yaml-cpp, which hangs on some malformed text; every
// input ends in a tree or an InputError in about linear time, with nesting limited to 64 levels.

#include <string>
#include <string_view>
#include <vector>

namespace mcslam::io::detail {

struct YamlEntry;

/// One parsed node. Scalars keep their text (numbers are parsed by the caller).
struct YamlNode {
  enum class Kind { kNull, kScalar, kSequence, kMap };
  Kind kind = Kind::kNull;
  int line = 1;                    // 1-based line where the node starts
  std::string tag;                 // e.g. "!!opencv-matrix" or "!foo"; empty when untagged
  std::string scalar;              // kScalar: the text, quotes removed, escapes decoded
  std::vector<YamlNode> items;     // kSequence
  std::vector<YamlEntry> entries;  // kMap, in file order

  /// kMap lookup; nullptr if absent (or not a map).
  const YamlNode* find(std::string_view key) const;
};

/// One `key: value` of a map.
struct YamlEntry {
  std::string key;
  int line = 1;  // line of the key
  YamlNode value;
};

/// Parses one YAML document. Throws InputError "<name>:<line>: YAML syntax error: <what>" on
/// anything outside the subset or invalid. Empty text (or only comments) gives a kNull node.
YamlNode parse_yaml(std::string_view text, const std::string& name);

}  // namespace mcslam::io::detail
