// Fuzzes the vocabulary file reader. The first byte chooses how the rest is read: as the whole
// file (checksum included, so corrupt files are rejected by it), or as a file body to which the
// valid checksum is appended (so the header and tree checks behind the checksum are reached).
// A file that loads must give a usable vocabulary: every descriptor has a word, transforms are
// normalised, and saved again it loads with the same id.
#include <cmath>

#include "fuzz_support.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/place/vocabulary.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mcslam;
  if (size == 0) return 0;
  std::string bytes(fuzz::as_text(data + 1, size - 1));
  if (data[0] & 1) {
    const std::uint64_t sum = place::file_checksum(bytes);
    bytes.append(reinterpret_cast<const char*>(&sum), sizeof(sum));
  }
  const std::string path = fuzz::write("vocabulary.bin", bytes);
  std::optional<place::Vocabulary> voc;
  try {
    voc = place::Vocabulary::load(path);
  } catch (const InputError&) {
    return 0;
  }
  if (voc->words() < 1 || voc->nodes() < voc->words()) __builtin_trap();
  std::vector<features::OrbDescriptor> descriptors(3);
  descriptors[1].bytes.fill(0xFF);
  descriptors[2].bytes.fill(0x5A);
  for (const auto& d : descriptors)
    if (static_cast<int>(voc->word_of(d)) >= voc->words()) __builtin_trap();
  const place::BowImage image = voc->transform(descriptors);
  double total = 0.0;
  for (const auto& [word, weight] : image.bow) {
    if (!(weight > 0.0) || static_cast<int>(word) >= voc->words()) __builtin_trap();
    total += weight;
  }
  if (!image.bow.empty() && std::abs(total - 1.0) > 1e-9) __builtin_trap();
  const std::string copy = (fuzz::scratch() / "copy.bin").string();
  voc->save(copy);
  if (place::Vocabulary::load(copy).id() != voc->id()) __builtin_trap();
  return 0;
}
