// The drift model "AR(2) drift + white noise" (drift_likelihood.hpp, the offline fit
// gyrodrift.filters.fit_drift_model) fitted from the whole-record lag statistics a target keeps
// while streaming (lag_statistics.hpp): the exact log-likelihood from the statistics, its
// profile over the mean and the common scale of q and r, and its maximisation. The equations
// and the algorithm are those of the numpy reference gyrodrift.reference.lag_drift
// (lag_loglike, lag_drift_fit; docs/validation/online-identification.md, "Whole-record
// statistics"), which the tests hold this header to.
//
// Model: x_t = a1 x_{t-1} + a2 x_{t-2} + w_t (var q), y_t = mean + x_t + v_t (var r).
// Statistics (lag_statistics.hpp): n, c, sum w, P_0..P_L, the first and the last L values of
// w = y - c. With z = y - mean = w - d (d = mean - c) and the lag sums
//   S_k = P_k - d lin_k + (n - k) d^2,   lin_k = 2 sum w - sum_{t<k} w_t - sum_{t>=n-k} w_t,
// the log-likelihood is
//   log L = -(n log 2 pi + log det + Q) / 2,   Q = v M v^T, v = (1, -d),
// a quadratic form in the mean with the 2 x 2 matrix M built from:
//   - the Kalman filter (prediction form, stationary start) over the first L samples: its
//     innovation variances F_t, and the innovations of the first L values of w and of the
//     constant 1 (the innovations are linear in z): sum e e^T / F;
//   - from t = L on the steady-state filter (Riccati recursion continued until F changes by
//     at most 1e-15 relative on two steps running, sigma^2 its F): the innovations are
//     e_t = sum_{j<=L} pi_j z_{t-j} (pi its impulse response), whose squares over
//     t = L..n-1 sum to sum_k g_k S_k / sigma^2 (g_0 = sum pi_j^2,
//     g_k = 2 sum pi_j pi_{j+k}) minus the squares of the zero-padded convolution pi * z at t = 0..L-1 (first samples) and t = n..n+L-1
//     (last samples);
//   - log det = sum_{t<L} log F_t + (n - L) log sigma^2.
// Exact up to terms of order rho^L per sample, rho the pole modulus of the steady-state
// innovation filter (the fit reports rho^L of its estimate as `truncation`). The "whittle" kind keeps only the steady part:
// log det = n log sigma^2, M from sum_k g_k S_k / sigma^2 (Whittle's approximation truncated at L);
// it needs no recursion: sigma^2 and pi, the impulse response of A(z) / B(z), come from the
// spectral factorisation q + r |A|^2 = sigma^2 |B|^2 in closed form (detail::lag_innovation_factor).
// The "whittle_no_head" kind is Whittle's with the first L values of w replaced by the record's
// mean of w, sum w / n, in lin_k (sum_{t<k} w_t = k sum w / n): the only place Whittle's form
// reads them, so it needs no first values and is the one kind the statistics without them
// (LagStatisticsNoHead, lag_statistics.hpp) can give; the others answer needs_head there.
// It is the numpy reference's Whittle likelihood on statistics whose head is that mean
// (scripts/online_whittle_proto.py --no-head).
//
// Profile: scaling q and r by s scales every F and sigma^2 by s, and Q is quadratic in d, so
// for a1, a2 and the split lam = q / (q + r) the maximum over the mean and the scale is in
// closed form: d = M01 / M11, s = (M00 - M01 d) / n (M at q = lam, r = 1 - lam),
//   log L = -(n log 2 pi + log det + n log s + n) / 2.
//
// Fit (lag_drift_fit; the reference's algorithm, with its own maximiser):
//   - parameters u = (u1, u2, u3): a2 = tanh u2, a1 = tanh u1 (1 - a2) (every u is
//     stationary, as in fit_drift_model), lam = 1 / (1 + exp(-u3)); f(u) = -log L / n (the
//     profile; +inf where it is not finite);
//   - a grid of 48 starts: partial autocorrelations (-0.5, 0.3, 0.7, 0.95) x
//     (-0.3, -0.05, 0.05, 0.3), splits (0.2, 0.5, 0.8); the two best on each side of a2 = 0
//     (ties: the earlier in grid order) are each maximised;
//   - next to a2 = 0 the likelihood can have a maximum on each side, and the side a run ends
//     on is set by its start's split as much as by its a2: when every run ends on the side of
//     the best one, f is minimised over (u1, u3) with u2 held at the mirror of the best one's,
//     then over all three from there, and the better of the two ends is kept;
//   - maximiser: BFGS (Nocedal & Wright 2006, Numerical Optimization, alg. 6.1 with the
//     initial scaling of eq. 6.20), central-difference gradients (step 1e-5 max(1, |u_i|):
//     rounding and truncation errors about 1e-9 of f's per-sample scale each), a
//     backtracking line search with Armijo's condition (c1 = 1e-4, steps interpolated
//     quadratically within [0.1, 0.5] of the last one) and steps no longer than 1 in any u.
//     A run stops when the predicted gain of the next step, n g^T H g / 2 in log-likelihood
//     units (H the inverse-Hessian estimate), is at most 1e-8: converged; when the line
//     search finds no decrease (the precision of f is reached): converged if that gain is at
//     most 1e-5; after max_iterations iterations (default kLagDriftMaxIterations): not
//     converged.
// Status: too_few_samples below lag_drift_min_samples (2 L + 2) samples; non_finite for
// statistics that are not finite (or a fit that is not); not_converged when the best run did
// not converge; truncation when rho^L of the fit exceeds lag_drift_truncation_tol(kind)
// (kLagDriftTruncationTol, or kLagDriftWhittleNoHeadTruncationTol for whittle_no_head: L too
// short for this model, the neglected terms are not negligible); needs_head for a kind other
// than whittle_no_head on statistics without the first values. The estimate is set for ok,
// not_converged and truncation.
//
// Work: one likelihood evaluation is about 6000 flops at L = 32 (the impulse response and its
// autocorrelation, the Kalman filter over the first samples, the Riccati recursion to the
// steady state, the two end convolutions); Whittle's kinds skip the recursion (the steady
// state in closed form) and the first samples' filter: the impulse response's
// autocorrelation, (L + 1)(L + 2) / 2 products, is most of what is left. A fit takes 600 to
// 900 evaluations on realistic records (evaluations of the result): about 1.3 ms on a desktop
// core (exact), 0.13 to 0.21 ms (whittle_no_head at L = 12 and 8); in software double on a
// Cortex-M4F 3.5e8 instructions (exact, L = 32), 4.1e7 and 3.3e7 (whittle_no_head at L = 12
// and 8: 5.2e4 and 4.2e4 an evaluation; 6.7e7 and 5.9e7 when they iterated the recursion)
// (cpp/cortex_m/use_lag_drift_fit.cpp; docs/validation/online-identification.md).
// Memory: the statistics are read in place (a float pair as Scalar(sum) + Scalar(comp); with
// the first values kept, those and the last L values copied once); working state on the
// stack: the grid's four best starts as indices, the best run and the one running (BFGS works
// in place on it: 3 x 3 inverse Hessian and a few 3-vectors) and the impulse response (L + 1
// Scalars). The stack is the sum of the frames on the deepest call chain (the fit, its runs,
// BFGS, the objective, the likelihood's build, software double's routines), so what is not
// needed there is kept off it: the grid's values, the estimate's profile, BFGS's update and the
// result's fields live in functions called when the chain is shallow (GYRODRIFT_NOINLINE),
// the gradient's evaluations in BFGS's own frame. On the Cortex-M4 1880 B of stack below the
// caller at L = 32 (exact), 1136 B at L = 12 and 1104 B at L = 8 (whittle_no_head), software
// double's routines included (cpp/cortex_m/use_lag_drift_fit.cpp's fit_stack); no heap, no
// exceptions. The statistics must not change during a fit (a target that pushes on while it
// fits runs the fit on a copy).
// Scalar is the fit's precision: double. The likelihood must resolve differences of 0.1 on a
// value of order n (1e-7 relative at 10^6 samples), below float's resolution; a float
// instantiation compiles but cannot be relied on.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "ar2_model.hpp"
#include "drift_likelihood.hpp"
#include "lag_statistics.hpp"

// The fit's stack on the target is the sum of the frames on its deepest call chain: a function
// is kept out of line (GYRODRIFT_NOINLINE) where inlining it would keep its locals on the stack
// while its caller goes on deeper, and inlined (GYRODRIFT_ALWAYS_INLINE) where a frame of its own
// would only add to the chain.
#ifndef GYRODRIFT_NOINLINE
#if defined(__GNUC__)
#define GYRODRIFT_NOINLINE __attribute__((noinline))
#elif defined(_MSC_VER)
#define GYRODRIFT_NOINLINE __declspec(noinline)
#else
#define GYRODRIFT_NOINLINE
#endif
#endif
#ifndef GYRODRIFT_ALWAYS_INLINE
#if defined(__GNUC__)
#define GYRODRIFT_ALWAYS_INLINE __attribute__((always_inline))
#else
#define GYRODRIFT_ALWAYS_INLINE
#endif
#endif

namespace gyrodrift {

enum class LagLikelihoodKind : std::uint8_t {
  exact = 0,    // the exact Gaussian likelihood up to terms of order rho^L
  whittle = 1,  // Whittle's approximation truncated at L
  whittle_no_head = 2,  // Whittle's with the first L samples replaced by the record's mean
};

enum class LagDriftFitStatus : std::uint8_t {
  ok = 0,
  too_few_samples,  // fewer than lag_drift_min_samples(L) samples
  truncation,       // rho^L of the fit above kLagDriftTruncationTol: L too short for this model
  not_converged,    // the best run hit the iteration limit (kLagDriftMaxIterations by default)
  non_finite,       // NaN or Inf in the statistics or in the fit
  bad_model,        // (likelihood, profile) parameters outside the model: q < 0, r <= 0, non-stationary
  needs_head,       // the kind needs the first L values, which the statistics do not keep
};

inline const char* to_string(LagDriftFitStatus s) noexcept {
  switch (s) {
    case LagDriftFitStatus::ok: return "ok";
    case LagDriftFitStatus::too_few_samples: return "too few samples";
    case LagDriftFitStatus::truncation: return "truncation not negligible";
    case LagDriftFitStatus::not_converged: return "not converged";
    case LagDriftFitStatus::non_finite: return "non-finite";
    case LagDriftFitStatus::bad_model: return "bad model";
    case LagDriftFitStatus::needs_head: return "needs the first samples";
  }
  return "unknown";
}

// rho^L above which the neglected terms of the likelihood are not negligible (the reference's
// TRUNCATION_TOL: n rho^L < 2e-3 log-likelihood units at 10 h at 400 Hz).
inline constexpr double kLagDriftTruncationTol = 1e-10;
// rho^L above which the whittle_no_head kind's fit is refused as truncation. That kind is an
// approximation whatever L (log det without the first samples' excess, the first values
// replaced by the mean), so the exact kind's 1e-10 is not what it needs. Measured on the 40
// convergence records (both of the papers' pairs, r/q 1 and 3, seeds 1-5, 240000 and 960000
// samples; docs/validation/online-identification.md) at L = 4, 6, 8 and 12: every fit with
// rho^L <= 3e-3 (all 80 at L = 8 and 12, whose rho^L is at most 2.1e-3, and 21 at L = 6) is
// within 0.12 offline standard errors of the offline maximum-likelihood fit; the 6 fits that
// left one standard error (at L = 4, up to 2.4) all have rho^L >= 6.1e-3, and so does no fit
// this tolerance accepts.
inline constexpr double kLagDriftWhittleNoHeadTruncationTol = 3e-3;
// The truncation tolerance of a kind.
constexpr double lag_drift_truncation_tol(LagLikelihoodKind kind) noexcept {
  return kind == LagLikelihoodKind::whittle_no_head ? kLagDriftWhittleNoHeadTruncationTol : kLagDriftTruncationTol;
}
// Largest number of BFGS iterations of one run (a fit makes at most 6 runs).
inline constexpr std::uint32_t kLagDriftMaxIterations = 200;

// The fewest samples the likelihood is taken from (the reference's minimum): the first L and
// the last L samples apart, and two of the steady part between them.
constexpr std::uint64_t lag_drift_min_samples(std::size_t lags) noexcept { return 2U * lags + 2U; }

// The profile at (a1, a2, lam): the log-likelihood maximised over the mean and the scale s,
// the mean and q = lam s, r = (1 - lam) s there.
template <class Scalar>
struct LagDriftProfile {
  Scalar loglike = Scalar(0);
  Scalar mean = Scalar(0);
  Scalar q = Scalar(0);
  Scalar r = Scalar(0);
};

template <class Scalar>
struct LagDriftFitResult {
  LagDriftFitStatus status = LagDriftFitStatus::non_finite;
  DriftModelParams<Scalar> model{};  // a1, a2, q, r, mean (0 unless ok, truncation or not_converged)
  Scalar loglike = Scalar(0);        // of the kind fitted, at the estimate
  Scalar truncation = Scalar(0);     // rho^L of the estimate
  std::uint32_t iterations = 0;      // BFGS iterations, all runs
  std::uint32_t evaluations = 0;     // likelihood evaluations (grid, line searches, gradients)
  std::uint8_t runs = 0;             // BFGS runs: 4, or 6 with the run across the fold
};

namespace detail {

// The first and the last L values of w in Scalar, for statistics that keep the first ones
// (the exact kind's end convolutions read each L times an evaluation); nothing otherwise
// (Whittle's form without them reads the last values once an evaluation, in place).
template <class Scalar, std::size_t Lags, bool KeepHead>
struct LagEndValues {
  template <class Stats>
  explicit LagEndValues(const Stats& st) noexcept {
    for (std::size_t i = 0; i < Lags; ++i) {
      head[i] = static_cast<Scalar>(st.head(i));
      tail[i] = static_cast<Scalar>(st.tail(i));
    }
  }
  Scalar head[Lags] = {}, tail[Lags] = {};
};
template <class Scalar, std::size_t Lags>
struct LagEndValues<Scalar, Lags, false> {
  template <class Stats>
  explicit LagEndValues(const Stats&) noexcept {}
};

// The kind a fit takes by default: the exact one, or Whittle's without the first values when
// the statistics do not keep them.
constexpr LagLikelihoodKind lag_default_kind(bool keeps_head) noexcept {
  return keeps_head ? LagLikelihoodKind::exact : LagLikelihoodKind::whittle_no_head;
}

// Whether the kind can be computed from statistics that do (not) keep the first values.
constexpr bool lag_kind_available(LagLikelihoodKind kind, bool keeps_head) noexcept {
  return keeps_head || kind == LagLikelihoodKind::whittle_no_head;
}

// The steady-state innovation form of the model without iterating the Riccati recursion. Its
// spectrum S(w) = q / |A(e^iw)|^2 + r, A(z) = 1 - a1 z^-1 - a2 z^-2, factors as
//   q + r |A(e^iw)|^2 = sigma^2 |B(e^iw)|^2,   B(z) = 1 + b1 z^-1 + b2 z^-2, roots inside the
// unit circle: sigma^2 the steady-state innovation variance, A / B the steady-state innovation
// filter (the roots of B are the eigenvalues of the Kalman filter's A (I - K H)). With
// x = z + 1/z the left side is c2 x^2 + c1 x + e = e (1 - t1 x)(1 - t2 x), c1 = -r a1 (1 - a2),
// c2 = -r a2, e = q + r ((1 + a2)^2 + a1^2), so t1 + t2 = -c1 / e and t1 t2 = c2 / e; each t_i
// gives the root beta_i = 2 t_i / (1 + s_i) of B, s_i = sqrt(1 - 4 t_i^2) (the principal root,
// real part > 0), and sigma^2 = c2 / (beta_1 beta_2) = e (1 + s_1)(1 + s_2) / 4. Only symmetric
// functions of the pair are needed, and they are real whether the t_i are real or complex
// conjugates (both s_i >= 0, or s_2 the conjugate of s_1):
//   s_1 s_2 = sqrt(S(0) S(pi)) / e, with the spectrum's numerator at w = 0 and pi,
//             S(0) = q + r (1 - a1 - a2)^2 and S(pi) = q + r (1 + a1 - a2)^2 (free of the
//             cancellation in 1 - 4 t^2 next to the unit circle, where s_i is small);
//   s_1 + s_2 = sqrt(s_1^2 + s_2^2 + 2 s_1 s_2), s_1^2 + s_2^2 = 2 - 4 ((t1 + t2)^2 - 2 t1 t2);
// then b2 = c2 / sigma^2 and b1 = c1 / (sigma^2 + c2) (the factorisation's lag-2 and lag-1
// coefficients: sigma^2 b2 = c2, sigma^2 b1 (1 + b2) = c1). Defined for every stationary
// (a1, a2) and q, r >= 0 with q + r > 0 (r = 0: B = 1 and sigma^2 = q; q = 0: B = A and
// sigma^2 = r); false when e is not positive or the result is not finite. About 30 operations
// and two square roots, against some tens of Riccati steps to 1e-15; next to the unit circle
// it is the more accurate of the two (the recursion stops on a change of 1e-15 while it
// converges as rho^2t).
template <class Scalar>
bool lag_innovation_factor(Scalar a1, Scalar a2, Scalar q, Scalar r, Scalar& sigma2, Scalar& b1,
                           Scalar& b2) noexcept {
  const Scalar zero(0), one(1), two(2), four(4);
  const Scalar e = q + r * ((one + a2) * (one + a2) + a1 * a1);
  if (!(e > zero) || !std::isfinite(e)) return false;
  const Scalar c1 = -r * a1 * (one - a2), c2 = -r * a2;
  const Scalar sum_t = -c1 / e, prod_t = c2 / e;
  const Scalar s_lo = one - a1 - a2, s_hi = one + a1 - a2;
  const Scalar spec0 = q + r * s_lo * s_lo, spec_pi = q + r * s_hi * s_hi;
  const Scalar s_prod = std::sqrt(spec0 * spec_pi) / e;
  const Scalar s_sq = two - four * (sum_t * sum_t - two * prod_t) + two * s_prod;
  const Scalar s_sum = std::sqrt(s_sq > zero ? s_sq : zero);
  sigma2 = e * (one + s_sum + s_prod) / four;
  b2 = c2 / sigma2;
  b1 = c1 / (sigma2 + c2);
  return sigma2 > zero && std::isfinite(sigma2) && std::isfinite(b1) && std::isfinite(b2);
}

// The likelihood's ingredients for one model, from the statistics (see the header comment).
template <class Scalar, class StatScalar, std::size_t Lags, bool KeepHead = true>
class LagLikelihoodForm {
 public:
  using Stats = LagStatistics<StatScalar, Lags, KeepHead>;

  explicit LagLikelihoodForm(const Stats& st) noexcept : st_(st), ends_(st) {}

  static Scalar value(const typename Stats::Sum& s) noexcept {
    return static_cast<Scalar>(s.sum) + static_cast<Scalar>(s.comp);
  }

  // Every statistic finite?
  bool finite() const noexcept {
    bool ok = std::isfinite(st_.centre()) && std::isfinite(value(st_.total()));
    for (std::size_t k = 0; k <= Lags; ++k) ok = ok && std::isfinite(value(st_.product(k)));
    for (std::size_t i = 0; i < st_.kept(); ++i) ok = ok && std::isfinite(st_.tail(i)) && head_finite(i);
    return ok;
  }

  // log det and M (m00, m01, m11) at (a1, a2, q, r), and the steady-state innovation filter's
  // denominator (b1, b2); false when they are not finite. The model must be stationary with
  // q >= 0, r > 0. The exact kind runs the Kalman filter over the first L samples and the
  // Riccati recursion on to the steady state (until F changes by at most 1e-15 relative on
  // two steps running);
  // Whittle's kinds read only the steady state, in closed form (lag_innovation_factor).
  bool build(Scalar a1, Scalar a2, Scalar q, Scalar r, LagLikelihoodKind kind) noexcept {
    if (!lag_kind_available(kind, KeepHead)) return false;
    const bool exact = kind == LagLikelihoodKind::exact && KeepHead;
    const Scalar n = static_cast<Scalar>(st_.samples());
    const Scalar zero(0), one(1);
    // sum_{t<L} log F_t as the log of their product, kept as mantissa * 2^exponent (frexp
    // after each factor: exact, no overflow), so one log a evaluation instead of L.
    Scalar prod_f = one;
    int exp_f = 0;
    // Innovations of the first L values of w (h) and of the constant 1 (o), over the first
    // L samples with the time-varying gain; their contribution sum e e^T / F.
    Scalar ehh = zero, eho = zero, eoo = zero;
    Scalar s2 = zero;
    if (exact) {
      Scalar k0 = zero, k1 = zero;
      Scalar g0, g1;
      drift_stationary_covariance(a1, a2, q, g0, g1);
      Scalar p00 = g0, p01 = g1, p11 = g0;
      Scalar xh0 = zero, xh1 = zero, xo0 = zero, xo1 = zero;
      const Scalar riccati_tol = Scalar(1e-15);
      const std::size_t max_steps = 64U * Lags + 256U;
      Scalar f = zero, f_prev = std::numeric_limits<Scalar>::infinity();
      // Steady when F has not moved on two steps running: with a1 = 0 the even and the odd
      // samples are two chains and F moves every other step only.
      int calm = 0;
      for (std::size_t t = 0;; ++t) {
        f = p00 + r;
        if (!(f > zero) || !std::isfinite(f)) return false;
        k0 = p00 / f;
        k1 = p01 / f;
        calm = std::fabs(f - f_prev) <= riccati_tol * f ? calm + 1 : 0;
        if (t < Lags) {
          // The first samples' filter.
          int e2 = 0;
          prod_f = std::frexp(prod_f * f, &e2);
          exp_f += e2;
          const Scalar eh = head_value(t) - xh0;
          const Scalar eo = one - xo0;
          ehh += eh * eh / f;
          eho += eh * eo / f;
          eoo += eo * eo / f;
          const Scalar uh0 = xh0 + k0 * eh, uh1 = xh1 + k1 * eh;
          xh0 = a1 * uh0 + a2 * uh1;
          xh1 = uh0;
          const Scalar uo0 = xo0 + k0 * eo, uo1 = xo1 + k1 * eo;
          xo0 = a1 * uo0 + a2 * uo1;
          xo1 = uo0;
        } else if (calm >= 2 || t >= max_steps) {
          break;
        }
        f_prev = f;
        // Filtered covariance P - K H P, then predicted A P A^T + Q.
        const Scalar u00 = p00 - k0 * p00, u01 = p01 - k0 * p01, u11 = p11 - k1 * p01;
        p00 = a1 * a1 * u00 + Scalar(2) * a1 * a2 * u01 + a2 * a2 * u11 + q;
        p01 = a1 * u00 + a2 * u01;
        p11 = u00;
      }
      s2 = f;
      b1_ = -(a1 * (one - k0) - a2 * k1);  // A (I - K H)'s characteristic polynomial
      b2_ = -a2 * (one - k0);
      // Impulse response of the steady-state innovation filter.
      Scalar x0 = zero, x1 = zero;
      for (std::size_t t = 0; t <= Lags; ++t) {
        const Scalar e = (t == 0 ? one : zero) - x0;
        pi_[t] = e;
        const Scalar u0 = x0 + k0 * e, u1 = x1 + k1 * e;
        x0 = a1 * u0 + a2 * u1;
        x1 = u0;
      }
    } else {
      if (!lag_innovation_factor(a1, a2, q, r, s2, b1_, b2_)) return false;
      // Impulse response of A(z) / B(z): pi_t = alpha_t - b1 pi_{t-1} - b2 pi_{t-2}, alpha =
      // (1, -a1, -a2, 0, ...).
      Scalar p1 = zero, p2 = zero;
      for (std::size_t t = 0; t <= Lags; ++t) {
        const Scalar alpha = t == 0 ? one : (t == 1 ? -a1 : (t == 2 ? -a2 : zero));
        const Scalar v = alpha - b1_ * p1 - b2_ * p2;
        pi_[t] = v;
        p2 = p1;
        p1 = v;
      }
    }
    // sum_k g_k (P_k, lin_k, n - k) with the running sums of the first and the last values
    // (the first ones the record's mean of w for whittle_no_head).
    Scalar sp = zero, sl = zero, sn = zero;
    const Scalar total = value(st_.total());
    const Scalar total2 = Scalar(2) * total;
    const bool no_head = kind == LagLikelihoodKind::whittle_no_head;
    const Scalar mean_w = total / n;
    Scalar head_cum = zero, tail_cum = zero;
    for (std::size_t k = 0; k <= Lags; ++k) {
      Scalar g = zero;
      for (std::size_t j = 0; j + k <= Lags; ++j) g += pi_[j] * pi_[j + k];
      if (k > 0) {
        g *= Scalar(2);
        head_cum += no_head ? mean_w : head_value(k - 1);
        tail_cum += tail_value(Lags - k);
      }
      sp += value(st_.product(k)) * g;
      sl += (total2 - head_cum - tail_cum) * g;
      sn += (n - static_cast<Scalar>(k)) * g;
    }
    m00_ = sp / s2;
    m01_ = Scalar(0.5) * sl / s2;
    m11_ = sn / s2;
    if (!exact) {
      log_det_ = n * std::log(s2);
      return std::isfinite(log_det_) && std::isfinite(m00_) && std::isfinite(m01_) && std::isfinite(m11_);
    }
    // The zero-padded convolution pi * z at t = 0..L-1 (first samples) and t = n..n+L-1
    // (last samples, ct_s = sum_{j>s} pi_j tail_{L+s-j}), of w and of the constant 1 (whose
    // convolutions are the partial sums of pi).
    Scalar pi_total = zero;
    for (std::size_t j = 0; j <= Lags; ++j) pi_total += pi_[j];
    Scalar chh = zero, cho = zero, coo = zero, co = zero;
    for (std::size_t t = 0; t < Lags; ++t) {
      Scalar ch = zero;
      for (std::size_t j = 0; j <= t; ++j) ch += pi_[j] * head_value(t - j);
      co += pi_[t];
      chh += ch * ch;
      cho += ch * co;
      coo += co * co;
      Scalar ct = zero;
      for (std::size_t j = t + 1; j <= Lags; ++j) ct += pi_[j] * tail_value(Lags + t - j);
      const Scalar cto = pi_total - co;
      chh += ct * ct;
      cho += ct * cto;
      coo += cto * cto;
    }
    m00_ += ehh - chh / s2;
    m01_ += eho - cho / s2;
    m11_ += eoo - coo / s2;
    const Scalar sum_log_f = std::log(prod_f) + static_cast<Scalar>(exp_f) * ln2();
    log_det_ = sum_log_f + (n - static_cast<Scalar>(Lags)) * std::log(s2);
    return std::isfinite(log_det_) && std::isfinite(m00_) && std::isfinite(m01_) && std::isfinite(m11_);
  }

  // After build(): log L at d = mean - c.
  Scalar loglike(Scalar d) const noexcept {
    const Scalar n = static_cast<Scalar>(st_.samples());
    const Scalar q = m00_ - Scalar(2) * d * m01_ + d * d * m11_;
    return Scalar(-0.5) * (n * log_2pi() + log_det_ + q);
  }

  // After build() at (q, r) = (lam, 1 - lam): the profile; false when it is not finite.
  bool profile(Scalar lam, LagDriftProfile<Scalar>& out) const noexcept {
    const Scalar n = static_cast<Scalar>(st_.samples());
    if (!(m11_ > Scalar(0))) return false;
    const Scalar d = m01_ / m11_;
    const Scalar scale = (m00_ - m01_ * d) / n;
    if (!(scale > Scalar(0)) || !std::isfinite(scale)) return false;
    out.loglike = Scalar(-0.5) * (n * log_2pi() + log_det_ + n * std::log(scale) + n);
    out.mean = static_cast<Scalar>(st_.centre()) + d;
    out.q = lam * scale;
    out.r = (Scalar(1) - lam) * scale;
    return std::isfinite(out.loglike) && std::isfinite(out.mean);
  }

  // After build() at (q, r) = (lam, 1 - lam): the profile's log-likelihood alone, as profile();
  // false when profile() is. Out of line, so that the caller keeps one Scalar on its stack while
  // it builds the next model.
  GYRODRIFT_NOINLINE bool profile_loglike(Scalar lam, Scalar& loglike) const noexcept {
    LagDriftProfile<Scalar> p;
    if (!profile(lam, p)) return false;
    loglike = p.loglike;
    return true;
  }

  // After build(): the pole modulus rho of the steady-state innovation filter, the larger
  // root modulus of z^2 + b1 z + b2 (the eigenvalues of A (I - K H)).
  Scalar pole() const noexcept {
    const Scalar tr = -b1_;
    const Scalar bc = -b2_;  // lambda^2 - tr lambda - bc = 0
    const Scalar disc = Scalar(0.25) * tr * tr + bc;
    if (disc >= Scalar(0)) return Scalar(0.5) * std::fabs(tr) + std::sqrt(disc);
    return std::sqrt(-bc);
  }

  const Stats& stats() const noexcept { return st_; }

 private:
  static Scalar log_2pi() noexcept { return Scalar(1.8378770664093454835606594728112353L); }
  static Scalar ln2() noexcept { return Scalar(0.6931471805599453094172321214581765681L); }

  // The first values (0 without them: never read then, the kinds that read them refused) and
  // the last ones, in Scalar.
  Scalar head_value(std::size_t i) const noexcept {
    if constexpr (KeepHead) {
      return ends_.head[i];
    } else {
      static_cast<void>(i);
      return Scalar(0);
    }
  }
  Scalar tail_value(std::size_t i) const noexcept {
    if constexpr (KeepHead) {
      return ends_.tail[i];
    } else {
      return static_cast<Scalar>(st_.tail(i));
    }
  }
  bool head_finite(std::size_t i) const noexcept {
    if constexpr (KeepHead) {
      return std::isfinite(st_.head(i));
    } else {
      static_cast<void>(i);
      return true;
    }
  }

  const Stats& st_;
  LagEndValues<Scalar, Lags, KeepHead> ends_;
  Scalar pi_[Lags + 1] = {};
  Scalar log_det_ = Scalar(0), m00_ = Scalar(0), m01_ = Scalar(0), m11_ = Scalar(0);
  Scalar b1_ = Scalar(0), b2_ = Scalar(0);  // the steady-state innovation filter A(z) / B(z)'s B
};

template <class Scalar>
inline void lag_natural(const Scalar* u, Scalar& a1, Scalar& a2, Scalar& lam) noexcept {
  a2 = std::tanh(u[1]);
  a1 = std::tanh(u[0]) * (Scalar(1) - a2);
  lam = Scalar(1) / (Scalar(1) + std::exp(-u[2]));
}

// f(u) = -(profile log-likelihood) / n, +inf where it is not finite; counts evaluations.
template <class Scalar, class StatScalar, std::size_t Lags, bool KeepHead>
class LagFitObjective {
 public:
  LagFitObjective(const LagStatistics<StatScalar, Lags, KeepHead>& st, LagLikelihoodKind kind) noexcept
      : form_(st), kind_(kind) {}

  Scalar operator()(const Scalar* u) noexcept {
    Scalar a1, a2, lam;
    lag_natural(u, a1, a2, lam);
    if (!(lam > Scalar(0) && lam < Scalar(1)) || !ar2_is_stationary(a1, a2)) {
      return std::numeric_limits<Scalar>::infinity();
    }
    ++evaluations_;
    Scalar loglike = Scalar(0);
    if (!form_.build(a1, a2, lam, Scalar(1) - lam, kind_) || !form_.profile_loglike(lam, loglike)) {
      return std::numeric_limits<Scalar>::infinity();
    }
    return -loglike / static_cast<Scalar>(form_.stats().samples());
  }

  LagLikelihoodForm<Scalar, StatScalar, Lags, KeepHead>& form() noexcept { return form_; }
  std::uint32_t evaluations() const noexcept { return evaluations_; }
  Scalar samples() const noexcept { return static_cast<Scalar>(form_.stats().samples()); }

 private:
  LagLikelihoodForm<Scalar, StatScalar, Lags, KeepHead> form_;
  LagLikelihoodKind kind_;
  std::uint32_t evaluations_ = 0;
};

// The 48 starts of the fit, in the reference's order: partial autocorrelations
// (-0.5, 0.3, 0.7, 0.95) x (-0.3, -0.05, 0.05, 0.3), splits (0.2, 0.5, 0.8), the split the
// fastest; point i as u = (atanh p1, atanh p2, logit lam).
inline constexpr int kLagGridPoints = 48;
template <class Scalar>
inline void lag_grid_point(int i, Scalar* u) noexcept {
  static constexpr Scalar pacf1[4] = {Scalar(-0.5), Scalar(0.3), Scalar(0.7), Scalar(0.95)};
  static constexpr Scalar pacf2[4] = {Scalar(-0.3), Scalar(-0.05), Scalar(0.05), Scalar(0.3)};
  static constexpr Scalar split[3] = {Scalar(0.2), Scalar(0.5), Scalar(0.8)};
  const Scalar p1 = pacf1[i / 12], p2 = pacf2[(i / 3) % 4], lam = split[i % 3];
  // atanh p = log((1 + p) / (1 - p)) / 2 (one log routine for the whole fit)
  u[0] = Scalar(0.5) * std::log((Scalar(1) + p1) / (Scalar(1) - p1));
  u[1] = Scalar(0.5) * std::log((Scalar(1) + p2) / (Scalar(1) - p2));
  u[2] = std::log(lam / (Scalar(1) - lam));
}

template <class Scalar>
struct BfgsRun {
  Scalar u[3] = {Scalar(0), Scalar(0), Scalar(0)};
  Scalar f = std::numeric_limits<Scalar>::infinity();
  std::uint32_t iterations = 0;
  bool converged = false;
};

// BFGS's update of the inverse Hessian estimate h from the step s and the change of the gradient
// y (sy = s^T y, yy = y^T y, ss = s^T s); the first update scales h to eq. 6.20's first. Out of
// line: its temporaries are not on the stack while bfgs evaluates the objective.
template <std::size_t D, class Scalar>
GYRODRIFT_NOINLINE void bfgs_update(Scalar (&h)[D][D], const Scalar* s, const Scalar* y, Scalar sy, Scalar yy,
                                    Scalar ss, bool& scaled) noexcept {
  // Curvature condition; skip the update when it fails (Nocedal & Wright, sec. 6.1).
  if (!(sy > std::sqrt(std::numeric_limits<Scalar>::epsilon() * ss * yy) && sy > Scalar(0))) return;
  if (!scaled) {
    const Scalar gamma = sy / yy;  // eq. 6.20
    for (std::size_t i = 0; i < D; ++i)
      for (std::size_t j = 0; j < D; ++j) h[i][j] = i == j ? gamma : Scalar(0);
    scaled = true;
  }
  // H' = (I - rho s y^T) H (I - rho y s^T) + rho s s^T, rho = 1 / y^T s.
  const Scalar rho = Scalar(1) / sy;
  Scalar hy[D];
  Scalar yhy = Scalar(0);
  for (std::size_t i = 0; i < D; ++i) {
    Scalar v = Scalar(0);
    for (std::size_t j = 0; j < D; ++j) v += h[i][j] * y[j];
    hy[i] = v;
    yhy += y[i] * v;
  }
  for (std::size_t i = 0; i < D; ++i) {
    for (std::size_t j = 0; j < D; ++j) {
      h[i][j] += -rho * (hy[i] * s[j] + s[i] * hy[j]) + (rho * rho * yhy + rho) * s[i] * s[j];
    }
  }
}

// BFGS over the D coordinates of u listed in free_idx (the others held), from run.u and in
// place (run.u the current point; f, iterations and converged set); objective per sample, its
// n = samples (the stopping rule is in log-likelihood units).
template <std::size_t D, class Scalar, class Objective>
void bfgs(Objective& obj, BfgsRun<Scalar>& run, const std::size_t (&free_idx)[D],
          std::uint32_t max_iterations) noexcept {
  run.iterations = 0;
  run.converged = false;
  const Scalar n = obj.samples();
  const Scalar fd_step = Scalar(1e-5), armijo = Scalar(1e-4), gain_tol = Scalar(1e-8), stall_tol = Scalar(1e-5),
               max_step = Scalar(1);
  Scalar* const u = run.u;
  // The central-difference gradient at x (x restored).
  auto gradient = [&](Scalar* x, Scalar* g) noexcept GYRODRIFT_ALWAYS_INLINE {
    bool ok = true;
    for (std::size_t i = 0; i < D; ++i) {
      const std::size_t c = free_idx[i];
      const Scalar keep = x[c];
      const Scalar h = fd_step * (std::fabs(keep) > Scalar(1) ? std::fabs(keep) : Scalar(1));
      x[c] = keep + h;
      const Scalar fp = obj(x);
      x[c] = keep - h;
      const Scalar fm = obj(x);
      x[c] = keep;
      g[i] = (fp - fm) / (Scalar(2) * h);
      ok = ok && std::isfinite(g[i]);
    }
    return ok;
  };
  Scalar f = obj(u);
  run.f = f;
  Scalar g[D] = {}, h[D][D] = {};
  if (!std::isfinite(f) || !gradient(u, g)) return;
  for (std::size_t i = 0; i < D; ++i)
    for (std::size_t j = 0; j < D; ++j) h[i][j] = i == j ? Scalar(1) : Scalar(0);
  bool scaled = false;
  for (; run.iterations < max_iterations; ++run.iterations) {
    Scalar p[D];
    Scalar slope = Scalar(0), gain = Scalar(0);
    for (std::size_t i = 0; i < D; ++i) {
      Scalar v = Scalar(0);
      for (std::size_t j = 0; j < D; ++j) v += h[i][j] * g[j];
      p[i] = -v;
      slope += g[i] * p[i];
    }
    gain = Scalar(-0.5) * n * slope;  // n g^T H g / 2
    if (!(slope < Scalar(0))) {
      // Not a descent direction (H lost positive definiteness to rounding): restart.
      for (std::size_t i = 0; i < D; ++i) {
        for (std::size_t j = 0; j < D; ++j) h[i][j] = i == j ? Scalar(1) : Scalar(0);
        p[i] = -g[i];
      }
      scaled = false;
      slope = Scalar(0);
      for (std::size_t i = 0; i < D; ++i) slope += g[i] * p[i];
      gain = Scalar(-0.5) * n * slope;
      if (!(slope < Scalar(0))) {
        run.converged = true;  // zero gradient
        break;
      }
    }
    if (gain <= gain_tol) {
      run.converged = true;
      break;
    }
    Scalar longest = Scalar(0);
    for (std::size_t i = 0; i < D; ++i) longest = std::fabs(p[i]) > longest ? std::fabs(p[i]) : longest;
    if (longest > max_step) {
      const Scalar shrink = max_step / longest;
      for (std::size_t i = 0; i < D; ++i) p[i] *= shrink;
      slope *= shrink;
    }
    // Backtracking line search (Armijo), quadratic interpolation within [0.1, 0.5].
    Scalar alpha = Scalar(1), f_new = f;
    Scalar u_new[3] = {u[0], u[1], u[2]};
    bool accepted = false;
    for (int trial = 0; trial < 40; ++trial) {
      for (std::size_t i = 0; i < D; ++i) u_new[free_idx[i]] = u[free_idx[i]] + alpha * p[i];
      f_new = obj(u_new);
      if (std::isfinite(f_new) && f_new <= f + armijo * alpha * slope) {
        accepted = true;
        break;
      }
      Scalar next = Scalar(0.1) * alpha;
      if (std::isfinite(f_new)) {
        const Scalar denom = Scalar(2) * (f_new - f - slope * alpha);
        if (denom > Scalar(0)) {
          const Scalar aq = -slope * alpha * alpha / denom;
          next = aq < Scalar(0.1) * alpha ? Scalar(0.1) * alpha : (aq > Scalar(0.5) * alpha ? Scalar(0.5) * alpha : aq);
        }
      }
      alpha = next;
    }
    if (!accepted || !(f_new < f)) {
      run.converged = gain <= stall_tol;  // no decrease left within f's precision
      break;
    }
    // The step s (in p) and the change of the gradient y (in y), in place.
    Scalar y[D] = {};
    if (!gradient(u_new, y)) break;
    for (int i = 0; i < 3; ++i) u[i] = u_new[i];
    Scalar* const s = p;
    Scalar sy = Scalar(0), yy = Scalar(0), ss = Scalar(0);
    for (std::size_t i = 0; i < D; ++i) {
      s[i] = alpha * p[i];
      const Scalar g_new = y[i];
      y[i] = g_new - g[i];
      g[i] = g_new;
      sy += s[i] * y[i];
      yy += y[i] * y[i];
      ss += s[i] * s[i];
    }
    f = f_new;
    bfgs_update(h, s, y, sy, yy, ss, scaled);
  }
  run.f = f;
}

template <class Scalar>
inline int sign_of(Scalar v) noexcept {
  return v > Scalar(0) ? 1 : (v < Scalar(0) ? -1 : 0);
}

}  // namespace detail

// Log-likelihood of the model p from the statistics (kind exact or whittle). ok, or
// too_few_samples (n < lag_drift_min_samples), non_finite (statistics, parameters or the
// recursion), bad_model (q < 0, r <= 0 or non-stationary); `loglike` is only written on ok.
// r = 0 is refused: the steady-state filter of a noise-free drift is not defined by the
// statistics' recursion here.
template <class Scalar, class StatScalar, std::size_t Lags, bool KeepHead>
LagDriftFitStatus lag_drift_loglike(const LagStatistics<StatScalar, Lags, KeepHead>& st,
                                    const DriftModelParams<Scalar>& p, Scalar& loglike,
                                    LagLikelihoodKind kind = detail::lag_default_kind(KeepHead)) noexcept {
  if (!detail::lag_kind_available(kind, KeepHead)) return LagDriftFitStatus::needs_head;
  if (st.samples() < lag_drift_min_samples(Lags)) return LagDriftFitStatus::too_few_samples;
  const Ar2Status ps = drift_params_status(p);
  if (ps == Ar2Status::non_finite) return LagDriftFitStatus::non_finite;
  if (ps != Ar2Status::ok || !(p.r > Scalar(0))) return LagDriftFitStatus::bad_model;
  detail::LagLikelihoodForm<Scalar, StatScalar, Lags, KeepHead> form(st);
  if (!form.finite() || !form.build(p.a1, p.a2, p.q, p.r, kind)) return LagDriftFitStatus::non_finite;
  const Scalar v = form.loglike(p.mean - static_cast<Scalar>(st.centre()));
  if (!std::isfinite(v)) return LagDriftFitStatus::non_finite;
  loglike = v;
  return LagDriftFitStatus::ok;
}

// The profile log-likelihood at (a1, a2, lam = q / (q + r), 0 < lam < 1): maximised over the
// mean and the common scale of q and r (header comment). Statuses as lag_drift_loglike;
// `out` is only written on ok.
template <class Scalar, class StatScalar, std::size_t Lags, bool KeepHead>
LagDriftFitStatus lag_drift_profile(const LagStatistics<StatScalar, Lags, KeepHead>& st, Scalar a1, Scalar a2,
                                    Scalar lam, LagDriftProfile<Scalar>& out,
                                    LagLikelihoodKind kind = detail::lag_default_kind(KeepHead)) noexcept {
  if (!detail::lag_kind_available(kind, KeepHead)) return LagDriftFitStatus::needs_head;
  if (st.samples() < lag_drift_min_samples(Lags)) return LagDriftFitStatus::too_few_samples;
  if (!std::isfinite(a1) || !std::isfinite(a2) || !std::isfinite(lam)) return LagDriftFitStatus::non_finite;
  if (!(lam > Scalar(0) && lam < Scalar(1)) || !ar2_is_stationary(a1, a2)) return LagDriftFitStatus::bad_model;
  detail::LagLikelihoodForm<Scalar, StatScalar, Lags, KeepHead> form(st);
  LagDriftProfile<Scalar> p;
  if (!form.finite() || !form.build(a1, a2, lam, Scalar(1) - lam, kind) || !form.profile(lam, p)) {
    return LagDriftFitStatus::non_finite;
  }
  out = p;
  return LagDriftFitStatus::ok;
}

namespace detail {

// The four runs from the grid's best starts and, when they all end on one side of a2 = 0, the
// run across the fold (lag_drift_fit's header comment); the best one into `chosen`; the BFGS
// iterations of all runs and their number into `*iterations` and `*runs` unless null. Out of
// line, so that the grid's state never sits on the stack beside the caller's.
template <class Scalar, class Objective>
GYRODRIFT_NOINLINE void lag_fit_runs(Objective& obj, std::uint32_t max_iterations, BfgsRun<Scalar>& chosen,
                                     std::uint32_t* iterations, std::uint8_t* runs) noexcept {
  // The grid, in the reference's order; the two best starts on each side of a2 = 0 (the
  // earlier one wins a tie, as a stable sort), kept as grid indices (the point recomputed
  // when its run starts), so that little of the fit's state lives beside its runs.
  int best_i[2][2] = {{-1, -1}, {-1, -1}};  // [side: a2 < 0, a2 > 0][rank], -1: none
  {
    Scalar best_f[2][2] = {};
    for (int i = 0; i < kLagGridPoints; ++i) {
      Scalar u[3];
      lag_grid_point(i, u);
      const Scalar f = obj(u);
      const int side = u[1] > Scalar(0) ? 1 : 0;
      if (best_i[side][0] < 0 || f < best_f[side][0]) {
        best_i[side][1] = best_i[side][0];
        best_f[side][1] = best_f[side][0];
        best_i[side][0] = i;
        best_f[side][0] = f;
      } else if (best_i[side][1] < 0 || f < best_f[side][1]) {
        best_i[side][1] = i;
        best_f[side][1] = f;
      }
    }
  }
  // Each of the four runs; the best one (the first on a tie) and the sides they ended on.
  const std::size_t all3[3] = {0, 1, 2};
  std::uint32_t its = 0;
  BfgsRun<Scalar> run;
  int sides[4] = {};
  for (int m = 0; m < 4; ++m) {
    for (int i = 0; i < 3; ++i) run.u[i] = Scalar(0);
    if (best_i[m / 2][m % 2] >= 0) lag_grid_point(best_i[m / 2][m % 2], run.u);
    bfgs<3>(obj, run, all3, max_iterations);
    its += run.iterations;
    sides[m] = sign_of(run.u[1]);
    if (m == 0 || run.f < chosen.f) chosen = run;
  }
  std::uint8_t count = 4;
  bool one_side = true;
  for (const int side : sides) one_side = one_side && side == sign_of(chosen.u[1]);
  if (one_side) {
    // Across the fold: (u1, u3) with u2 at the mirror of the best one's, then all three.
    run.u[0] = chosen.u[0];
    run.u[1] = -chosen.u[1];
    run.u[2] = chosen.u[2];
    const std::size_t two[2] = {0, 2};
    bfgs<2>(obj, run, two, max_iterations);
    its += run.iterations;
    bfgs<3>(obj, run, all3, max_iterations);
    its += run.iterations;
    count = 6;
    if (run.f < chosen.f) chosen = run;
  }
  if (iterations != nullptr) *iterations = its;
  if (runs != nullptr) *runs = count;
}

// The estimate at the chosen run's end: the natural parameters, the profile there (mean, q, r,
// log-likelihood) and rho^L; the status (non_finite when the run's f or the profile is not
// finite, the parameters outside the model (with check_ar also a non-stationary AR part); else
// not_converged, truncation or ok). `model`, `*loglike` and `*truncation` (unless null) are only
// written when the status is not non_finite.
template <std::size_t Lags, class Scalar, class Objective>
GYRODRIFT_NOINLINE LagDriftFitStatus lag_fit_estimate(Objective& obj, LagLikelihoodKind kind, const BfgsRun<Scalar>& chosen,
                                   bool check_ar, DriftModelParams<Scalar>& model, Scalar* loglike,
                                   Scalar* truncation) noexcept {
  Scalar a1, a2, lam;
  lag_natural(chosen.u, a1, a2, lam);
  LagDriftProfile<Scalar> p;
  auto& form = obj.form();
  const bool ok = std::isfinite(chosen.f) && (!check_ar || ar2_is_stationary(a1, a2)) && lam > Scalar(0) &&
                  lam < Scalar(1) && form.build(a1, a2, lam, Scalar(1) - lam, kind) && form.profile(lam, p);
  if (!ok) return LagDriftFitStatus::non_finite;
  model = DriftModelParams<Scalar>{a1, a2, p.q, p.r, p.mean};
  if (loglike != nullptr) *loglike = p.loglike;
  // rho^L by squaring (no pow routine on the target)
  Scalar power = Scalar(1), base = form.pole();
  for (std::size_t e = Lags; e > 0; e >>= 1U) {
    if ((e & 1U) != 0U) power *= base;
    base *= base;
  }
  if (truncation != nullptr) *truncation = power;
  if (!chosen.converged) return LagDriftFitStatus::not_converged;
  if (!(power <= static_cast<Scalar>(lag_drift_truncation_tol(kind)))) return LagDriftFitStatus::truncation;
  return LagDriftFitStatus::ok;
}

// lag_drift_fit into `res` (its fields as lag_drift_fit's result): the identifier's fit writes
// them in place.
template <class Scalar, class StatScalar, std::size_t Lags, bool KeepHead>
void lag_drift_fit_into(const LagStatistics<StatScalar, Lags, KeepHead>& st, LagLikelihoodKind kind,
                        std::uint32_t max_iterations, LagDriftFitResult<Scalar>& res) noexcept {
  res = LagDriftFitResult<Scalar>{};
  if (!lag_kind_available(kind, KeepHead)) {
    res.status = LagDriftFitStatus::needs_head;
    return;
  }
  if (st.samples() < lag_drift_min_samples(Lags)) {
    res.status = LagDriftFitStatus::too_few_samples;
    return;
  }
  LagFitObjective<Scalar, StatScalar, Lags, KeepHead> obj(st, kind);
  if (!obj.form().finite()) {
    res.status = LagDriftFitStatus::non_finite;
    return;
  }
  BfgsRun<Scalar> chosen;
  lag_fit_runs(obj, max_iterations, chosen, &res.iterations, &res.runs);
  res.status = lag_fit_estimate<Lags>(obj, kind, chosen, true, res.model, &res.loglike, &res.truncation);
  res.evaluations = obj.evaluations() + 1U;
}

}  // namespace detail

// Maximises the profile log-likelihood from the statistics (header comment: the grid, the two
// best starts on each side of a2 = 0, BFGS, the run across the fold).
template <class Scalar, class StatScalar, std::size_t Lags, bool KeepHead>
LagDriftFitResult<Scalar> lag_drift_fit(const LagStatistics<StatScalar, Lags, KeepHead>& st,
                                        LagLikelihoodKind kind = detail::lag_default_kind(KeepHead),
                                        std::uint32_t max_iterations = kLagDriftMaxIterations) noexcept {
  LagDriftFitResult<Scalar> res;
  detail::lag_drift_fit_into(st, kind, max_iterations, res);
  return res;
}

}  // namespace gyrodrift
