#include "io/yaml_subset.hpp"

#include <cstdint>
#include <cstdio>
#include <unordered_set>
#include <utility>

#include "io/text_util.hpp"
#include "mcslam/core/error.hpp"

namespace mcslam::io::detail {

const YamlNode* YamlNode::find(std::string_view key) const {
  for (const YamlEntry& entry : entries)
    if (entry.key == key) return &entry.value;
  return nullptr;
}

namespace {

constexpr int kMaxDepth = 64;
constexpr const char* kIndentedMore = "bad indentation: line indented more than its block allows";
constexpr const char* kBadDedent = "bad indentation: dedent to a column no enclosing block uses";

bool is_blank(char c) { return c == ' ' || c == '\t'; }
bool is_flow_indicator(char c) { return c == ',' || c == '[' || c == ']' || c == '{' || c == '}'; }

/// The text without a leading byte order mark and with "\r\n" and lone '\r' (YAML line breaks
/// too) turned into '\n', so the parser sees one kind of break. Rejects the control characters
/// YAML does not allow; afterwards a NUL byte cannot occur, which lets '\0' mean "end of text".
std::string normalize(std::string_view text, const std::string& name) {
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
  std::string out;
  out.reserve(text.size());
  int line = 1;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    const auto byte = static_cast<unsigned char>(c);
    if (c == '\r' || c == '\n') {
      if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') ++i;
      out += '\n';
      ++line;
      continue;
    }
    if ((byte < 0x20 && c != '\t') || byte == 0x7f) {
      char code[8];
      std::snprintf(code, sizeof(code), "0x%02x", static_cast<unsigned>(byte));
      throw InputError(file_error(at_line(name, line),
                                  std::string("YAML syntax error: control character ") + code));
    }
    out += c;
  }
  return out;
}

void append_utf8(std::string& out, std::uint32_t cp) {
  if (cp < 0x80) {
    out += static_cast<char>(cp);
  } else if (cp < 0x800) {
    out += static_cast<char>(0xC0 | (cp >> 6));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  } else if (cp < 0x10000) {
    out += static_cast<char>(0xE0 | (cp >> 12));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  } else {
    out += static_cast<char>(0xF0 | (cp >> 18));
    out += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  }
}

/// Recursive descent over the normalized text. Block structure is followed by indentation: after
/// each block node the position is at the first character of the next line with content, whose
/// column tells the enclosing collections whether it continues them. Every loop consumes input
/// or throws, and nesting is bounded, so any text ends in about linear time.
class Parser {
 public:
  Parser(std::string text, const std::string& name) : text_(std::move(text)), name_(name) {}

  YamlNode parse_document() {
    settle_at_content();
    // Directives ("%YAML 1.2", "%TAG ...", OpenCV's "%YAML:1.0") precede the document.
    while (!at_end() && column() == 0 && peek() == '%') {
      skip_line_rest();
      next_content_line();
    }
    YamlNode root;
    root.line = line_;
    if (at_end()) return root;
    if (!at_document_marker()) {
      root = parse_block_node(-1, true, false);
    } else if (peek() == '-') {
      pos_ += 3;  // "---", possibly followed by the root on the same line
      root = parse_block_node(-1, false, false);
    }
    bool ended = false;
    if (at_document_marker() && peek() == '.') {
      pos_ += 3;
      if (!rest_is_empty()) fail(line_, "unexpected text after '...'");
      next_content_line();
      ended = true;
    }
    if (!at_end()) {
      if (ended || at_document_marker()) fail(line_, "expected one YAML document, got more");
      fail(line_, "unexpected text after the end of the top-level node");
    }
    return root;
  }

 private:
  struct Scalar {
    std::string text;
    bool plain = false;
    bool multi_line = false;
    int end_line = 1;  // line of the last character
  };
  // A flow sequence item or flow map entry: a node, or `key: value`.
  struct FlowEntry {
    YamlNode node;        // the node, or the value of a pair
    bool pair = false;    // `key: value`
    bool scalar = false;  // not a pair, and `node` is an untagged scalar: `key` is its text
    std::string key;
    int key_line = 1;
  };

  // Counts open collections so that hostile nesting cannot exhaust the stack.
  class DepthGuard {
   public:
    DepthGuard(Parser& parser, int line) : parser_(parser) {
      if (parser_.depth_ >= kMaxDepth)
        parser_.fail(line, "nesting deeper than " + std::to_string(kMaxDepth) + " levels");
      ++parser_.depth_;
    }
    ~DepthGuard() { --parser_.depth_; }
    DepthGuard(const DepthGuard&) = delete;
    DepthGuard& operator=(const DepthGuard&) = delete;

   private:
    Parser& parser_;
  };

  [[noreturn]] void fail(int line, const std::string& what) const {
    throw InputError(file_error(at_line(name_, line), "YAML syntax error: " + what));
  }

  // ---- Characters and lines --------------------------------------------------------------

  char at(std::size_t i) const { return i < text_.size() ? text_[i] : '\0'; }  // '\0': the end
  char peek() const { return at(pos_); }
  bool at_end() const { return pos_ >= text_.size(); }
  int column() const { return static_cast<int>(pos_ - line_start_); }
  // A blank, a line break or the end follows at i: what makes '-', '?' and ':' indicators.
  bool separated(std::size_t i) const {
    const char c = at(i);
    return c == '\0' || c == '\n' || is_blank(c);
  }
  // Same inside [ ] and { }, where flow indicators also separate.
  bool flow_separated(std::size_t i) const { return separated(i) || is_flow_indicator(at(i)); }
  bool comment_starts_here() const {
    return peek() == '#' && (pos_ == line_start_ || is_blank(text_[pos_ - 1]));
  }
  bool at_document_marker() const {
    if (pos_ != line_start_ || pos_ + 3 > text_.size()) return false;
    const std::string_view three(text_.data() + pos_, 3);
    return (three == "---" || three == "...") && separated(pos_ + 3);
  }
  bool at_sequence_indicator() const { return peek() == '-' && separated(pos_ + 1); }

  void newline() {  // at a '\n'
    ++pos_;
    ++line_;
    line_start_ = pos_;
  }
  void skip_blanks() {
    while (is_blank(peek())) ++pos_;
  }
  void skip_line_rest() {
    while (!at_end() && peek() != '\n') ++pos_;
  }
  // Skips blanks; true when nothing but a comment is left on the line.
  bool rest_is_empty() {
    skip_blanks();
    return at_end() || peek() == '\n' || comment_starts_here();
  }

  // From the start of a line, skips empty and comment lines to the first character of the next
  // line with content (or to the end), counting empty lines (for folding) and noting comments.
  void settle_at_content() {
    for (;;) {
      bool tab = false;
      while (is_blank(peek())) {
        tab = tab || peek() == '\t';
        ++pos_;
      }
      if (at_end()) return;
      if (peek() == '\n') {
        ++empty_lines_;
        newline();
        continue;
      }
      if (peek() == '#') {
        saw_comment_ = true;
        skip_line_rest();
        if (at_end()) return;
        newline();
        continue;
      }
      // Tabs may separate and trail, but block indentation is spaces only.
      if (tab) fail(line_, "tabs cannot indent YAML");
      return;
    }
  }

  // Leaves the current line, where only blanks or a comment remain, for the next content line.
  void next_content_line() {
    empty_lines_ = 0;
    saw_comment_ = false;
    skip_blanks();
    if (peek() == '#') saw_comment_ = true;
    skip_line_rest();
    if (at_end()) return;
    newline();
    settle_at_content();
  }

  // Indentation of the current content line; -1 at the end or at a document marker, which
  // close every block.
  int current_indent() const { return at_end() || at_document_marker() ? -1 : column(); }

  void finish_line(const char* after) {
    if (!rest_is_empty())
      fail(line_, std::string("unexpected text after the ") + after +
                      (peek() == '#' ? " (a comment needs a blank before '#')" : ""));
    next_content_line();
  }

  // After an entry of a block collection at `indent` (inside one at `parent`): true when the
  // current line is the collection's next entry, false when the collection ends there.
  bool next_sibling(int indent, int parent) {
    const int next = current_indent();
    if (next == indent) return true;
    if (next > indent) fail(line_, kIndentedMore);
    if (next > parent) fail(line_, kBadDedent);
    return false;
  }

  // ---- Block context -----------------------------------------------------------------------

  // A block node, positioned after "key:", "- " or "---" on the same line, or at the start of
  // a content line. `compact` lets a map or sequence start on this line (at line starts and
  // after "- "). Its lines are indented more than `parent`, the enclosing collection's column;
  // a map value (`map_value`) may also be a sequence at `parent`, as YAML allows. Returns at
  // the start of the next content line.
  YamlNode parse_block_node(int parent, bool compact, bool map_value) {
    skip_blanks();
    YamlNode node;
    node.line = line_;
    if (peek() == '!') {
      node.tag = read_tag(false);
      skip_blanks();
    }
    if (rest_is_empty()) {
      // The node is on the following lines, or empty.
      next_content_line();
      const int indent = current_indent();
      if (indent > parent || (map_value && indent == parent && at_sequence_indicator())) {
        YamlNode child = parse_block_node(parent, true, map_value);
        if (!node.tag.empty()) {
          if (!child.tag.empty()) fail(child.line, "a node cannot have two tags");
          child.tag = std::move(node.tag);
          child.line = node.line;
        }
        return child;
      }
      return node;
    }
    const bool tagged = !node.tag.empty();
    const int col = column();
    const char c = peek();
    if (compact && !tagged && at_sequence_indicator()) return parse_block_seq(col, parent);
    if (c == '[' || c == '{') {
      YamlNode flow = c == '[' ? parse_flow_seq() : parse_flow_map();
      flow.tag = std::move(node.tag);
      flow.line = node.line;
      skip_blanks();
      if (peek() == ':' && separated(pos_ + 1))
        fail(node.line, "complex keys (a flow collection as a key) are not supported");
      finish_line(c == '[' ? "flow sequence" : "flow map");
      return flow;
    }
    const int start_line = line_;
    Scalar s;
    if (c == '"' || c == '\'') {
      s = read_quoted();
    } else {
      check_plain_start(false);
      s.text = read_plain_line(false);
      s.plain = true;
    }
    skip_blanks();
    if (peek() == ':' && separated(pos_ + 1)) {
      if (tagged) fail(start_line, "tags on keys are not supported");
      if (!compact)
        fail(start_line, "a map cannot start on this line (quote a value that has ': ')");
      if (s.multi_line) fail(start_line, "a key and its ':' must be on one line");
      return parse_block_map(col, parent, std::move(s.text), start_line);
    }
    if (s.plain) {
      continue_plain(s.text, parent);
    } else {
      finish_line("quoted scalar");
    }
    return scalar_node(std::move(s), node.line, std::move(node.tag));
  }

  // A block map at column `indent`, positioned at the ':' after its first key.
  YamlNode parse_block_map(int indent, int parent, std::string key, int key_line) {
    DepthGuard guard(*this, key_line);
    YamlNode map;
    map.kind = YamlNode::Kind::kMap;
    map.line = key_line;
    std::unordered_set<std::string> keys;  // YamlNode::find would make this quadratic
    for (;;) {
      ++pos_;  // the ':'
      if (!keys.insert(key).second) fail(key_line, "duplicate key '" + key + "'");
      YamlEntry entry;
      entry.key = std::move(key);
      entry.line = key_line;
      entry.value = parse_block_node(indent, false, true);
      map.entries.push_back(std::move(entry));
      if (!next_sibling(indent, parent)) return map;
      key_line = line_;
      key = read_block_key();
    }
  }

  // The key of a further map entry, at the start of its line; stops at the ':'.
  std::string read_block_key() {
    const int key_line = line_;
    const char c = peek();
    if (at_sequence_indicator()) fail(key_line, "expected 'key: value', got a sequence item '- '");
    if (c == '!') fail(key_line, "tags on keys are not supported");
    if (c == '[' || c == '{')
      fail(key_line, "expected 'key: value' (complex keys are not supported)");
    std::string key;
    const bool plain = c != '"' && c != '\'';
    if (plain) {
      check_plain_start(false);
      key = read_plain_line(false);
    } else {
      Scalar s = read_quoted();
      if (s.multi_line) fail(key_line, "a key and its ':' must be on one line");
      key = std::move(s.text);
    }
    skip_blanks();
    if (peek() != ':' || !separated(pos_ + 1)) {
      // OpenCV reads "data:[1, 2]"; YAML needs the blank after ':'.
      if (plain && key.find(':') != std::string::npos)
        fail(key_line, "expected 'key: value' (put a space after ':')");
      fail(key_line, "expected 'key: value'");
    }
    return key;
  }

  // A block sequence at column `indent`, positioned at its first '-'.
  YamlNode parse_block_seq(int indent, int parent) {
    DepthGuard guard(*this, line_);
    YamlNode seq;
    seq.kind = YamlNode::Kind::kSequence;
    seq.line = line_;
    for (;;) {
      ++pos_;  // the '-'
      seq.items.push_back(parse_block_node(indent, true, false));
      if (!next_sibling(indent, parent)) return seq;
      if (!at_sequence_indicator()) {
        if (indent == parent) return seq;  // a map value at the map's column: the next key
        fail(line_, "expected a sequence item '- '");
      }
    }
  }

  // Folds the lines that continue a plain scalar (more indented than `parent`) into `text`:
  // one line break gives a space, n empty lines give n '\n'. A comment ends the scalar.
  void continue_plain(std::string& text, int parent) {
    for (;;) {
      next_content_line();
      if (saw_comment_ || current_indent() <= parent) return;
      if (empty_lines_ == 0) {
        text += ' ';
      } else {
        text.append(static_cast<std::size_t>(empty_lines_), '\n');
      }
      text += read_plain_line(false);
      // "key: value" cannot continue a scalar: the line is indented too much.
      if (peek() == ':') fail(line_, kIndentedMore);
    }
  }

  // ---- Scalars and tags --------------------------------------------------------------------

  // Rejects what cannot start a plain scalar, naming the construct.
  void check_plain_start(bool flow) const {
    const char c = peek();
    const bool indicator = flow ? flow_separated(pos_ + 1) : separated(pos_ + 1);
    if (c == '&' || c == '*') fail(line_, "anchors and aliases are not supported");
    if (c == '|' || c == '>')
      fail(line_, "block scalars (| and >) are not supported; quote the text");
    if ((c == '-' || c == '?' || c == ':') && indicator && !separated(pos_ + 1))
      fail(line_,
           std::string("'") + c + "' before '" + at(pos_ + 1) + "' is not a value; quote it");
    if (c == '?' && indicator) fail(line_, "complex keys ('? ') are not supported");
    if (c == ':' && indicator) fail(line_, "missing key before ':'");
    if (c == '-' && indicator)
      fail(line_, flow ? "a block sequence cannot start inside [ ] or { }"
                       : "a block sequence cannot start here");
    if (c == '!') fail(line_, "a node cannot have two tags");
    if (c == '#') fail(line_, "a node cannot start with '#' (a comment needs a blank before it)");
    if (is_flow_indicator(c) || c == '@' || c == '`' || c == '%')
      fail(line_, std::string("a node cannot start with '") + c + "'");
  }

  // One line of a plain scalar, trailing blanks dropped. Stops at a line break, a comment, a ':'
  // indicator and, inside [ ] and { }, a flow indicator.
  std::string read_plain_line(bool flow) {
    const std::size_t start = pos_;
    std::size_t end = pos_;
    while (!at_end()) {
      const char c = peek();
      if (c == '\n') break;
      if (c == ':' && (flow ? flow_separated(pos_ + 1) : separated(pos_ + 1))) break;
      if (c == '#' && pos_ > line_start_ && is_blank(text_[pos_ - 1])) break;
      if (flow && is_flow_indicator(c)) break;
      ++pos_;
      if (!is_blank(c)) end = pos_;
    }
    return text_.substr(start, end - start);
  }

  static YamlNode scalar_node(Scalar s, int line, std::string tag) {
    YamlNode node;
    node.line = line;
    node.tag = std::move(tag);
    const std::string& t = s.text;
    if (s.plain && (t.empty() || t == "~" || t == "null" || t == "Null" || t == "NULL"))
      return node;  // kNull
    node.kind = YamlNode::Kind::kScalar;
    node.scalar = std::move(s.text);
    return node;
  }

  // "!name", "!!name" or "!<verbatim>", which must be followed by a blank (or a flow indicator).
  std::string read_tag(bool flow) {
    const std::size_t start = pos_;
    ++pos_;
    if (peek() == '<') {
      while (!at_end() && peek() != '>' && peek() != '\n') ++pos_;
      if (peek() != '>') fail(line_, "end of verbatim tag '>' not found");
      ++pos_;
    } else {
      while (!separated(pos_) && !is_flow_indicator(peek())) ++pos_;
    }
    if (!(flow ? flow_separated(pos_) : separated(pos_)))
      fail(line_, "a tag must be followed by a space");
    return text_.substr(start, pos_ - start);
  }

  // A single- or double-quoted scalar, which may span lines.
  Scalar read_quoted() {
    const char quote = peek();
    const int open_line = line_;
    const char* unterminated = quote == '"' ? "end of double-quoted scalar '\"' not found"
                                            : "end of single-quoted scalar \"'\" not found";
    Scalar s;
    ++pos_;
    for (;;) {
      if (at_end()) fail(open_line, unterminated);
      const char c = peek();
      if (c == quote) {
        ++pos_;
        s.end_line = line_;
        if (quote == '"' || peek() != '\'') return s;
        s.text += '\'';  // '' in single quotes
        ++pos_;
      } else if (is_blank(c)) {
        std::size_t end = pos_;
        while (is_blank(at(end))) ++end;
        if (at(end) != '\n') s.text.append(text_, pos_, end - pos_);  // blanks before a break go
        pos_ = end;
      } else if (c == '\n') {
        fold_quoted_break(s, false, open_line, unterminated);
      } else if (c == '\\' && quote == '"') {
        read_escape(s, open_line, unterminated);
      } else {
        s.text += c;
        ++pos_;
      }
    }
  }

  // At a line break in a quoted scalar: one break folds into a space (none when escaped), each
  // empty line after it gives '\n'; the next line's leading blanks are dropped.
  void fold_quoted_break(Scalar& s, bool escaped, int open_line, const char* unterminated) {
    s.multi_line = true;
    int breaks = 0;
    while (peek() == '\n') {
      newline();
      if (at_document_marker()) fail(open_line, unterminated);
      ++breaks;
      skip_blanks();
    }
    if (!escaped && breaks == 1) {
      s.text += ' ';
    } else {
      s.text.append(static_cast<std::size_t>(breaks - 1), '\n');
    }
  }

  // A '\' escape in a double-quoted scalar.
  void read_escape(Scalar& s, int open_line, const char* unterminated) {
    ++pos_;  // the '\'
    if (at_end()) fail(open_line, unterminated);
    const char e = peek();
    if (e == '\n') {  // an escaped line break joins the lines without a space
      fold_quoted_break(s, true, open_line, unterminated);
      return;
    }
    ++pos_;
    switch (e) {
      // clang-format off
      case '0': s.text += '\0'; return;
      case 'a': s.text += '\a'; return;
      case 'b': s.text += '\b'; return;
      case 't': case '\t': s.text += '\t'; return;
      case 'n': s.text += '\n'; return;
      case 'v': s.text += '\v'; return;
      case 'f': s.text += '\f'; return;
      case 'r': s.text += '\r'; return;
      case 'e': s.text += '\x1b'; return;
      case ' ': case '"': case '/': case '\\': s.text += e; return;
      case 'N': append_utf8(s.text, 0x85); return;
      case '_': append_utf8(s.text, 0xA0); return;
      case 'L': append_utf8(s.text, 0x2028); return;
      case 'P': append_utf8(s.text, 0x2029); return;
      case 'x': append_code_point(s.text, 2); return;
      case 'u': append_code_point(s.text, 4); return;
      case 'U': append_code_point(s.text, 8); return;
      // clang-format on
      default:
        fail(line_, std::string("unknown escape '\\") + e + "' in a double-quoted scalar");
    }
  }

  // The code point of an \x, \u or \U escape (`digits` hex digits), in UTF-8.
  void append_code_point(std::string& out, int digits) {
    std::uint32_t cp = 0;
    for (int i = 0; i < digits; ++i) {
      const char h = peek();
      std::uint32_t value = 0;
      if (h >= '0' && h <= '9') {
        value = static_cast<std::uint32_t>(h - '0');
      } else if (h >= 'a' && h <= 'f') {
        value = static_cast<std::uint32_t>(h - 'a' + 10);
      } else if (h >= 'A' && h <= 'F') {
        value = static_cast<std::uint32_t>(h - 'A' + 10);
      } else {
        fail(line_, "an escape needs " + std::to_string(digits) + " hex digits");
      }
      cp = cp * 16 + value;
      ++pos_;
    }
    if (cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF))
      fail(line_, "escape of an invalid Unicode code point");
    append_utf8(out, cp);
  }

  // ---- Flow context ------------------------------------------------------------------------

  [[noreturn]] void fail_unterminated_flow() const {
    fail(flow_line_, flow_close_ == ']' ? "end of flow sequence ']' not found"
                                        : "end of flow map '}' not found");
  }

  // Skips blanks, line breaks and comments inside [ ] or { }; returns the line breaks passed.
  // Indentation is not checked there (PyYAML and yaml-cpp do not either).
  int skip_flow_space(bool* comment = nullptr) {
    int breaks = 0;
    for (;;) {
      if (at_end()) fail_unterminated_flow();
      if (is_blank(peek())) {
        ++pos_;
      } else if (peek() == '\n') {
        newline();
        ++breaks;
        if (at_document_marker()) fail_unterminated_flow();
      } else if (comment_starts_here()) {
        if (comment != nullptr) *comment = true;
        skip_line_rest();
      } else {
        return breaks;
      }
    }
  }

  // A node inside [ ] or { }, at its first character.
  YamlNode parse_flow_node() {
    const int line = line_;
    std::string tag;
    if (peek() == '!') {
      tag = read_tag(true);
      skip_flow_space();
      const char c = peek();
      if (c == ',' || c == ']' || c == '}' || (c == ':' && flow_separated(pos_ + 1))) {
        YamlNode empty;  // "[!tag , x]": a tagged empty node
        empty.line = line;
        empty.tag = std::move(tag);
        return empty;
      }
    }
    YamlNode node;
    if (peek() == '[') {
      node = parse_flow_seq();
    } else if (peek() == '{') {
      node = parse_flow_map();
    } else {
      node = scalar_node(read_flow_scalar(), line, "");
    }
    node.tag = std::move(tag);
    node.line = line;
    return node;
  }

  Scalar read_flow_scalar() {
    if (peek() == '"' || peek() == '\'') return read_quoted();
    check_plain_start(true);
    Scalar s;
    s.plain = true;
    s.text = read_plain_line(true);
    s.end_line = line_;
    // Continuation lines fold like block ones; a comment or an indicator ends the scalar.
    while (peek() == '\n') {
      bool comment = false;
      const int breaks = skip_flow_space(&comment);
      const char c = peek();
      if (comment || is_flow_indicator(c) || (c == ':' && flow_separated(pos_ + 1))) break;
      if (breaks == 1) {
        s.text += ' ';
      } else {
        s.text.append(static_cast<std::size_t>(breaks - 1), '\n');
      }
      s.text += read_plain_line(true);
      s.end_line = line_;
      s.multi_line = true;
    }
    return s;
  }

  // An item of [ ] or an entry of { }, at its first character; `close` is ']' or '}'.
  FlowEntry parse_flow_entry(char close) {
    FlowEntry e;
    e.key_line = line_;
    const char c = peek();
    if (c == '?' && flow_separated(pos_ + 1)) fail(line_, "complex keys ('? ') are not supported");
    if (c == '!' || c == '[' || c == '{') {
      e.node = parse_flow_node();
      skip_flow_space();
      if (peek() == ':')
        fail(e.key_line, e.node.tag.empty()
                             ? "complex keys (a flow collection as a key) are not supported"
                             : "tags on keys are not supported");
      return e;
    }
    Scalar s = read_flow_scalar();
    skip_flow_space();
    // After a quoted key (JSON style) the ':' may touch the value.
    if (peek() == ':' && (!s.plain || flow_separated(pos_ + 1))) {
      // A plain key spanning lines is invalid YAML and nearly always means a missing ']' or '}'
      // that let the next "key: value" line into the collection, so that is what is reported.
      if (s.multi_line && s.plain) fail_unterminated_flow();
      if (s.multi_line || line_ != s.end_line)
        fail(e.key_line, "a key and its ':' must be on one line");
      ++pos_;
      skip_flow_space();
      e.pair = true;
      e.key = std::move(s.text);
      e.node.line = line_;
      if (peek() != ',' && peek() != close) e.node = parse_flow_node();
      return e;
    }
    e.scalar = true;
    e.key = s.text;
    e.node = scalar_node(std::move(s), e.key_line, "");
    return e;
  }

  // After a flow entry: true after a ',', false at `close`.
  bool end_of_flow_entry(char close) {
    skip_flow_space();
    if (peek() == ',') {
      ++pos_;
      return true;
    }
    if (peek() != close)
      fail(line_, std::string("expected ',' or '") + close + "' in a flow " +
                      (close == ']' ? "sequence" : "map"));
    return false;
  }

  YamlNode parse_flow_seq() {
    DepthGuard guard(*this, line_);
    YamlNode seq;
    seq.kind = YamlNode::Kind::kSequence;
    seq.line = line_;
    const char saved_close = flow_close_;
    const int saved_line = flow_line_;
    flow_close_ = ']';
    flow_line_ = line_;
    ++pos_;  // the '['
    for (;;) {
      skip_flow_space();
      if (peek() == ']') break;  // also after a trailing ','
      FlowEntry entry = parse_flow_entry(']');
      if (entry.pair) {  // "[a: 1]": a map of one entry
        YamlNode pair;
        pair.kind = YamlNode::Kind::kMap;
        pair.line = entry.key_line;
        pair.entries.push_back(
            YamlEntry{std::move(entry.key), entry.key_line, std::move(entry.node)});
        seq.items.push_back(std::move(pair));
      } else {
        seq.items.push_back(std::move(entry.node));
      }
      if (!end_of_flow_entry(']')) break;
    }
    ++pos_;  // the ']'
    flow_close_ = saved_close;
    flow_line_ = saved_line;
    return seq;
  }

  YamlNode parse_flow_map() {
    DepthGuard guard(*this, line_);
    YamlNode map;
    map.kind = YamlNode::Kind::kMap;
    map.line = line_;
    const char saved_close = flow_close_;
    const int saved_line = flow_line_;
    flow_close_ = '}';
    flow_line_ = line_;
    std::unordered_set<std::string> keys;
    ++pos_;  // the '{'
    for (;;) {
      skip_flow_space();
      if (peek() == '}') break;
      FlowEntry entry = parse_flow_entry('}');
      if (!entry.pair) {  // "{a, b}": keys with empty values
        if (!entry.scalar)
          fail(entry.key_line, entry.node.tag.empty()
                                   ? "complex keys (a flow collection as a key) are not supported"
                                   : "tags on keys are not supported");
        entry.node = YamlNode{};
        entry.node.line = entry.key_line;
      }
      if (!keys.insert(entry.key).second) fail(entry.key_line, "duplicate key '" + entry.key + "'");
      map.entries.push_back(YamlEntry{std::move(entry.key), entry.key_line, std::move(entry.node)});
      if (!end_of_flow_entry('}')) break;
    }
    ++pos_;  // the '}'
    flow_close_ = saved_close;
    flow_line_ = saved_line;
    return map;
  }

  const std::string text_;
  const std::string& name_;
  std::size_t pos_ = 0;
  std::size_t line_start_ = 0;
  int line_ = 1;
  int depth_ = 0;
  int empty_lines_ = 0;       // empty lines passed by the last next_content_line()
  bool saw_comment_ = false;  // the last next_content_line() passed a comment
  char flow_close_ = ']';     // the innermost open flow collection's closer...
  int flow_line_ = 1;         // ...and the line of its opener
};

}  // namespace

YamlNode parse_yaml(std::string_view text, const std::string& name) {
  return Parser(normalize(text, name), name).parse_document();
}

}  // namespace mcslam::io::detail
