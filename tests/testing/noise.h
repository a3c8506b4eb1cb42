#pragma once

// Deterministic test noise shared by tests and benchmarks.

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <random>

namespace saker::testing {

// Test noise from a fully specified engine and our own transforms (the standard distributions
// differ between library versions), so the figures are the same everywhere.
class Noise {
 public:
  explicit Noise(uint64_t seed) : engine_(seed) {}

  // Uniform on [lo, hi) from the top 53 bits of one engine draw.
  double Uniform(double lo, double hi) {
    return lo + (hi - lo) * (static_cast<double>(engine_() >> 11) * 0x1.0p-53);
  }

  // Standard normal by Box-Muller (two uniforms per draw); 1 - u keeps the logarithm finite.
  double Gaussian() {
    const double u = 1.0 - Uniform(0, 1);
    const double v = Uniform(0, 1);
    return std::sqrt(-2.0 * std::log(u)) * std::cos(2.0 * M_PI * v);
  }

  // Two independent N(0, sigma^2) draws.
  Eigen::Vector2d Gaussian2(double sigma) {
    return sigma * Eigen::Vector2d(Gaussian(), Gaussian());
  }

  // A draw from N(0, cov) through the Cholesky factor.
  template <int N>
  Eigen::Matrix<double, N, 1> Draw(const Eigen::Matrix<double, N, N>& cov) {
    Eigen::Matrix<double, N, 1> z;
    for (int i = 0; i < N; ++i) z(i) = Gaussian();
    const Eigen::Matrix<double, N, N> l = cov.llt().matrixL();
    return l * z;
  }

  // A draw from N(mean, cov) through the Cholesky factor.
  template <int N>
  Eigen::Matrix<double, N, 1> Draw(const Eigen::Matrix<double, N, 1>& mean,
                                   const Eigen::Matrix<double, N, N>& cov) {
    return mean + Draw<N>(cov);
  }

 private:
  std::mt19937_64 engine_;
};

}  // namespace saker::testing
