#include "mcslam/io/config_file.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string_view>

#include "io/text_util.hpp"
#include "mcslam/core/error.hpp"

namespace mcslam::io {

namespace {

std::string trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return {};
  const auto last = s.find_last_not_of(" \t\r\n");
  return s.substr(first, last - first + 1);
}

int line_of(const YAML::Node& node, int fallback) {
  const YAML::Mark mark = node.Mark();
  return mark.line >= 0 ? mark.line + 1 : fallback;
}

bool is_matrix_tag(const std::string& tag) {
  return tag.find("opencv-matrix") != std::string::npos;
}

// A map with rows, cols, dt and data (OpenCV's FileStorage layout), or tagged !!opencv-matrix.
bool looks_like_matrix(const YAML::Node& node) {
  if (!node.IsMap()) return false;
  if (is_matrix_tag(node.Tag())) return true;
  return node.size() == 4 && node["rows"] && node["cols"] && node["dt"] && node["data"];
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

  Leaf matrix_leaf(const std::string& key, const YAML::Node& node, int line) const {
    auto bad = [&](const std::string& problem) {
      return InputError(
          file_error(where(line), "key '" + key + "': malformed OpenCV matrix (" + problem + ")"));
    };
    auto integer = [&](const char* name) {
      const YAML::Node n = node[name];
      if (!n || !n.IsScalar()) throw bad(std::string("'") + name + "' must be an integer");
      const auto v = detail::parse_integer(trim(n.Scalar()));
      if (!v || *v < 0 || *v > std::numeric_limits<int>::max())
        throw bad(std::string("'") + name + "' must be a non-negative integer, got '" + n.Scalar() +
                  "'");
      return *v;
    };
    const long long rows = integer("rows");
    const long long cols = integer("cols");
    const YAML::Node dt = node["dt"];
    if (!dt || !dt.IsScalar()) throw bad("'dt' must be a type such as d, f or 3f");
    const std::string type = trim(dt.Scalar());
    long long channels = 1;
    if (!type.empty() && std::isdigit(static_cast<unsigned char>(type.front()))) {
      const auto digits = type.find_first_not_of("0123456789");
      channels = detail::parse_integer(type.substr(0, digits)).value_or(0);
    }
    if (channels <= 0) throw bad("bad 'dt' '" + type + "'");
    const YAML::Node data = node["data"];
    if (!data || !data.IsSequence()) throw bad("'data' must be a list");
    Leaf leaf;
    leaf.kind = Kind::kMatrix;
    leaf.line = line;
    for (const YAML::Node& item : data) {
      if (!item.IsScalar()) throw bad("'data' items must be numbers");
      leaf.items.push_back(item.Scalar());
    }
    if (static_cast<long long>(leaf.items.size()) != rows * cols * channels)
      throw bad("rows x cols x channels = " + std::to_string(rows * cols * channels) + " but " +
                std::to_string(leaf.items.size()) + " data values");
    return leaf;
  }

  void flatten(const std::string& prefix, const YAML::Node& node, int line) {
    if (node.IsMap() && node.size() > 0 && !looks_like_matrix(node)) {
      for (auto it = node.begin(); it != node.end(); ++it) {
        const int key_line = line_of(it->first, line);
        if (!it->first.IsScalar())
          throw InputError(file_error(where(key_line), "keys must be plain names"));
        const std::string name = it->first.Scalar();
        flatten(prefix.empty() ? name : prefix + "." + name, it->second, key_line);
      }
      return;
    }
    if (prefix.empty()) return;  // empty top-level map
    Leaf leaf;
    leaf.line = line;
    if (looks_like_matrix(node)) {
      leaf = matrix_leaf(prefix, node, line);
    } else if (node.IsScalar()) {
      leaf.kind = Kind::kScalar;
      leaf.scalar = node.Scalar();
    } else if (node.IsSequence()) {
      leaf.kind = Kind::kSequence;
      for (const YAML::Node& item : node) {
        if (item.IsScalar()) {
          leaf.items.push_back(item.Scalar());
        } else {
          leaf.nested_items = true;
        }
      }
    } else if (node.IsMap()) {
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

namespace {

/// yaml-cpp 0.7 (Debian 12) loops forever, allocating, when a ',' comes where a block-level node
/// should start: "," or ",]" alone, "!tag ,", or a line starting with ',' after an indented map
/// (found by fuzz/fuzz_settings). Such text is not valid YAML (a plain scalar cannot start with
/// ','), so it is rejected first with the syntax error yaml-cpp should have given. A node starts
/// at a line start, after "- ", "? ", ": ", "--- " and after a tag or anchor. Quoted and flow
/// text is followed across lines, so "[1\n, 2]" and "a: ',x'" stay valid.
void reject_comma_node(const std::string& text, const std::string& name) {
  int flow_depth = 0;
  char quote = 0;           // ' or " while inside a quoted scalar
  bool node_start = true;   // the next token starts a node
  bool token_start = true;  // the next character starts a token
  int line = 1;
  auto blank = [&](std::size_t i) {
    return i >= text.size() || text[i] == ' ' || text[i] == '\t' || text[i] == '\r' ||
           text[i] == '\n';
  };
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '\n') ++line;
    // YAML allows no C0 control character but tab, line feed and carriage return (yaml-cpp
    // loops on some, e.g. a NUL byte before a ',').
    if (static_cast<unsigned char>(c) < 0x20 && c != '\t' && c != '\n' && c != '\r') {
      char code[8];
      std::snprintf(code, sizeof(code), "0x%02x", static_cast<unsigned>(c));
      throw InputError(file_error(detail::at_line(name, line),
                                  std::string("not a YAML text: control character ") + code));
    }
    if (quote) {
      if (c == '\\' && quote == '"')
        ++i;
      else if (c == quote)
        quote = 0;
      continue;
    }
    if (c == '\n') {
      node_start = token_start = true;
      continue;
    }
    if (blank(i)) {
      token_start = true;
      continue;
    }
    const bool column_zero = i == 0 || text[i - 1] == '\n';
    if ((c == '#' && token_start) || (c == '%' && column_zero)) {
      while (i + 1 < text.size() && text[i + 1] != '\n') ++i;  // a comment or a directive
      continue;
    }
    if (node_start && flow_depth == 0) {
      if (c == ',')
        throw InputError(file_error(detail::at_line(name, line),
                                    "YAML syntax error: a node cannot start with ',' outside "
                                    "[ ] or { }"));
      if ((c == '!' || c == '&') && token_start) {
        // A tag or anchor (it ends at a blank or a flow indicator): the node follows it.
        while (!blank(i + 1) && std::strchr(",[]{}", text[i + 1]) == nullptr) ++i;
        token_start = true;
        continue;
      }
      if ((c == '-' || c == '?' || c == ':') && blank(i + 1)) continue;  // an indicator
      if (c == '-' && text.compare(i, 3, "---") == 0 && blank(i + 3)) {  // a document marker
        i += 2;
        continue;
      }
    }
    if ((c == '\'' || c == '"') && token_start) {
      quote = c;
    } else if (c == '[' || c == '{') {
      ++flow_depth;
    } else if ((c == ']' || c == '}') && flow_depth > 0) {
      --flow_depth;
    } else if (c == ':' && blank(i + 1) && flow_depth == 0) {
      node_start = token_start = true;  // "key: value": the value is a node
      continue;
    }
    node_start = false;
    token_start = c == ',' || c == '[' || c == '{';
  }
}

}  // namespace

ConfigFile ConfigFile::from_string(const std::string& yaml, const std::string& name) {
  std::string text = yaml;
  if (text.rfind("\xEF\xBB\xBF", 0) == 0) text.erase(0, 3);  // UTF-8 byte order mark
  // OpenCV's "%YAML:1.0" directive is not YAML: blank that line, keeping the line numbers.
  if (text.rfind("%YAML:", 0) == 0) text.erase(0, std::min(text.find('\n'), text.size()));

  ConfigFile config;
  config.path_ = name;
  std::vector<YAML::Node> documents;
  reject_comma_node(text, name);
  try {
    documents = YAML::LoadAll(text);
  } catch (const YAML::Exception& e) {
    const std::string where = e.mark.line >= 0 ? detail::at_line(name, e.mark.line + 1) : name;
    throw InputError(file_error(where, "YAML syntax error: " + e.msg));
  }
  if (documents.size() > 1)
    throw InputError(
        file_error(name, "expected one YAML document, got " + std::to_string(documents.size())));
  if (documents.empty() || documents.front().IsNull()) return config;
  const YAML::Node& root = documents.front();
  if (!root.IsMap())
    throw InputError(file_error(detail::at_line(name, line_of(root, 1)),
                                "the top level must be a map of settings"));
  try {
    ConfigFileBuilder{config}.flatten("", root, 1);
  } catch (const YAML::Exception& e) {
    throw InputError(file_error(name, std::string("cannot read YAML: ") + e.what()));
  }
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
