// Fuzzes the settings reader: the input is parsed as a YAML settings file, then every key is read
// as each type a setting can have. Bad text must end in InputError.
#include <string>
#include <vector>

#include "fuzz_support.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/io/config_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mcslam;
  try {
    io::ConfigFile file =
        io::ConfigFile::from_string(std::string(fuzz::as_text(data, size)), "fuzz.yaml");
    for (const std::string& key : file.keys()) {
      try {
        double d = 0;
        file.read(key, d);
      } catch (const InputError&) {
      }
      try {
        int i = 0;
        file.read(key, i);
      } catch (const InputError&) {
      }
      try {
        bool b = false;
        file.read(key, b);
      } catch (const InputError&) {
      }
      try {
        std::string s;
        file.read(key, s);
      } catch (const InputError&) {
      }
      try {
        std::vector<double> v;
        file.read(key, v);
      } catch (const InputError&) {
      }
    }
    file.mark_used("a");
    (void)file.unused_keys();
  } catch (const InputError&) {
  }
  return 0;
}
