#pragma once
// Tiny ONNX models for tests: a hand-written protobuf encoder, enough for a graph that reshapes a
// 1x3xHxW input into a chosen output shape (what a detector's loader checks).

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace mcslam::test {

inline std::string varint(std::uint64_t v) {
  std::string out;
  do {
    const auto byte = static_cast<unsigned char>((v & 0x7f) | (v > 0x7f ? 0x80 : 0));
    out += static_cast<char>(byte);
    v >>= 7;
  } while (v != 0);
  return out;
}
inline std::string field(int number, std::uint64_t value) {
  return varint(static_cast<std::uint64_t>(number) << 3) + varint(value);
}
inline std::string field(int number, const std::string& payload) {
  return varint((static_cast<std::uint64_t>(number) << 3) | 2) + varint(payload.size()) + payload;
}

inline std::string value_info(const std::string& name, const std::vector<std::int64_t>& dims) {
  std::string shape;
  for (std::int64_t d : dims) shape += field(1, field(1, static_cast<std::uint64_t>(d)));
  const std::string tensor = field(1, std::uint64_t{1}) + field(2, shape);  // float
  return field(1, name) + field(2, field(1, tensor));
}

/// A valid ONNX model: a 1x3xHxW input reshaped to `output` (an int64 initializer holds the
/// shape), with optional metadata.
inline std::string tiny_onnx(
    int size, const std::vector<std::int64_t>& output,
    const std::vector<std::pair<std::string, std::string>>& metadata = {}) {
  std::string raw;
  for (std::int64_t v : output)
    for (int b = 0; b < 8; ++b)
      raw += static_cast<char>((static_cast<std::uint64_t>(v) >> (8 * b)) & 0xff);
  const std::string shape_tensor = field(1, static_cast<std::uint64_t>(output.size())) +
                                   field(2, std::uint64_t{7}) + field(8, std::string("shape")) +
                                   field(9, raw);
  const std::string node = field(1, std::string("images")) + field(1, std::string("shape")) +
                           field(2, std::string("out")) + field(3, std::string("reshape")) +
                           field(4, std::string("Reshape"));
  const std::string graph =
      field(1, node) + field(2, std::string("tiny")) + field(5, shape_tensor) +
      field(11, value_info("images", {1, 3, size, size})) + field(12, value_info("out", output));
  std::string model = field(1, std::uint64_t{7}) + field(2, std::string("mcslam-test")) +
                      field(7, graph) + field(8, field(2, std::uint64_t{13}));
  for (const auto& [key, value] : metadata) model += field(14, field(1, key) + field(2, value));
  return model;
}

}  // namespace mcslam::test
