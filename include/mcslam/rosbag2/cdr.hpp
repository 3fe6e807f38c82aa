#pragma once
// OMG CDR (XCDR1, and XCDR2's plain final encoding) as ROS 2 serialises messages: a 4-byte
// encapsulation header (00 00 big-endian, 00 01 little-endian; 00 06 / 00 07 for XCDR2), then
// the fields, each primitive aligned to its size counted from the byte after the header (XCDR2
// aligns 8-byte primitives to 4). Strings are a uint32 length that counts the NUL, the bytes and
// the NUL; sequences a uint32 count and the elements.

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace mcslam::rosbag2 {

/// A message shorter than its fields, or an encapsulation this reader does not know.
class CdrError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class CdrReader {
 public:
  /// Reads the encapsulation header; throws CdrError for a payload shorter than 4 bytes or an
  /// unknown encapsulation kind.
  CdrReader(const std::uint8_t* data, std::size_t size);

  bool little_endian() const { return little_; }
  std::size_t position() const { return pos_; }
  std::size_t remaining() const { return size_ - pos_; }

  std::uint8_t u8(const char* field);
  bool boolean(const char* field) { return u8(field) != 0; }
  std::uint16_t u16(const char* field);
  std::uint32_t u32(const char* field);
  std::int32_t i32(const char* field) { return static_cast<std::int32_t>(u32(field)); }
  std::uint64_t u64(const char* field);
  double f64(const char* field);
  /// The characters (without the NUL); a view into the payload.
  std::string_view string(const char* field);
  /// A sequence<uint8>: its bytes, a view into the payload.
  std::pair<const std::uint8_t*, std::size_t> bytes(const char* field);
  /// A sequence count checked against the bytes left (each element at least `min_element` bytes).
  std::uint32_t sequence_length(const char* field, std::size_t min_element);
  void f64_array(double* out, std::size_t n, const char* field);

 private:
  void need(std::size_t n, const char* field) const;
  void align(std::size_t n);
  const std::uint8_t* body_;  // after the header
  std::size_t size_;          // of the body
  std::size_t pos_ = 0;
  bool little_ = true;
  std::size_t max_align_ = 8;
};

/// Writes little-endian XCDR1 (what ROS 2's default middleware writes).
class CdrWriter {
 public:
  CdrWriter();
  void u8(std::uint8_t v) { out_.push_back(v); }
  void boolean(bool v) { u8(v ? 1 : 0); }
  void u16(std::uint16_t v) { put(&v, 2); }
  void u32(std::uint32_t v) { put(&v, 4); }
  void i32(std::int32_t v) { put(&v, 4); }
  void u64(std::uint64_t v) { put(&v, 8); }
  void f64(double v) { put(&v, 8); }
  void string(std::string_view s);
  void bytes(const std::uint8_t* data, std::size_t size);
  void f64_sequence(const std::vector<double>& v);
  void f64_array(const double* v, std::size_t n);
  /// Reserves a sequence<uint8> of `size` bytes and returns where to write them.
  std::uint8_t* reserve_bytes(std::size_t size);
  const std::vector<std::uint8_t>& data() const { return out_; }
  std::vector<std::uint8_t> take() { return std::move(out_); }

 private:
  void align(std::size_t n);
  void put(const void* v, std::size_t n);
  std::vector<std::uint8_t> out_;
};

}  // namespace mcslam::rosbag2
