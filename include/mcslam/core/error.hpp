#pragma once
// Errors raised while loading input (files, configs, models). The per-frame path never throws;
// it reports a TrackingState instead.

#include <stdexcept>
#include <string>

namespace mcslam {

/// Bad input detected while loading: the message names the file (or option) and the problem.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Builds "<path>: <problem>" for InputError messages.
inline std::string file_error(const std::string& path, const std::string& problem) {
  return path + ": " + problem;
}

}  // namespace mcslam
