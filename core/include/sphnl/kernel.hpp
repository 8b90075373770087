#pragma once
// The 3-D cubic spline kernel (paper eq. 1, Monaghan & Lattanzio 1985) and the
// constants of the pair interaction, precomputed once per smoothing length h.
#include <cmath>
#include <numbers>

namespace sphnl {

struct CubicSpline {
  double h = 0, inv_h = 0;
  double a2 = 0;                 // 1/(pi h^3): the 3-D normalisation of W
  double aa = 0;                 // 1/(pi h^4)
  double c1 = 0, d1 = 0, c2 = 0; // F = dW/dr / r coefficients
  double support2 = 0;           // (2h)^2: a pair interacts when r^2 < support2
  double inv_w_dp = 0;           // 1/W(dp), dp = h/1.5: tensile correction f = W/W(dp)

  static constexpr double kMinR2 = 1e-18;  // coincident particles never interact

  CubicSpline() = default;
  explicit CubicSpline(double smoothing_length) {
    h = smoothing_length;
    inv_h = 1.0 / h;
    a2 = 1.0 / (std::numbers::pi * h * h * h);
    aa = 1.0 / (std::numbers::pi * h * h * h * h);
    c1 = -3.0 * aa;
    d1 = 9.0 * aa / 4.0;
    c2 = -3.0 * aa / 4.0;
    support2 = 4.0 * h * h;
    inv_w_dp = 1.0 / w(h / 1.5);
  }

  // The one definition of the kernel maths. The pair loops call the two
  // polynomials below with q = r/h < 2 (the distance filter guarantees it) and
  // select the branch without a jump, so that they vectorise; w() and f() add
  // the q > 2 case for callers that have not filtered.

  /// W at q = r/h in [0, 2], eq. 1: both pieces of the cubic spline. `Real`
  /// is the arithmetic the caller evaluates in (double, or float for
  /// precision = mixed); the coefficients are rounded to it once
  /// (`Polynomials`).
  template <class Real>
  Real w_of_q(Real q) const {
    return polynomials<Real>().w_of_q(q);
  }
  /// r F = dW/dr at q = r/h in [0, 2]; F = (dW/dr)/r is this times 1/r.
  template <class Real>
  Real dwdr_of_q(Real q) const {
    return polynomials<Real>().dwdr_of_q(q);
  }

  /// The two polynomials with their coefficients in `Real`. A pair loop
  /// keeps one outside the loop: rounding a coefficient inside it would put
  /// a conversion (which may raise an FP exception) in each branch of the
  /// select, and GCC then keeps the branch instead of vectorising.
  template <class Real>
  struct Polynomials {
    Real a2, c1, d1, c2;
    Real w_of_q(Real q) const {
      const Real t = Real(2) - q;
      return q <= Real(1) ? a2 * (Real(1) - Real(1.5) * q * q + Real(0.75) * q * q * q) : Real(0.25) * a2 * t * t * t;
    }
    Real dwdr_of_q(Real q) const {
      const Real t = Real(2) - q;
      return q <= Real(1) ? (c1 * q + d1 * q * q) : c2 * t * t;
    }
  };
  template <class Real>
  Polynomials<Real> polynomials() const {
    return {static_cast<Real>(a2), static_cast<Real>(c1), static_cast<Real>(d1), static_cast<Real>(c2)};
  }

  /// W(r), eq. 1.
  double w(double r) const {
    const double q = r * inv_h;
    return q <= 2.0 ? w_of_q(q) : 0.0;
  }
  /// F(r) = (dW/dr)/r, so that grad_a W_ab = F * r_ab.
  double f(double r) const {
    const double q = r * inv_h;
    return q <= 2.0 ? dwdr_of_q(q) / r : 0.0;
  }
};

}  // namespace sphnl
