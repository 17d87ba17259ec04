// Overlapping Allan variance (IEEE Std 952-1997 Annex C; NIST SP 1065 eq. 11) in O(N) per
// averaging factor, without forming the phase (angle) array.
//
// Rate input y_0..y_{N-1} (one sample per tau0). With S_i = y_i + ... + y_{i+m-1},
//   sigma^2(m tau0) = 1 / (2 m^2 n) * sum_{i=0}^{n-1} (S_{i+m} - S_i)^2,   n = N - 2m + 1,
// which is SP 1065 eq. 11 on the phase x_k = tau0 * (y_0 + ... + y_{k-1}), x_0 = 0.
// D_i = S_{i+m} - S_i is updated in O(1): D_{i+1} = D_i + y_{i+2m} - 2 y_{i+m} + y_i.
// Precision: D and the mean both cancel out of D (m samples minus m samples), so the
// large-offset cancellation that forces mean removal on the cumulative-sum (phase) route does
// not arise; D and the sum of squares are accumulated in `Accum` (long double by default,
// 64-bit mantissa on x86), so the rounding of the running D grows like sqrt(N) * 2^-64.
//
// Phase (cumulative angle) input x_0..x_{Np-1}: the second difference is formed directly,
//   sigma^2(m tau0) * tau0^2 = 1 / (2 m^2 n) * sum_{i=0}^{n-1} (x_{i+2m} - 2 x_{i+m} + x_i)^2,
//   n = Np - 2m.
//
// Streaming use (chunks of a record too large for memory): the OadevSums state plus the
// seed / advance / finish functions take any split of the index range; oadev() is the
// whole-array driver. No allocation, no exceptions; functions return false on bad input.
#pragma once
#include <cmath>
#include <cstddef>
#include <cstdint>

namespace gyrodrift {

enum class AllanInput : std::uint8_t { rate, phase };

// Running sums for one averaging factor m (rate input: D_i; both: sum of squares, terms).
template <class Accum = long double>
struct OadevSums {
  Accum diff{0};
  Accum sum_sq{0};
  std::size_t terms{0};
};

// Largest averaging factor m that leaves at least 2 squared differences (the same cut as
// allantools.oadev, which drops results built from a single difference).
inline std::size_t oadev_max_m(std::size_t n_data, AllanInput kind) noexcept {
  // rate: n = N - 2m + 1 >= 2  <=>  m <= (N - 1) / 2;  phase: n = Np - 2m >= 2.
  if (kind == AllanInput::rate) return n_data >= 3 ? (n_data - 1) / 2 : 0;
  return n_data >= 4 ? (n_data - 2) / 2 : 0;
}

// Number of squared differences at averaging factor m (0 if m does not fit).
inline std::size_t oadev_terms(std::size_t n_data, AllanInput kind, std::size_t m) noexcept {
  if (m == 0 || m > n_data / 2) return 0;
  if (kind == AllanInput::rate) return n_data - 2 * m + 1;
  return n_data > 2 * m ? n_data - 2 * m : 0;
}

// Rate input, step 1: D_0 = sum_k (y[m+k] - y[k]), k = 0..m-1, fed in as many pieces as
// wanted (lo = &y[k0], hi = &y[m+k0]). Differencing pairwise first cancels the mean exactly
// (the difference of two doubles is exact in long double), so a large constant rate costs
// no precision.
template <class Scalar, class Accum>
inline void oadev_rate_seed(OadevSums<Accum>& s, const Scalar* lo, const Scalar* hi,
                            std::size_t n) noexcept {
  Accum part{0};
  for (std::size_t i = 0; i < n; ++i) {
    part += static_cast<Accum>(hi[i]) - static_cast<Accum>(lo[i]);
  }
  s.diff += part;
}

// Rate input, step 2: n terms i = i0..i0+n-1 given y0 = &y[i0], y1 = &y[i0+m], y2 = &y[i0+2m].
// Each term adds D_i^2, then moves D_i to D_{i+1}. Call it for i up to n_terms - 2 in total
// (the last increment reads y[N-1]), then oadev_rate_finish() adds the last D^2.
template <class Scalar, class Accum>
inline void oadev_rate_advance(OadevSums<Accum>& s, const Scalar* y0, const Scalar* y1,
                               const Scalar* y2, std::size_t n) noexcept {
  Accum d = s.diff;
  Accum sq_a{0};
  Accum sq_b{0};
  std::size_t i = 0;
  // Two samples per iteration: the D chain takes one add per two samples, and the two
  // square sums are independent, so the x87 adds pipeline instead of waiting on each other.
  for (; i + 2 <= n; i += 2) {
    const Accum inc0 = (static_cast<Accum>(y2[i]) - Accum(2) * static_cast<Accum>(y1[i])) +
                       static_cast<Accum>(y0[i]);
    const Accum inc1 = (static_cast<Accum>(y2[i + 1]) -
                        Accum(2) * static_cast<Accum>(y1[i + 1])) +
                       static_cast<Accum>(y0[i + 1]);
    const Accum d1 = d + inc0;
    sq_a += d * d;
    sq_b += d1 * d1;
    d = d + (inc0 + inc1);
  }
  for (; i < n; ++i) {
    sq_a += d * d;
    d += (static_cast<Accum>(y2[i]) - Accum(2) * static_cast<Accum>(y1[i])) +
         static_cast<Accum>(y0[i]);
  }
  s.diff = d;
  s.sum_sq += sq_a + sq_b;
  s.terms += n;
}

// Rate input, step 3: the last term D_{n-1}^2.
template <class Accum>
inline void oadev_rate_finish(OadevSums<Accum>& s) noexcept {
  s.sum_sq += s.diff * s.diff;
  s.terms += 1;
}

// Phase input: n terms given x0 = &x[i0], x1 = &x[i0+m], x2 = &x[i0+2m].
template <class Scalar, class Accum>
inline void oadev_phase_accumulate(OadevSums<Accum>& s, const Scalar* x0, const Scalar* x1,
                                   const Scalar* x2, std::size_t n) noexcept {
  Accum sq_a{0};
  Accum sq_b{0};
  std::size_t i = 0;
  for (; i + 2 <= n; i += 2) {
    const Accum v0 = (static_cast<Accum>(x2[i]) - Accum(2) * static_cast<Accum>(x1[i])) +
                     static_cast<Accum>(x0[i]);
    const Accum v1 = (static_cast<Accum>(x2[i + 1]) -
                      Accum(2) * static_cast<Accum>(x1[i + 1])) +
                     static_cast<Accum>(x0[i + 1]);
    sq_a += v0 * v0;
    sq_b += v1 * v1;
  }
  for (; i < n; ++i) {
    const Accum v = (static_cast<Accum>(x2[i]) - Accum(2) * static_cast<Accum>(x1[i])) +
                    static_cast<Accum>(x0[i]);
    sq_a += v * v;
  }
  s.sum_sq += sq_a + sq_b;
  s.terms += n;
}

// sigma^2 from the sums, in data units per sample squared: rate input gives (rate units)^2;
// phase input gives (phase units)^2 / tau0^2 once the caller divides by tau0^2.
// Returns false (and leaves `out` alone) when there are no terms or the sum is not finite.
template <class Accum, class Out>
inline bool oadev_sigma2(const OadevSums<Accum>& s, std::size_t m, Out& out) noexcept {
  if (s.terms == 0 || m == 0) return false;
  const Accum mm = static_cast<Accum>(m);
  const Accum value = s.sum_sq / (Accum(2) * mm * mm * static_cast<Accum>(s.terms));
  if (!std::isfinite(value)) return false;
  out = static_cast<Out>(value);
  return true;
}

// Whole-array overlapping Allan variance for the averaging factors m[0..n_m).
// Writes sigma2[j] (see oadev_sigma2 for units) and terms[j] (may be null). Returns false if
// any m does not fit (0 or beyond oadev_max_m) or the data hold NaN/Inf; outputs for the
// factors already done stay written, the rest are untouched.
template <class Scalar, class Out, class Accum = long double>
inline bool oadev(const Scalar* data, std::size_t n_data, AllanInput kind, const std::size_t* m,
                  std::size_t n_m, Out* sigma2, std::size_t* terms) noexcept {
  const std::size_t max_m = oadev_max_m(n_data, kind);
  for (std::size_t j = 0; j < n_m; ++j) {
    const std::size_t mj = m[j];
    if (mj == 0 || mj > max_m) return false;
    const std::size_t n = oadev_terms(n_data, kind, mj);
    OadevSums<Accum> s;
    if (kind == AllanInput::rate) {
      oadev_rate_seed(s, data, data + mj, mj);
      oadev_rate_advance(s, data, data + mj, data + 2 * mj, n - 1);
      oadev_rate_finish(s);
    } else {
      oadev_phase_accumulate(s, data, data + mj, data + 2 * mj, n);
    }
    if (!oadev_sigma2(s, mj, sigma2[j])) return false;
    if (terms != nullptr) terms[j] = s.terms;
  }
  return true;
}

// Averaging-factor grids. Each writes up to `capacity` strictly increasing factors
// 1 <= m <= max_m and returns how many it wrote.
enum class TauGrid : std::uint8_t { octave, decade, all };

// octave: 1, 2, 4, ...; all: 1, 2, 3, ...; decade: round(10^(k / per_decade)), k = 0, 1, ...,
// duplicates removed (per_decade = 0 is treated as 1).
inline std::size_t tau_grid(TauGrid grid, std::size_t max_m, std::size_t per_decade,
                            std::size_t* out, std::size_t capacity) noexcept {
  std::size_t count = 0;
  if (grid == TauGrid::octave) {
    for (std::size_t m = 1; m <= max_m && count < capacity; m *= 2) {
      out[count++] = m;
      if (m > max_m / 2) break;  // next doubling would exceed max_m (and avoids overflow)
    }
  } else if (grid == TauGrid::all) {
    for (std::size_t m = 1; m <= max_m && count < capacity; ++m) out[count++] = m;
  } else {
    const double step = 1.0 / static_cast<double>(per_decade == 0 ? 1 : per_decade);
    std::size_t last = 0;
    for (std::size_t k = 0; count < capacity; ++k) {
      const double value = std::round(std::pow(10.0, static_cast<double>(k) * step));
      if (!(value <= static_cast<double>(max_m))) break;
      const auto m = static_cast<std::size_t>(value);
      if (m > last) {
        out[count++] = m;
        last = m;
      }
    }
  }
  return count;
}

}  // namespace gyrodrift
