#include "io/yaml_subset.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "mcslam/core/error.hpp"

namespace mcslam::io::detail {
namespace {

using Kind = YamlNode::Kind;

std::string quote(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (c == '\n') {
      out += "\\n";
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char code[8];
      std::snprintf(code, sizeof(code), "\\x%02x", static_cast<unsigned>(c));
      out += code;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

// A compact rendering of a tree: ~ for null, "text" for scalars, [..] and {"key": ..}, each
// node preceded by its tag.
std::string render(const YamlNode& node) {
  std::string out = node.tag.empty() ? "" : node.tag + " ";
  switch (node.kind) {
    case Kind::kNull:
      return out + "~";
    case Kind::kScalar:
      return out + quote(node.scalar);
    case Kind::kSequence:
      out += "[";
      for (std::size_t i = 0; i < node.items.size(); ++i)
        out += (i ? ", " : "") + render(node.items[i]);
      return out + "]";
    case Kind::kMap:
      out += "{";
      for (std::size_t i = 0; i < node.entries.size(); ++i)
        out += (i ? ", " : "") + quote(node.entries[i].key) + ": " + render(node.entries[i].value);
      return out + "}";
  }
  return out;
}

std::string tree(const std::string& text) { return render(parse_yaml(text, "t.yaml")); }

// The InputError message parse_yaml() gives, or "" when it parses.
std::string error_of(const std::string& text) {
  try {
    parse_yaml(text, "t.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

using Cases = std::vector<std::pair<std::string, std::string>>;

void expect_trees(const Cases& cases) {
  for (const auto& [text, expected] : cases) {
    try {
      EXPECT_EQ(tree(text), expected) << "input: " << quote(text);
    } catch (const InputError& e) {
      ADD_FAILURE() << "input " << quote(text) << ": " << e.what();
    }
  }
}

void expect_errors(const Cases& cases) {
  for (const auto& [text, expected] : cases)
    EXPECT_EQ(error_of(text), "t.yaml:" + expected) << "input: " << quote(text);
}

TEST(YamlSubset, DocumentMarkersDirectivesAndComments) {
  expect_trees({
      {"", "~"},
      {"# only\n\n   # comments\n", "~"},
      {"\xEF\xBB\xBF"
       "a: 1\n",
       R"({"a": "1"})"},
      {"%YAML:1.0\na: 1\n", R"({"a": "1"})"},
      {"%YAML 1.2\n%TAG !e! tag:example.com,2000:\n---\na: 1\n...\n# end\n", R"({"a": "1"})"},
      {"%YAML:1.0\n---\nx: 2\n", R"({"x": "2"})"},
      {"--- {a: 1}\n", R"({"a": "1"})"},
      {"--- text\n", R"("text")"},
      {"--- !!opencv-matrix\nrows: 1\n", R"(!!opencv-matrix {"rows": "1"})"},
      {"---\n...\n", "~"},
      {"a: 1\r\nb: 2\rc: 3", R"({"a": "1", "b": "2", "c": "3"})"},
      {"a: 1 # one\nb: x#y\n# full line\n   # indented\nc: 'q' # after quote\n"
       "d: [1, # in flow\n  # alone in flow\n  2] # after flow\n",
       R"({"a": "1", "b": "x#y", "c": "q", "d": ["1", "2"]})"},
  });
}

TEST(YamlSubset, BlockMaps) {
  expect_trees({
      {"Camera.fx: 517.3\nkey with spaces: value with spaces\n\"quoted key\": 1\n'single': 2\n",
       R"({"Camera.fx": "517.3", "key with spaces": "value with spaces", "quoted key": "1", )"
       R"("single": "2"})"},
      {"a:\n  b:\n    c: 1\n  d: 2\ne: 3\n", R"({"a": {"b": {"c": "1"}, "d": "2"}, "e": "3"})"},
      {"  a: 1\n  b: 2\n", R"({"a": "1", "b": "2"})"},
      {"a:\nb: ~\nc: null\nd: Null\ne: NULL\nf:   # comment\ng: nul\nh: ''\ni: \"\"\n",
       R"({"a": ~, "b": ~, "c": ~, "d": ~, "e": ~, "f": ~, "g": "nul", "h": "", "i": ""})"},
      {"a:\n- 1\n- 2\nb: 3\n", R"({"a": ["1", "2"], "b": "3"})"},  // sequence at the key's column
      {"a:\n\n  # comment\n  b: 1\n", R"({"a": {"b": "1"}})"},
      {"a:\tb\nc:  d  \n", R"({"a": "b", "c": "d"})"},
      {"<<: x\n", R"({"<<": "x"})"},  // a merge key is just a key
  });
}

TEST(YamlSubset, BlockSequences) {
  expect_trees({
      {"- a\n- - b\n  - c\n- d: 1\n  e: 2\n-\n-\n  f: 3\n",
       R"(["a", ["b", "c"], {"d": "1", "e": "2"}, ~, {"f": "3"}])"},
      {"- - - x\n    - y\n  - z\n", R"([[["x", "y"], "z"]])"},
      {"a:\n  - 1\n  -\n  - [2]\n", R"({"a": ["1", ~, ["2"]]})"},
      {"-   a: 1\n    b: 2\n", R"([{"a": "1", "b": "2"}])"},
  });
}

TEST(YamlSubset, FlowCollections) {
  expect_trees({
      {"[a, b, [c, d]]", R"(["a", "b", ["c", "d"]])"},
      {"{a: 1, b: [2, 3]}", R"({"a": "1", "b": ["2", "3"]})"},
      {"a: [1, 2,]\nb: {c: 1,}\nc: []\nd: {}\ne: [ ]\n",
       R"({"a": ["1", "2"], "b": {"c": "1"}, "c": [], "d": {}, "e": []})"},
      {"a: [1,\n  2,\n\n  3\n  ]\nb: {x: 1,\n  y: 2}\n",
       R"({"a": ["1", "2", "3"], "b": {"x": "1", "y": "2"}})"},
      {"a: [1,\n2]\n", R"({"a": ["1", "2"]})"},  // flow lines need no indentation (as in PyYAML)
      {"[one two, three\n  four]", R"(["one two", "three four"])"},
      {"[a: 1, b]", R"([{"a": "1"}, "b"])"},
      {"{a, b: , c: ~}", R"({"a": ~, "b": ~, "c": ~})"},
      {"{\"a\":1, 'b': [x]}", R"({"a": "1", "b": ["x"]})"},
      {"[http://x.org, a:b, {c:d}]", R"(["http://x.org", "a:b", {"c:d": ~}])"},
      {"[!t , !u x, !v [1]]", R"([!t ~, !u "x", !v ["1"]])"},
      {"- [a, b]\n- {c: d}\n", R"([["a", "b"], {"c": "d"}])"},
  });
}

TEST(YamlSubset, Scalars) {
  expect_trees({
      {"a: x:y\nb: http://x.org/a#b\nc: -1\nd: ?x\ne: :x\nf: it's\ng: 1, 2\n",
       R"({"a": "x:y", "b": "http://x.org/a#b", "c": "-1", "d": "?x", "e": ":x", "f": "it's", )"
       R"("g": "1, 2"})"},
      {"a: 'it''s'\nb: '# no comment'\nc: '\\n'\n",
       R"({"a": "it's", "b": "# no comment", "c": "\\n"})"},
      {"a: \"q\\\"x\\\\ \\/ \\n\\t\\r\\0\\b\\f\\e\\a\\v\\ \"\n",
       R"({"a": "q\"x\\ / \n\x09\x0d\x00\x08\x0c\x1b\x07\x0b "})"},
      {"a: \"\\x41\\u00e9\\U0001F600\\N\\_\\L\"\n",
       "{\"a\": \"A\xC3\xA9\xF0\x9F\x98\x80\xC2\x85\xC2\xA0\xE2\x80\xA8\"}"},
      {"a: 'x\n  y\n\n  z'\nb: \"p \\\n   q\"\nc: \"r  \n\n\n  s\"\n",
       R"({"a": "x y\nz", "b": "p q", "c": "r\n\ns"})"},
      {"a: plain\n  continued\n\n  para\nb: x\n", R"({"a": "plain continued\npara", "b": "x"})"},
      {"- a\n  b\n- c\n", R"(["a b", "c"])"},
      {"a: b\n  - c\n", R"({"a": "b - c"})"},  // "- c" continues the scalar, as YAML says
      {"just\ntext\n", R"("just text")"},
      {"\"top\"\n", R"("top")"},
  });
}

TEST(YamlSubset, Tags) {
  expect_trees({
      {"a: !foo x\nb: !<tag:x.org,2000:y> [1]\nc: !!str\nd: !!opencv-matrix\n  rows: 1\n",
       R"({"a": !foo "x", "b": !<tag:x.org,2000:y> ["1"], "c": !!str ~, )"
       R"("d": !!opencv-matrix {"rows": "1"}})"},
      {"- !t\n  - 1\n- !u\n", R"([!t ["1"], !u ~])"},
      {"a:\n  !t\n  b: 1\n", R"({"a": !t {"b": "1"}})"},
      {"Tbc: !!opencv-matrix\n   rows: 2\n   cols: 3\n   dt: f\n   data: [ 1., 0., 0.5,\n"
       "           0., 1.e-3, -2 ]\n",
       R"({"Tbc": !!opencv-matrix {"rows": "2", "cols": "3", "dt": "f", )"
       R"("data": ["1.", "0.", "0.5", "0.", "1.e-3", "-2"]}})"},
  });
}

TEST(YamlSubset, LinesOfNodesAndKeys) {
  const YamlNode root = parse_yaml(
      "%YAML:1.0\n"  // 1
      "a: 1\n"       // 2
      "b:\n"         // 3
      "  - x\n"      // 4
      "  - [y,\n"    // 5
      "     z]\n"    // 6
      "c: !t\n"      // 7
      "  d: 'p\n"    // 8
      "    q'\n"     // 9
      "e:\n",        // 10
      "t.yaml");
  ASSERT_EQ(root.kind, Kind::kMap);
  EXPECT_EQ(root.line, 2);
  ASSERT_EQ(root.entries.size(), 4u);
  EXPECT_EQ(root.entries[0].line, 2);
  EXPECT_EQ(root.entries[0].value.line, 2);
  const YamlEntry& b = root.entries[1];
  EXPECT_EQ(b.line, 3);
  EXPECT_EQ(b.value.line, 4);
  ASSERT_EQ(b.value.items.size(), 2u);
  EXPECT_EQ(b.value.items[0].line, 4);
  EXPECT_EQ(b.value.items[1].line, 5);
  ASSERT_EQ(b.value.items[1].items.size(), 2u);
  EXPECT_EQ(b.value.items[1].items[1].line, 6);
  const YamlNode* c = root.find("c");
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(c->line, 7);  // where its tag is
  ASSERT_NE(c->find("d"), nullptr);
  EXPECT_EQ(c->find("d")->line, 8);
  EXPECT_EQ(c->find("d")->scalar, "p q");
  EXPECT_EQ(root.entries[3].value.kind, Kind::kNull);
  EXPECT_EQ(root.entries[3].value.line, 10);
  EXPECT_EQ(root.find("missing"), nullptr);
  EXPECT_EQ(c->find("d")->find("x"), nullptr);  // not a map
}

TEST(YamlSubset, UnsupportedConstructsAreNamed) {
  expect_errors({
      {"a: &x 1\n", "1: YAML syntax error: anchors and aliases are not supported"},
      {"a: 1\nb: *x\n", "2: YAML syntax error: anchors and aliases are not supported"},
      {"a: |\n  x\n",
       "1: YAML syntax error: block scalars (| and >) are not supported; quote the text"},
      {"a: >-\n  x\n",
       "1: YAML syntax error: block scalars (| and >) are not supported; quote the text"},
      {"? a\n: b\n", "1: YAML syntax error: complex keys ('? ') are not supported"},
      {"{? a: b}", "1: YAML syntax error: complex keys ('? ') are not supported"},
      {"[a]: b\n",
       "1: YAML syntax error: complex keys (a flow collection as a key) are not supported"},
      {"{[a]: b}",
       "1: YAML syntax error: complex keys (a flow collection as a key) are not supported"},
      {"!t a: 1\n", "1: YAML syntax error: tags on keys are not supported"},
      {"a: 1\n!t b: 1\n", "2: YAML syntax error: tags on keys are not supported"},
      {"a: !t !u x\n", "1: YAML syntax error: a node cannot have two tags"},
      {"a: 1\n---\nb: 2\n", "2: YAML syntax error: expected one YAML document, got more"},
      {"a: 1\n...\n\nb: 2\n", "4: YAML syntax error: expected one YAML document, got more"},
      {"---\n---\n", "2: YAML syntax error: expected one YAML document, got more"},
  });
}

TEST(YamlSubset, InvalidTextIsASyntaxErrorAtItsLine) {
  expect_errors({
      // Indicators that cannot start a plain scalar.
      {",\n", "1: YAML syntax error: a node cannot start with ','"},
      {"a: ]\n", "1: YAML syntax error: a node cannot start with ']'"},
      {"a: }\n", "1: YAML syntax error: a node cannot start with '}'"},
      {"a: @x\n", "1: YAML syntax error: a node cannot start with '@'"},
      {"a: `x\n", "1: YAML syntax error: a node cannot start with '`'"},
      {"a: %x\n", "1: YAML syntax error: a node cannot start with '%'"},
      {"a: 1\n%YAML 1.2\n", "2: YAML syntax error: a node cannot start with '%'"},
      {"[1,,2]", "1: YAML syntax error: a node cannot start with ','"},
      {"[a, -]", "1: YAML syntax error: '-' before ']' is not a value; quote it"},
      {": a\n", "1: YAML syntax error: missing key before ':'"},
      // Structure.
      {"a: b: c\n",
       "1: YAML syntax error: a map cannot start on this line (quote a value that has ': ')"},
      {"--- a: 1\n",
       "1: YAML syntax error: a map cannot start on this line (quote a value that has ': ')"},
      {"a: - b\n", "1: YAML syntax error: a block sequence cannot start here"},
      {"[- a]", "1: YAML syntax error: a block sequence cannot start inside [ ] or { }"},
      {"a: 1\n- b\n", "2: YAML syntax error: expected 'key: value', got a sequence item '- '"},
      {"- a\nb\n", "2: YAML syntax error: expected a sequence item '- '"},
      {"a: 1\nb\n", "2: YAML syntax error: expected 'key: value'"},
      {"rows: 1\ndata:[1, 2]\n",
       "2: YAML syntax error: expected 'key: value' (put a space after ':')"},
      {"\"a\nb\": 1\n", "1: YAML syntax error: a key and its ':' must be on one line"},
      {"[a\n: b]", "1: YAML syntax error: a key and its ':' must be on one line"},
      {"a: 1\na: 2\n", "2: YAML syntax error: duplicate key 'a'"},
      {"x:\n  {a: 1,\n   a: 2}\n", "3: YAML syntax error: duplicate key 'a'"},
      // Indentation.
      {"a: 1\n  b: 2\n",
       "2: YAML syntax error: bad indentation: line indented more than its block allows"},
      {"a: [1]\n  b: 2\n",
       "2: YAML syntax error: bad indentation: line indented more than its block allows"},
      {"a: 1\n# c\n  b\n",
       "3: YAML syntax error: bad indentation: line indented more than its block allows"},
      {"a:\n    b: 1\n  c: 2\n",
       "3: YAML syntax error: bad indentation: dedent to a column no enclosing block uses"},
      {"  a: 1\nb: 2\n",
       "2: YAML syntax error: bad indentation: dedent to a column no enclosing block uses"},
      {"a:\n\tb: 1\n", "2: YAML syntax error: tabs cannot indent YAML"},
      {"a:\n  \t- 1\n", "2: YAML syntax error: tabs cannot indent YAML"},
      // Unterminated quotes and flow collections are reported where they open.
      {"a: [1, 2\n", "1: YAML syntax error: end of flow sequence ']' not found"},
      {"a: [1,\n  [2, 3]\n", "1: YAML syntax error: end of flow sequence ']' not found"},
      {"b: [1, 2\nc: 3\n", "1: YAML syntax error: end of flow sequence ']' not found"},
      {"a: {b: 1\n", "1: YAML syntax error: end of flow map '}' not found"},
      {"a: [\n---\n]\n", "1: YAML syntax error: end of flow sequence ']' not found"},
      {"a: \"x\n", "1: YAML syntax error: end of double-quoted scalar '\"' not found"},
      {"a: 'x\n\nb: 1\n", "1: YAML syntax error: end of single-quoted scalar \"'\" not found"},
      {"a: \"x\\", "1: YAML syntax error: end of double-quoted scalar '\"' not found"},
      {"a: !<x\n", "1: YAML syntax error: end of verbatim tag '>' not found"},
      {"[a, {b: c]", "1: YAML syntax error: expected ',' or '}' in a flow map"},
      {"{a: [1, 2}", "1: YAML syntax error: expected ',' or ']' in a flow sequence"},
      {"[a # c\n  b]", "2: YAML syntax error: expected ',' or ']' in a flow sequence"},
      // Text after a closed node.
      {"a: [1] x\n", "1: YAML syntax error: unexpected text after the flow sequence"},
      {"a: [1]# c\n",
       "1: YAML syntax error: unexpected text after the flow sequence (a comment needs a blank "
       "before '#')"},
      {"a: 'x'#c\n",
       "1: YAML syntax error: unexpected text after the quoted scalar (a comment needs a blank "
       "before '#')"},
      {"[a,#c\n b]",
       "1: YAML syntax error: a node cannot start with '#' (a comment needs a blank "
       "before it)"},
      {"a: {b: 1}}\n", "1: YAML syntax error: unexpected text after the flow map"},
      {"a: 'q' x\n", "1: YAML syntax error: unexpected text after the quoted scalar"},
      {"\"c\"\n!x\n", "2: YAML syntax error: unexpected text after the end of the top-level node"},
      {"a: 1\n... x\n", "2: YAML syntax error: unexpected text after '...'"},
      {"a: !t,x\n", "1: YAML syntax error: a tag must be followed by a space"},
      // Escapes and characters.
      {"a: \"\\q\"\n", "1: YAML syntax error: unknown escape '\\q' in a double-quoted scalar"},
      {"a: \"\\x4\"\n", "1: YAML syntax error: an escape needs 2 hex digits"},
      {"a: \"\\uD800\"\n", "1: YAML syntax error: escape of an invalid Unicode code point"},
      {"a: \"\\U00110000\"\n", "1: YAML syntax error: escape of an invalid Unicode code point"},
      {"a: \x01\n", "1: YAML syntax error: control character 0x01"},
      {"a: 1\r\nb: '\x7f'\n", "2: YAML syntax error: control character 0x7f"},
      {std::string("a: 1\n\0,\n", 8), "2: YAML syntax error: control character 0x00"},
  });
}

TEST(YamlSubset, InputsThatHungYamlCppEndInAnError) {
  // yaml-cpp 0.7 never returned on these (found by fuzz/fuzz_settings).
  expect_errors({
      {",", "1: YAML syntax error: a node cannot start with ','"},
      {",]", "1: YAML syntax error: a node cannot start with ','"},
      {"!tag ,", "1: YAML syntax error: a node cannot start with ','"},
      {"a:\n  b: 1\n,", "3: YAML syntax error: a node cannot start with ','"},
      {std::string("\0,", 2), "1: YAML syntax error: control character 0x00"},
      {"%Y: [&.52, -0.95\n ,,\n", "2: YAML syntax error: a node cannot start with ','"},
      // fuzz/corpus/settings/hang-yaml-cpp-settings-1 without its control character.
      {"%YAMo+:\xd5\xd5\xd5\xd5\n!opencv-matrix\n   r\xfbowsta: \"chai  "
       "ch3\n:\nr\"\"\"\"\"\"\"\"\"\"\"\""
       "\"\"\"\"\"\"\"\"\"\"\"\"\"\",,,,000.0\x81LEFT., 1.16]\n",
       "5: YAML syntax error: unexpected text after the quoted scalar"},
  });
}

TEST(YamlSubset, DeepNestingIsRejectedWithoutRecursingFurther) {
  const int n = 100000;
  expect_errors({
      {std::string(n, '[') + std::string(n, ']'),
       "1: YAML syntax error: nesting deeper than 64 levels"},
      {[&] {
         std::string text;
         for (int i = 0; i < n; ++i) text += "{a: ";
         return text;
       }(),
       "1: YAML syntax error: nesting deeper than 64 levels"},
      {[&] {
         std::string text;
         for (int i = 0; i < n; ++i) text += "- ";
         return text;
       }(),
       "1: YAML syntax error: nesting deeper than 64 levels"},
      {[&] {
         std::string text;
         for (int i = 0; i < 1000; ++i) text += std::string(i, ' ') + "a:\n";
         return text;
       }(),
       "65: YAML syntax error: nesting deeper than 64 levels"},
  });
  // 64 levels are fine.
  EXPECT_EQ(tree(std::string(63, '[') + "[x]" + std::string(63, ']')),
            std::string(64, '[') + "\"x\"" + std::string(64, ']'));
}

TEST(YamlSubset, LargeInputsParse) {
  std::string keys;
  for (int i = 0; i < 100000; ++i)
    keys += "key" + std::to_string(i) + ": " + std::to_string(i) + "\n";
  const YamlNode map = parse_yaml(keys, "t.yaml");
  ASSERT_EQ(map.entries.size(), 100000u);
  EXPECT_EQ(map.entries.back().key, "key99999");
  EXPECT_EQ(map.entries.back().line, 100000);
  EXPECT_EQ(parse_yaml("a: '" + std::string(1 << 20, 'x') + "'", "t.yaml").find("a")->scalar.size(),
            1u << 20);
  EXPECT_EQ(error_of("[" + std::string(1 << 20, ' ')),
            "t.yaml:1: YAML syntax error: end of flow sequence ']' not found");
}

TEST(YamlSubset, RandomTextParsesOrThrowsInputError) {
  std::mt19937 rng(20240607);
  // Raw bytes, and text made of YAML's indicators, blanks and breaks (which gets further).
  const std::string alphabet = "ab1.:-?,[]{}#&*!|>'\"%@`~ \t\n\n\n   \\xu0";
  for (int kind = 0; kind < 2; ++kind) {
    for (int round = 0; round < 64; ++round) {
      const std::size_t size = round == 0 ? (1u << 20) : 1 + rng() % 4096;  // 1 MB once
      std::string text(size, ' ');
      for (char& c : text)
        c = kind == 0 ? static_cast<char>(rng() & 0xFF) : alphabet[rng() % alphabet.size()];
      try {
        parse_yaml(text, "t.yaml");
      } catch (const InputError& e) {
        EXPECT_EQ(std::string(e.what()).rfind("t.yaml:", 0), 0u) << e.what();
      }
    }
  }
}

}  // namespace
}  // namespace mcslam::io::detail
