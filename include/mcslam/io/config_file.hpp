#pragma once
// Key-tracking reader of YAML settings files (the only place the project parses YAML). Upper
// layers fill their option structs through read() and report unused_keys() as likely typos.
//
// Keys are flattened with '.': `camera: {fx: 500}` gives the key "camera.fx"; ORB-SLAM2 style
// top-level keys such as "Camera.fx" stay as they are. An OpenCV matrix node (`!!opencv-matrix`,
// a map with rows, cols, dt and data) is one leaf. OpenCV's "%YAML:1.0" first line is accepted.

#include <map>
#include <set>
#include <string>
#include <vector>

namespace mcslam::io {

class ConfigFile {
 public:
  /// Throws InputError for a missing or unreadable file, a YAML syntax error ("<file>:<line>:
  /// ..."), a top level that is not a map, duplicate keys and malformed OpenCV matrices.
  static ConfigFile load(const std::string& path);
  /// Same as load() for YAML text; `name` stands for the file name in messages.
  static ConfigFile from_string(const std::string& yaml, const std::string& name = "<string>");

  /// The file's path (or the name given to from_string()).
  const std::string& path() const { return path_; }
  /// True when `key` is a leaf key of the file.
  bool has(const std::string& key) const;

  // Each read(): when the key is present, parses it into `value`, marks the key used and
  // returns true; when absent, leaves `value` unchanged and returns false. A present key of the
  // wrong type throws InputError "<file>:<line>: key 'Camera.fx': expected a number, got 'abc'".
  bool read(const std::string& key, double& value);       ///< finite numbers, e.g. 517.3, 1e-3
  bool read(const std::string& key, int& value);          ///< integers (30.0 is 30; 1.5 throws)
  bool read(const std::string& key, bool& value);         ///< true/false, also 0/1
  bool read(const std::string& key, std::string& value);  ///< any scalar; an empty value is ""
  /// A YAML sequence of numbers, or an OpenCV matrix node (its data, row-major).
  bool read(const std::string& key, std::vector<double>& value);

  /// Marks a recognised-but-ignored key used; also every key below it ("Viewer" marks
  /// "Viewer.KeyFrameSize", ...). Unknown keys are ignored.
  void mark_used(const std::string& key);
  /// All leaf keys, flattened, sorted.
  std::vector<std::string> keys() const;
  /// Leaf keys never read nor marked, sorted.
  std::vector<std::string> unused_keys() const;

 private:
  enum class Kind { kNull, kScalar, kSequence, kMap, kMatrix };
  struct Leaf {
    Kind kind = Kind::kNull;
    int line = 0;                    // 1-based line of the value
    std::string scalar;              // kScalar
    std::vector<std::string> items;  // kSequence (scalar items) and kMatrix (its data)
    bool nested_items = false;       // kSequence: some item is not a scalar
  };
  friend struct ConfigFileBuilder;

  const Leaf* find(const std::string& key);
  [[noreturn]] void type_error(const std::string& key, const Leaf& leaf,
                               const std::string& expected) const;

  std::string path_;
  std::map<std::string, Leaf> leaves_;
  std::set<std::string> used_;
};

}  // namespace mcslam::io
