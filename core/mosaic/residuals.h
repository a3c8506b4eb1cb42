#pragma once
// Internal to the mosaic library (core/mosaic), not part of its API: the residual, the step
// (manifold) and the whitening shared by the bundle adjustment (adjustment.cc, through Ceres) and
// the chain solver (chain_solver.cc, Gauss-Newton with analytic Jacobians). The model is described
// in adjustment.h and docs/mosaic.md. Ceres stays out of this header: the residual and the step
// are templates that ceres::Jet and double both instantiate.
#include "core/track/homography.h"
#include "core/track/types.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cstddef>

namespace saker::mosaic::internal {

constexpr int kParameters = 8;  // per frame: types.h order, H(2,2) = 1
constexpr int kResiduals = 8;   // per block: 4 corners x 2 coordinates

template <typename T>
using Matrix3 = Eigen::Matrix<T, 3, 3>;

template <typename T>
Matrix3<T> HomographyFrom(const T* p) {
  Matrix3<T> h;
  h << p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], static_cast<T>(1);
  return h;
}

// The adjugate: the inverse times the determinant. Homogeneous use only needs the inverse up to
// scale, so there is no division (autodiff friendly, no sign or size assumption).
template <typename T>
Matrix3<T> Adjugate(const Matrix3<T>& m) {
  Matrix3<T> a;
  a(0, 0) = m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1);
  a(0, 1) = m(0, 2) * m(2, 1) - m(0, 1) * m(2, 2);
  a(0, 2) = m(0, 1) * m(1, 2) - m(0, 2) * m(1, 1);
  a(1, 0) = m(1, 2) * m(2, 0) - m(1, 0) * m(2, 2);
  a(1, 1) = m(0, 0) * m(2, 2) - m(0, 2) * m(2, 0);
  a(1, 2) = m(0, 2) * m(1, 0) - m(0, 0) * m(1, 2);
  a(2, 0) = m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0);
  a(2, 1) = m(0, 1) * m(2, 0) - m(0, 0) * m(2, 1);
  a(2, 2) = m(0, 0) * m(1, 1) - m(0, 1) * m(1, 0);
  return a;
}

// h c dehomogenised into out; false when c maps to infinity.
template <typename T>
bool Project(const Matrix3<T>& h, const Eigen::Vector2d& c, T* out) {
  const T w = h(2, 0) * c.x() + h(2, 1) * c.y() + h(2, 2);
  if (w == static_cast<T>(0)) return false;
  out[0] = (h(0, 0) * c.x() + h(0, 1) * c.y() + h(0, 2)) / w;
  out[1] = (h(1, 0) * c.x() + h(1, 1) * c.y() + h(1, 2)) / w;
  return true;
}

// The step of a frame: M (+) d = M N^-1 (I + D(d)) N, normalised, with N taking the frame's
// pixels to [-1, 1] around the image centre. A step of 1 moves the image corners by about the
// image size whatever the map frame is (metres thousands of metres from the origin, or pixels),
// which keeps the normal equations and the covariance well conditioned.
struct HomographyStep {
  double f = 1, cx = 0, cy = 0;  // normalised = (pixel - c) / f

  // The step of a width x height image (pixels centred, half the larger side is 1).
  static HomographyStep ForImage(int width, int height) {
    const double w = width - 1, h = height - 1;
    return HomographyStep{std::max(1.0, 0.5 * std::max(w, h)), 0.5 * w, 0.5 * h};
  }

  template <typename T>
  Matrix3<T> NormalisedFromPixel() const {
    Matrix3<T> n;
    n << static_cast<T>(1 / f), static_cast<T>(0), static_cast<T>(-cx / f), static_cast<T>(0),
        static_cast<T>(1 / f), static_cast<T>(-cy / f), static_cast<T>(0), static_cast<T>(0),
        static_cast<T>(1);
    return n;
  }
  template <typename T>
  Matrix3<T> PixelFromNormalised() const {
    Matrix3<T> n;
    n << static_cast<T>(f), static_cast<T>(0), static_cast<T>(cx), static_cast<T>(0),
        static_cast<T>(f), static_cast<T>(cy), static_cast<T>(0), static_cast<T>(0),
        static_cast<T>(1);
    return n;
  }

  template <typename T>
  bool Plus(const T* x, const T* delta, T* x_plus_delta) const {
    Matrix3<T> d;
    d << static_cast<T>(1) + delta[0], delta[1], delta[2], delta[3], static_cast<T>(1) + delta[4],
        delta[5], delta[6], delta[7], static_cast<T>(1);
    const Matrix3<T> m =
        HomographyFrom(x) * PixelFromNormalised<T>() * d * NormalisedFromPixel<T>();
    if (m(2, 2) == static_cast<T>(0)) return false;
    for (int i = 0; i < kParameters; ++i) x_plus_delta[i] = m(i / 3, i % 3) / m(2, 2);
    return true;
  }

  template <typename T>
  bool Minus(const T* y, const T* x, T* y_minus_x) const {
    const Matrix3<T> k = NormalisedFromPixel<T>() * Adjugate(HomographyFrom(x)) *
                         HomographyFrom(y) * PixelFromNormalised<T>();
    if (k(2, 2) == static_cast<T>(0)) return false;
    for (int i = 0; i < kParameters; ++i) y_minus_x[i] = k(i / 3, i % 3) / k(2, 2);
    y_minus_x[0] -= static_cast<T>(1);
    y_minus_x[4] -= static_cast<T>(1);
    return true;
  }

  // d Plus(x, delta) / d delta at delta = 0 (analytic): takes a covariance of the step (the
  // tangent space) to one of the 8 parameters, as Ceres's Covariance does with the manifold.
  Eigen::Matrix<double, kParameters, kParameters> PlusJacobian(const double* x) const {
    // dM = A E(delta) B with A = M N^-1, B = N; normalised: dh_j = dM_j - h_j dM_22 (M_22 = 1).
    const Eigen::Matrix3d a = HomographyFrom(x) * PixelFromNormalised<double>();
    const Eigen::Matrix3d b = NormalisedFromPixel<double>();
    Eigen::Matrix<double, kParameters, kParameters> j;
    for (int row = 0; row < kParameters; ++row) {
      const int r = row / 3, c = row % 3;
      for (int col = 0; col < kParameters; ++col) {
        const int k = col / 3, l = col % 3;
        j(row, col) = a(r, k) * b(l, c) - x[row] * a(2, k) * b(l, 2);
      }
    }
    return j;
  }
};

// whitening * (M_to^-1 M_from c - to_from_from c) over the 4 corners c of the `from` image.
struct LinkResidual {
  std::array<Eigen::Vector2d, 4> corners;
  Eigen::Matrix<double, kResiduals, 1> measured;
  Eigen::Matrix<double, kResiduals, kResiduals> whitening;

  template <typename T>
  bool operator()(const T* from, const T* to, T* residual) const {
    const Matrix3<T> to_from_from = Adjugate(HomographyFrom(to)) * HomographyFrom(from);
    Eigen::Matrix<T, kResiduals, 1> error;
    for (int i = 0; i < 4; ++i) {
      if (!Project(to_from_from, corners[static_cast<size_t>(i)], error.data() + 2 * i))
        return false;
    }
    for (int i = 0; i < kResiduals; ++i) error(i) -= measured(i);
    // Double times Jet (cheaper than a Jet matrix product).
    for (int r = 0; r < kResiduals; ++r) {
      T sum = whitening(r, 0) * error(0);
      for (int c = 1; c < kResiduals; ++c) sum += whitening(r, c) * error(c);
      residual[r] = sum;
    }
    return true;
  }
};

// W with W^T W = (J C J^T + floor^2 I)^-1: L^-1 of the Cholesky factor, or from the eigen
// decomposition with negative eigenvalues clamped when C is not positive semi-definite. J is the
// stacked TransferJacobian of the measurement at the corners, C its covariance.
inline Eigen::Matrix<double, kResiduals, kResiduals> LinkWhitening(
    const Eigen::Matrix3d& to_from_from, const track::HomographyCovariance& covariance,
    const std::array<Eigen::Vector2d, 4>& corners, double floor_px) {
  using Matrix8 = Eigen::Matrix<double, kResiduals, kResiduals>;
  Eigen::Matrix<double, kResiduals, kParameters> j;
  for (int i = 0; i < 4; ++i) {
    j.middleRows<2>(2 * i) = track::TransferJacobian(to_from_from, corners[static_cast<size_t>(i)]);
  }
  Matrix8 cov = j * covariance * j.transpose();
  cov = 0.5 * (cov + cov.transpose()).eval();
  const Matrix8 floored = cov + floor_px * floor_px * Matrix8::Identity();
  const Eigen::LLT<Matrix8> llt(floored);
  if (llt.info() == Eigen::Success) {
    return llt.matrixL().solve(Matrix8::Identity());
  }
  const Eigen::SelfAdjointEigenSolver<Matrix8> eigen(cov);
  const Eigen::Matrix<double, kResiduals, 1> inv_sd =
      (eigen.eigenvalues().cwiseMax(0).array() + floor_px * floor_px).rsqrt();
  return inv_sd.asDiagonal() * eigen.eigenvectors().transpose();
}

// The residual of a measured to_from_from (with its 8x8 covariance, types.h order) between two
// frames whose corners are `corners`.
inline LinkResidual MakeLinkResidual(const Eigen::Matrix3d& to_from_from,
                                     const track::HomographyCovariance& covariance,
                                     const std::array<Eigen::Vector2d, 4>& corners,
                                     double floor_px) {
  LinkResidual residual{corners, {}, LinkWhitening(to_from_from, covariance, corners, floor_px)};
  for (int i = 0; i < 4; ++i) {
    residual.measured.segment<2>(2 * i) =
        track::Transfer(to_from_from, corners[static_cast<size_t>(i)]);
  }
  return residual;
}

// The link residual at (from, to) (8 parameters each) and, analytically, its Jacobians with
// respect to the steps of `from` and `to` (HomographyStep, at zero): the derivatives of
// link(step.Plus(from, d_from), step.Plus(to, d_to)) at d = 0. False when a corner maps to
// infinity. The residual is homogeneous in M_from and M_to, so the normalisation of Plus drops out.
//
// With G = adj(M_to) M_from, p = G c, q = N c and s = N p:
//   from: dp = G N^-1 D(d) q          to: dp = -N^-1 D(d) s
// and d(p / p_z) = (1 / p_z) [1 0 -u; 0 1 -v] dp, (u, v) the projected corner.
inline bool LinkResidualJacobians(const LinkResidual& link, const HomographyStep& step,
                                  const double* from, const double* to,
                                  Eigen::Matrix<double, kResiduals, 1>* residual,
                                  Eigen::Matrix<double, kResiduals, kParameters>* d_from,
                                  Eigen::Matrix<double, kResiduals, kParameters>* d_to) {
  const Eigen::Matrix3d g = Adjugate(HomographyFrom(to)) * HomographyFrom(from);
  const Eigen::Matrix3d g_pixel = g * step.PixelFromNormalised<double>();  // G N^-1
  const double inverse_f = 1 / step.f;
  Eigen::Matrix<double, kResiduals, 1> error;
  Eigen::Matrix<double, kResiduals, kParameters> jf, jt;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d& c = link.corners[static_cast<size_t>(i)];
    const Eigen::Vector3d p = g * c.homogeneous();
    if (p.z() == 0) return false;
    const double u = p.x() / p.z(), v = p.y() / p.z(), iw = 1 / p.z();
    error(2 * i) = u - link.measured(2 * i);
    error(2 * i + 1) = v - link.measured(2 * i + 1);
    Eigen::Matrix<double, 2, 3> projection;
    projection << iw, 0, -u * iw, 0, iw, -v * iw;
    // from: projection * G N^-1 * [q0 q1 1 0 0 0 0 0; 0 0 0 q0 q1 1 0 0; 0 0 0 0 0 0 q0 q1].
    const Eigen::Matrix<double, 2, 3> k = projection * g_pixel;
    const double q0 = (c.x() - step.cx) * inverse_f, q1 = (c.y() - step.cy) * inverse_f;
    auto rows_f = jf.middleRows<2>(2 * i);
    rows_f << k.col(0) * q0, k.col(0) * q1, k.col(0), k.col(1) * q0, k.col(1) * q1, k.col(1),
        k.col(2) * q0, k.col(2) * q1;
    // to: -projection * N^-1 * [s0 s1 s2 0 0 0 0 0; 0 0 0 s0 s1 s2 0 0; 0 0 0 0 0 0 s0 s1].
    const Eigen::Matrix<double, 2, 3> kt = -projection * step.PixelFromNormalised<double>();
    const double s0 = (p.x() - step.cx * p.z()) * inverse_f;
    const double s1 = (p.y() - step.cy * p.z()) * inverse_f, s2 = p.z();
    auto rows_t = jt.middleRows<2>(2 * i);
    rows_t << kt.col(0) * s0, kt.col(0) * s1, kt.col(0) * s2, kt.col(1) * s0, kt.col(1) * s1,
        kt.col(1) * s2, kt.col(2) * s0, kt.col(2) * s1;
  }
  // Lazy (coefficient-based) products: Eigen's general product path costs more than the
  // arithmetic at this size.
  *residual = link.whitening.lazyProduct(error);
  *d_from = link.whitening.lazyProduct(jf);
  *d_to = link.whitening.lazyProduct(jt);
  return true;
}

}  // namespace saker::mosaic::internal
