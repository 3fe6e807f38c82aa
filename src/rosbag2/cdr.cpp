#include "mcslam/rosbag2/cdr.hpp"

#include <bit>

namespace mcslam::rosbag2 {
namespace {

constexpr bool kHostLittle = std::endian::native == std::endian::little;

template <typename T>
T load(const std::uint8_t* p, bool little) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  if (little != kHostLittle) {
    if constexpr (sizeof(T) == 2)
      v = static_cast<T>(__builtin_bswap16(static_cast<std::uint16_t>(v)));
    if constexpr (sizeof(T) == 4)
      v = static_cast<T>(__builtin_bswap32(static_cast<std::uint32_t>(v)));
    if constexpr (sizeof(T) == 8)
      v = static_cast<T>(__builtin_bswap64(static_cast<std::uint64_t>(v)));
  }
  return v;
}

}  // namespace

CdrReader::CdrReader(const std::uint8_t* data, std::size_t size) {
  if (size < 4)
    throw CdrError("the message is " + std::to_string(size) +
                   " bytes, shorter than the 4-byte CDR encapsulation header");
  const unsigned kind = (static_cast<unsigned>(data[0]) << 8) | data[1];
  switch (kind) {
    case 0x0000:
      little_ = false;
      break;  // CDR_BE
    case 0x0001:
      little_ = true;
      break;  // CDR_LE
    case 0x0006:
      little_ = false;
      max_align_ = 4;
      break;  // CDR2_BE (plain, final types)
    case 0x0007:
      little_ = true;
      max_align_ = 4;
      break;  // CDR2_LE
    default: {
      char text[8];
      std::snprintf(text, sizeof(text), "%02x %02x", data[0], data[1]);
      throw CdrError(std::string("unknown CDR encapsulation ") + text +
                     " (use plain CDR: 00 01 little-endian or 00 00 big-endian)");
    }
  }
  body_ = data + 4;
  size_ = size - 4;
}

void CdrReader::need(std::size_t n, const char* field) const {
  if (n > size_ - pos_)
    throw CdrError(std::string("the message is shorter than its fields: ") + field + " needs " +
                   std::to_string(n) + " bytes at offset " + std::to_string(pos_ + 4) + " of " +
                   std::to_string(size_ + 4));
}

void CdrReader::align(std::size_t n) {
  if (n > max_align_) n = max_align_;
  const std::size_t pad = (n - pos_ % n) % n;
  pos_ = pad > size_ - pos_ ? size_ : pos_ + pad;
}

std::uint8_t CdrReader::u8(const char* field) {
  need(1, field);
  return body_[pos_++];
}
std::uint16_t CdrReader::u16(const char* field) {
  align(2);
  need(2, field);
  const auto v = load<std::uint16_t>(body_ + pos_, little_);
  pos_ += 2;
  return v;
}
std::uint32_t CdrReader::u32(const char* field) {
  align(4);
  need(4, field);
  const auto v = load<std::uint32_t>(body_ + pos_, little_);
  pos_ += 4;
  return v;
}
std::uint64_t CdrReader::u64(const char* field) {
  align(8);
  need(8, field);
  const auto v = load<std::uint64_t>(body_ + pos_, little_);
  pos_ += 8;
  return v;
}
double CdrReader::f64(const char* field) { return std::bit_cast<double>(u64(field)); }

std::string_view CdrReader::string(const char* field) {
  const std::uint32_t n = u32(field);
  need(n, field);
  const char* p = reinterpret_cast<const char*>(body_ + pos_);
  pos_ += n;
  if (n == 0) return {};  // some writers store an empty string as length 0
  if (p[n - 1] != '\0')
    throw CdrError(std::string("the string ") + field + " does not end in a NUL");
  return {p, n - 1};
}

std::pair<const std::uint8_t*, std::size_t> CdrReader::bytes(const char* field) {
  const std::uint32_t n = u32(field);
  need(n, field);
  const std::uint8_t* p = body_ + pos_;
  pos_ += n;
  return {p, n};
}

std::uint32_t CdrReader::sequence_length(const char* field, std::size_t min_element) {
  const std::uint32_t n = u32(field);
  if (min_element > 0 && n > remaining() / min_element)
    throw CdrError(std::string("the message is shorter than its fields: ") + field + " has " +
                   std::to_string(n) + " elements but " + std::to_string(remaining()) +
                   " bytes are left");
  return n;
}

void CdrReader::f64_array(double* out, std::size_t n, const char* field) {
  if (n == 0) return;
  align(8);
  need(8 * n, field);
  for (std::size_t i = 0; i < n; ++i)
    out[i] = std::bit_cast<double>(load<std::uint64_t>(body_ + pos_ + 8 * i, little_));
  pos_ += 8 * n;
}

CdrWriter::CdrWriter() { out_ = {0x00, 0x01, 0x00, 0x00}; }

void CdrWriter::align(std::size_t n) {
  const std::size_t pos = out_.size() - 4;
  out_.resize(out_.size() + (n - pos % n) % n, 0);
}

void CdrWriter::put(const void* v, std::size_t n) {
  static_assert(kHostLittle, "CdrWriter writes little-endian CDR on a little-endian host");
  align(n);
  const auto* p = static_cast<const std::uint8_t*>(v);
  out_.insert(out_.end(), p, p + n);
}

void CdrWriter::string(std::string_view s) {
  u32(static_cast<std::uint32_t>(s.size() + 1));
  out_.insert(out_.end(), s.begin(), s.end());
  out_.push_back(0);
}

void CdrWriter::bytes(const std::uint8_t* data, std::size_t size) {
  u32(static_cast<std::uint32_t>(size));
  out_.insert(out_.end(), data, data + size);
}

std::uint8_t* CdrWriter::reserve_bytes(std::size_t size) {
  u32(static_cast<std::uint32_t>(size));
  const std::size_t at = out_.size();
  out_.resize(at + size);
  return out_.data() + at;
}

void CdrWriter::f64_sequence(const std::vector<double>& v) {
  u32(static_cast<std::uint32_t>(v.size()));
  f64_array(v.data(), v.size());
}

void CdrWriter::f64_array(const double* v, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) f64(v[i]);
}

}  // namespace mcslam::rosbag2
