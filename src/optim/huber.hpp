#pragma once
// The Huber loss of a residual block as the solvers of this module apply it (Ceres's way for a
// loss whose rho'' <= 0): the block adds rho(s) / 2 to the cost, s = |r|^2, and enters the normal
// equations with the weight rho'(s).

#include <cmath>

namespace mcslam::optim {

struct HuberTerm {
  double rho = 0.0;     // rho(s)
  double weight = 1.0;  // rho'(s)
};

/// rho(s) = s for s <= delta^2, else 2 delta sqrt(s) - delta^2; rho' = min(1, delta / sqrt(s)).
/// delta = 0: no loss (rho = s).
inline HuberTerm huber(double s, double delta) {
  if (!(delta > 0.0) || s <= delta * delta) return {s, 1.0};
  const double root = std::sqrt(s);
  return {2.0 * delta * root - delta * delta, delta / root};
}

}  // namespace mcslam::optim
