#include "mcslam/io/config_file.hpp"

#include <cctype>
#include <cmath>
#include <limits>

#include "io/text_util.hpp"
#include "io/yaml_subset.hpp"
#include "mcslam/core/error.hpp"

namespace mcslam::io {

namespace {

using detail::YamlNode;

std::string trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return {};
  const auto last = s.find_last_not_of(" \t\r\n");
  return s.substr(first, last - first + 1);
}

bool is_matrix_tag(const std::string& tag) {
  return tag.find("opencv-matrix") != std::string::npos;
}

// A map with rows, cols, dt and data (OpenCV's FileStorage layout), or tagged !!opencv-matrix.
bool looks_like_matrix(const YamlNode& node) {
  if (node.kind != YamlNode::Kind::kMap) return false;
  if (is_matrix_tag(node.tag)) return true;
  return node.entries.size() == 4 && node.find("rows") && node.find("cols") && node.find("dt") &&
         node.find("data");
}

}  // namespace

// Flattens a parsed YAML tree into ConfigFile's leaves.
struct ConfigFileBuilder {
  using Leaf = ConfigFile::Leaf;
  using Kind = ConfigFile::Kind;

  ConfigFile& config;

  std::string where(int line) const { return detail::at_line(config.path_, line); }

  void add(const std::string& key, Leaf leaf) {
    const int line = leaf.line;
    if (!config.leaves_.emplace(key, std::move(leaf)).second)
      throw InputError(file_error(where(line), "duplicate key '" + key + "'"));
  }

  Leaf matrix_leaf(const std::string& key, const YamlNode& node, int line) const {
    auto bad = [&](const std::string& problem) {
      return InputError(
          file_error(where(line), "key '" + key + "': malformed OpenCV matrix (" + problem + ")"));
    };
    auto integer = [&](const char* name) {
      const YamlNode* n = node.find(name);
      if (!n || n->kind != YamlNode::Kind::kScalar)
        throw bad(std::string("'") + name + "' must be an integer");
      const auto v = detail::parse_integer(trim(n->scalar));
      if (!v || *v < 0 || *v > std::numeric_limits<int>::max())
        throw bad(std::string("'") + name + "' must be a non-negative integer, got '" + n->scalar +
                  "'");
      return *v;
    };
    const long long rows = integer("rows");
    const long long cols = integer("cols");
    const YamlNode* dt = node.find("dt");
    if (!dt || dt->kind != YamlNode::Kind::kScalar)
      throw bad("'dt' must be a type such as d, f or 3f");
    const std::string type = trim(dt->scalar);
    long long channels = 1;
    if (!type.empty() && std::isdigit(static_cast<unsigned char>(type.front()))) {
      const auto digits = type.find_first_not_of("0123456789");
      channels = detail::parse_integer(type.substr(0, digits)).value_or(0);
    }
    if (channels <= 0) throw bad("bad 'dt' '" + type + "'");
    const YamlNode* data = node.find("data");
    if (!data || data->kind != YamlNode::Kind::kSequence) throw bad("'data' must be a list");
    Leaf leaf;
    leaf.kind = Kind::kMatrix;
    leaf.line = line;
    for (const YamlNode& item : data->items) {
      if (item.kind != YamlNode::Kind::kScalar) throw bad("'data' items must be numbers");
      leaf.items.push_back(item.scalar);
    }
    if (static_cast<long long>(leaf.items.size()) != rows * cols * channels)
      throw bad("rows x cols x channels = " + std::to_string(rows * cols * channels) + " but " +
                std::to_string(leaf.items.size()) + " data values");
    return leaf;
  }

  void flatten(const std::string& prefix, const YamlNode& node, int line) {
    // The top level is always a map of settings, even one that looks like a matrix.
    const bool matrix = !prefix.empty() && looks_like_matrix(node);
    if (node.kind == YamlNode::Kind::kMap && !node.entries.empty() && !matrix) {
      for (const detail::YamlEntry& entry : node.entries)
        flatten(prefix.empty() ? entry.key : prefix + "." + entry.key, entry.value, entry.line);
      return;
    }
    if (prefix.empty()) return;  // empty top-level map
    Leaf leaf;
    leaf.line = line;
    if (matrix) {
      leaf = matrix_leaf(prefix, node, line);
    } else if (node.kind == YamlNode::Kind::kScalar) {
      leaf.kind = Kind::kScalar;
      leaf.scalar = node.scalar;
    } else if (node.kind == YamlNode::Kind::kSequence) {
      leaf.kind = Kind::kSequence;
      for (const YamlNode& item : node.items) {
        if (item.kind == YamlNode::Kind::kScalar) {
          leaf.items.push_back(item.scalar);
        } else {
          leaf.nested_items = true;
        }
      }
    } else if (node.kind == YamlNode::Kind::kMap) {
      leaf.kind = Kind::kMap;  // an empty map
    } else {
      leaf.kind = Kind::kNull;
    }
    add(prefix, std::move(leaf));
  }
};

ConfigFile ConfigFile::load(const std::string& path) {
  return from_string(detail::read_text_file(path), path);
}

ConfigFile ConfigFile::from_string(const std::string& yaml, const std::string& name) {
  // The parser skips a byte order mark and directives such as OpenCV's "%YAML:1.0", and rejects
  // a second document.
  const YamlNode root = detail::parse_yaml(yaml, name);
  ConfigFile config;
  config.path_ = name;
  if (root.kind == YamlNode::Kind::kNull) return config;
  if (root.kind != YamlNode::Kind::kMap)
    throw InputError(
        file_error(detail::at_line(name, root.line), "the top level must be a map of settings"));
  ConfigFileBuilder{config}.flatten("", root, root.line);
  return config;
}

bool ConfigFile::has(const std::string& key) const { return leaves_.count(key) != 0; }

const ConfigFile::Leaf* ConfigFile::find(const std::string& key) {
  const auto it = leaves_.find(key);
  if (it == leaves_.end()) return nullptr;
  return &it->second;
}

void ConfigFile::type_error(const std::string& key, const Leaf& leaf,
                            const std::string& expected) const {
  std::string got;
  switch (leaf.kind) {
    case Kind::kScalar:
      got = "'" + leaf.scalar + "'";
      break;
    case Kind::kNull:
      got = "an empty value";
      break;
    case Kind::kSequence:
      got = "a list";
      break;
    case Kind::kMap:
      got = "a map";
      break;
    case Kind::kMatrix:
      got = "an OpenCV matrix";
      break;
  }
  throw InputError(file_error(detail::at_line(path_, leaf.line),
                              "key '" + key + "': expected " + expected + ", got " + got));
}

bool ConfigFile::read(const std::string& key, double& value) {
  const Leaf* leaf = find(key);
  if (leaf == nullptr) return false;
  if (leaf->kind != Kind::kScalar) type_error(key, *leaf, "a number");
  const auto parsed = detail::parse_double(trim(leaf->scalar));
  if (!parsed) type_error(key, *leaf, "a number");
  if (!std::isfinite(*parsed)) type_error(key, *leaf, "a finite number");
  value = *parsed;
  used_.insert(key);
  return true;
}

bool ConfigFile::read(const std::string& key, int& value) {
  const Leaf* leaf = find(key);
  if (leaf == nullptr) return false;
  if (leaf->kind != Kind::kScalar) type_error(key, *leaf, "an integer");
  const std::string text = trim(leaf->scalar);
  long long result = 0;
  if (const auto integer = detail::parse_integer(text)) {
    result = *integer;
  } else {
    const auto number = detail::parse_double(text);
    // Integral values written as decimals (30.0) are accepted; 1.5 is not.
    if (!number || !std::isfinite(*number) || std::trunc(*number) != *number ||
        std::abs(*number) > 1e18)
      type_error(key, *leaf, "an integer");
    result = static_cast<long long>(*number);
  }
  if (result < std::numeric_limits<int>::min() || result > std::numeric_limits<int>::max())
    type_error(key, *leaf, "an integer in the int range");
  value = static_cast<int>(result);
  used_.insert(key);
  return true;
}

bool ConfigFile::read(const std::string& key, bool& value) {
  const Leaf* leaf = find(key);
  if (leaf == nullptr) return false;
  if (leaf->kind != Kind::kScalar) type_error(key, *leaf, "a boolean (true/false)");
  const std::string text = trim(leaf->scalar);
  if (text == "true" || text == "True" || text == "TRUE" || text == "1") {
    value = true;
  } else if (text == "false" || text == "False" || text == "FALSE" || text == "0") {
    value = false;
  } else {
    type_error(key, *leaf, "a boolean (true/false)");
  }
  used_.insert(key);
  return true;
}

bool ConfigFile::read(const std::string& key, std::string& value) {
  const Leaf* leaf = find(key);
  if (leaf == nullptr) return false;
  if (leaf->kind == Kind::kNull) {
    value.clear();
  } else if (leaf->kind == Kind::kScalar) {
    value = leaf->scalar;
  } else {
    type_error(key, *leaf, "a string");
  }
  used_.insert(key);
  return true;
}

bool ConfigFile::read(const std::string& key, std::vector<double>& value) {
  const Leaf* leaf = find(key);
  if (leaf == nullptr) return false;
  if ((leaf->kind != Kind::kSequence && leaf->kind != Kind::kMatrix) || leaf->nested_items)
    type_error(key, *leaf, "a list of numbers");
  std::vector<double> result;
  result.reserve(leaf->items.size());
  for (const std::string& item : leaf->items) {
    const auto parsed = detail::parse_double(trim(item));
    if (!parsed || !std::isfinite(*parsed))
      throw InputError(
          file_error(detail::at_line(path_, leaf->line),
                     "key '" + key + "': expected a list of numbers, got item '" + item + "'"));
    result.push_back(*parsed);
  }
  value = std::move(result);
  used_.insert(key);
  return true;
}

void ConfigFile::mark_used(const std::string& key) {
  const std::string prefix = key + ".";
  for (auto it = leaves_.lower_bound(key); it != leaves_.end(); ++it) {
    if (it->first == key || it->first.rfind(prefix, 0) == 0) {
      used_.insert(it->first);
    } else if (it->first.compare(0, key.size(), key) != 0) {
      break;  // past every key that starts with `key`
    }
  }
}

std::vector<std::string> ConfigFile::keys() const {
  std::vector<std::string> result;
  result.reserve(leaves_.size());
  for (const auto& entry : leaves_) result.push_back(entry.first);
  return result;
}

std::vector<std::string> ConfigFile::unused_keys() const {
  std::vector<std::string> result;
  for (const auto& entry : leaves_)
    if (used_.count(entry.first) == 0) result.push_back(entry.first);
  return result;
}

}  // namespace mcslam::io
