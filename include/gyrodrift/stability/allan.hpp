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

#include "fused_common.hpp"

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

// Fused multi-tau kernel for rate input (the fast path for whole records in memory).
//
// The per-tau kernel above streams y three times per averaging factor and is bound by its
// long double running difference. Here every factor of a group is served from one pass:
// the record is cut into blocks of B term indices; for block b the needed stretches of y
// (at offsets 0, m_j, 2 m_j; nearby offsets merged into one segment) are turned into local
// prefix sums Q of (y - level) in double (level: local mean at b), and for term b+i of
// factor m
//   D_{b+i} = D_b + (L_2m(i) - 2 L_m(i) + L_0(i)),   L_s(i) = Q_s[i] - Q_s[0],
// so each factor costs three loads and a few flops per term (no dependency chain).
// Precision: D_b is carried from block to block in long double (block increments are exact
// differences of doubles); Q spans at most one segment (a few B samples) of data minus a
// line (the local level plus the record's rate ramp, fused_common.hpp RampLine; a line
// cancels from the increments of D exactly), so its rounding is ~B eps sigma however long
// the record, however far it drifts or however steeply it ramps (1e4 sigma over 1e6
// samples: 8.5e-14 relative, 3.3e-10 with a level only, which the streaming use without
// set_ramp() still removes).
// Squares are summed per block in double, then into long double.
// No allocation: fixed-capacity plan (MaxTaus factors) plus a caller-owned double workspace
// of workspace_doubles() elements.
template <std::size_t MaxTaus = 64>
class OadevFused {
 public:
  static constexpr std::size_t kMaxOffsets = 2 * MaxTaus + 1;

  // m: strictly increasing factors, each 1 <= m <= oadev_max_m(n_data, rate); block >= 16.
  bool plan(std::size_t n_data, const std::size_t* m, std::size_t n_m,
            std::size_t block) noexcept {
    n_m_ = 0;
    if (n_m == 0 || n_m > MaxTaus || block < 16) return false;
    const std::size_t max_m = oadev_max_m(n_data, AllanInput::rate);
    for (std::size_t j = 0; j < n_m; ++j) {
      if (m[j] == 0 || m[j] > max_m || (j > 0 && m[j] <= m[j - 1])) return false;
      m_[j] = m[j];
      n_terms_[j] = oadev_terms(n_data, AllanInput::rate, m[j]);
    }
    n_data_ = n_data;
    block_ = block;
    // Sorted distinct offsets: merge {0}, {m_j}, {2 m_j} (both increasing).
    std::size_t offsets[kMaxOffsets];
    std::size_t n_off = 0;
    offsets[n_off++] = 0;
    std::size_t a = 0;
    std::size_t c = 0;
    while (a < n_m || c < n_m) {
      const std::size_t va = a < n_m ? m[a] : static_cast<std::size_t>(-1);
      const std::size_t vc = c < n_m ? 2 * m[c] : static_cast<std::size_t>(-1);
      const std::size_t v = va < vc ? va : vc;
      if (va == v) ++a;
      if (vc == v) ++c;
      if (v != offsets[n_off - 1]) offsets[n_off++] = v;
    }
    // Greedy segments: an offset within B of the previous one's stretch joins its segment.
    n_seg_ = fused_detail::plan_segments(offsets, n_off, block, seg_start_, seg_len_, seg_q_,
                                         workspace_);
    for (std::size_t j = 0; j < n_m; ++j) {
      const std::size_t offs[3] = {0, m[j], 2 * m[j]};
      for (std::size_t s = 0; s < 3; ++s) {
        stream_[j][s] = fused_detail::segment_position(seg_start_, seg_q_, n_seg_, offs[s]);
      }
    }
    n_m_ = n_m;
    return true;
  }

  std::size_t workspace_doubles() const noexcept { return workspace_; }

  // Runs the planned factors over y[0..n_data); writes sigma2[j] (rate units^2) and terms[j]
  // (may be null). False if not planned, the workspace is too small, or the data are not
  // finite (outputs untouched).
  template <class Scalar, class Out>
  bool run(const Scalar* y, double* workspace, std::size_t workspace_len, Out* sigma2,
           std::size_t* terms) noexcept {
    if (n_m_ == 0 || workspace_len < workspace_) return false;
    // No separate finiteness pass: every sample enters the smallest factor's differences,
    // so a NaN/Inf makes its sum non-finite and finish() refuses it.
    reset_sums();
    // the record's rate line, removed in the prefix sums (a strong ramp keeps them small)
    line_ = fused_detail::ramp_line(y, n_data_);
    for (std::size_t j = 0; j < n_m_; ++j) seed_add(j, y, y + m_[j], m_[j]);
    const Scalar* bases[kMaxOffsets];
    for (std::size_t k = 0; k < n_seg_; ++k) bases[k] = y + seg_start_[k];
    if (!process_blocks(bases, 0, n_terms_[0], workspace, workspace_len)) return false;
    return finish(sigma2, terms);
  }

  // Streaming use (records read piece by piece, e.g. from a file):
  //   reset_sums(); seed_add(j, &y[k], &y[m_j + k], n) for k covering [0, m_j) of every j;
  //   process_blocks(...) over consecutive term ranges; finish(...).
  // The result equals run() bit for bit when b_begin is a multiple of block().
  void reset_sums() noexcept {
    line_ = fused_detail::RampLine{};  // streaming: a level per block, no line
    for (std::size_t j = 0; j < MaxTaus; ++j) {
      diff_[j] = 0;
      sum_sq_[j] = 0;
    }
  }

  template <class Scalar>
  void seed_add(std::size_t j, const Scalar* lo, const Scalar* hi, std::size_t n) noexcept {
    if (j >= n_m_) return;
    OadevSums<long double> part;
    oadev_rate_seed(part, lo, hi, n);
    diff_[j] += part.diff;
  }

  // Streaming: after reset_sums(), the rate line run() removes (head = the record's first
  // fused_detail::kRampEnd samples, tail its last ones; n the record length), so the result
  // equals run() bit for bit; without it each block removes a level only (precise unless
  // the record ramps by thousands of sigma).
  template <class Scalar>
  void set_ramp(const Scalar* head, const Scalar* tail, std::size_t n) noexcept {
    line_ = fused_detail::ramp_line(head, tail, n);
  }

  // Term indices [b_begin, b_end) (both multiples of block() except b_end >= n_terms(0) for
  // the last range; ranges in order). seg_base[k] points at y[b_begin + segment_start(k)]; it must give access up
  // to y[min(n_data, b_end + segment_start(k) + segment_span(k)) - 1] (segments starting
  // beyond the data are not read).
  template <class Scalar>
  bool process_blocks(const Scalar* const* seg_base, std::size_t b_begin, std::size_t b_end,
                      double* workspace, std::size_t workspace_len) noexcept {
    if (n_m_ == 0 || workspace_len < workspace_ || b_begin % block_ != 0) return false;
    if (b_end % block_ != 0 && b_end < n_terms_[0]) return false;
    const std::size_t bsz = block_;
    const bool wide = fused_detail::wide_simd();
    std::size_t n_active = n_m_;
    const std::size_t stop = b_end < n_terms_[0] ? b_end : n_terms_[0];
    for (std::size_t b = b_begin; b < stop; b += bsz) {
      while (n_active > 0 && n_terms_[n_active - 1] <= b) --n_active;
      const std::size_t rel = b - b_begin;
      // One line level + slope k (k the sample index) removed from all streams of this
      // block (a constant and a line cancel in L_2m - 2 L_m + L_0 and in the carry): the
      // local level at b and the record's ramp (run(); none when streaming), so drifting
      // and ramping records keep Q small.
      const std::size_t n_level = n_data_ - b < 64 ? n_data_ - b : 64;
      long double level{0};
      for (std::size_t i = 0; i < n_level; ++i) {
        level += static_cast<long double>(seg_base[0][rel + i]) -
                 static_cast<long double>(line_.slope) * static_cast<long double>(b + i);
      }
      const double mean =
          line_.snap(static_cast<double>(level / static_cast<long double>(n_level)));
      // Local prefix sums of the segments the active factors read.
      const std::size_t reach = 2 * m_[n_active - 1];
      for (std::size_t k = 0; k < n_seg_ && seg_start_[k] <= reach; ++k) {
        const std::size_t start = b + seg_start_[k];
        const std::size_t avail = n_data_ > start ? n_data_ - start : 0;
        const std::size_t len = seg_len_[k] - 1 < avail ? seg_len_[k] - 1 : avail;
        workspace[seg_q_[k]] = 0.0;  // Q[0] = 0, Q[t+1] = Q[t] + (y[t] - line)
        const double a = mean + line_.slope * static_cast<double>(start);
#if GYRODRIFT_ALLAN_X86_DISPATCH
        if (wide) {
          fused_detail::prefix_sum_avx2(seg_base[k] + rel, 1, len, a, line_.slope,
                                        workspace + seg_q_[k]);
          continue;
        }
#endif
        fused_detail::prefix_sum(seg_base[k] + rel, 1, len, a, line_.slope,
                                 workspace + seg_q_[k]);
      }
      for (std::size_t j = 0; j < n_active; ++j) {
        const std::size_t left = n_terms_[j] - b;
        const std::size_t len = left < bsz ? left : bsz;
        const double* p0 = workspace + stream_[j][0];
        const double* p1 = workspace + stream_[j][1];
        const double* p2 = workspace + stream_[j][2];
        const double k0 = static_cast<double>(diff_[j]) - ((p2[0] - 2.0 * p1[0]) + p0[0]);
        sum_sq_[j] +=
            static_cast<long double>(block_sum_sq_dispatch(wide, p0, p1, p2, len, k0));
        if (left > bsz) {  // carry D to the next block, exactly (differences of doubles)
          diff_[j] += (static_cast<long double>(p2[bsz]) - static_cast<long double>(p2[0])) -
                      2.0L * (static_cast<long double>(p1[bsz]) -
                              static_cast<long double>(p1[0])) +
                      (static_cast<long double>(p0[bsz]) - static_cast<long double>(p0[0]));
        }
      }
    }
    return true;
  }

  template <class Out>
  bool finish(Out* sigma2, std::size_t* terms) const noexcept {
    for (std::size_t j = 0; j < n_m_; ++j) {
      const long double mm = static_cast<long double>(m_[j]);
      const long double v =
          sum_sq_[j] / (2.0L * mm * mm * static_cast<long double>(n_terms_[j]));
      if (!std::isfinite(v)) return false;
    }
    for (std::size_t j = 0; j < n_m_; ++j) {
      const long double mm = static_cast<long double>(m_[j]);
      sigma2[j] = static_cast<Out>(sum_sq_[j] /
                                   (2.0L * mm * mm * static_cast<long double>(n_terms_[j])));
      if (terms != nullptr) terms[j] = n_terms_[j];
    }
    return true;
  }

  std::size_t block() const noexcept { return block_; }
  std::size_t factors() const noexcept { return n_m_; }
  std::size_t n_terms(std::size_t j) const noexcept { return j < n_m_ ? n_terms_[j] : 0; }
  std::size_t segments() const noexcept { return n_seg_; }
  std::size_t segment_start(std::size_t k) const noexcept { return seg_start_[k]; }
  // Samples of y one block of segment k reads beyond its start: span + block.
  std::size_t segment_span(std::size_t k) const noexcept { return seg_len_[k] - 1; }

 private:
  // sum_i (k0 + (p2[i] - 2 p1[i]) + p0[i])^2 over len terms (fused_detail::sum_sq_second).
  // Half of the kernel's time; on x86 the same loop is also compiled for AVX2+FMA and
  // chosen at run time (block_sum_sq_dispatch), ~1.6x faster there. Only the rounding of
  // the fused multiply-adds differs between the two (both double, ~1e-16 relative).
#if GYRODRIFT_ALLAN_X86_DISPATCH
  __attribute__((target("avx2,fma"))) static double block_sum_sq_avx2(
      const double* p0, const double* p1, const double* p2, std::size_t len,
      double k0) noexcept {
    return fused_detail::sum_sq_second(p0, p1, p2, len, k0);
  }
  static double block_sum_sq_base(const double* p0, const double* p1, const double* p2,
                                  std::size_t len, double k0) noexcept {
    return fused_detail::sum_sq_second(p0, p1, p2, len, k0);
  }
#endif

  static double block_sum_sq_dispatch(bool wide, const double* p0, const double* p1,
                                      const double* p2, std::size_t len, double k0) noexcept {
#if GYRODRIFT_ALLAN_X86_DISPATCH
    return wide ? block_sum_sq_avx2(p0, p1, p2, len, k0)
                : block_sum_sq_base(p0, p1, p2, len, k0);
#else
    (void)wide;
    return fused_detail::sum_sq_second(p0, p1, p2, len, k0);
#endif
  }

  std::size_t n_data_{0};
  std::size_t block_{0};
  std::size_t n_m_{0};
  std::size_t n_seg_{0};
  std::size_t workspace_{0};
  std::size_t m_[MaxTaus]{};
  std::size_t n_terms_[MaxTaus]{};
  std::size_t stream_[MaxTaus][3]{};
  std::size_t seg_start_[kMaxOffsets]{};
  std::size_t seg_len_[kMaxOffsets]{};
  std::size_t seg_q_[kMaxOffsets]{};
  fused_detail::RampLine line_{};
  long double diff_[MaxTaus]{};
  long double sum_sq_[MaxTaus]{};
};

// Where to cut the strictly increasing factors m[0..n_m) (n_m <= MaxTaus, all valid for
// n_data) into two fused groups [0, cut) and [cut, n_m) of about equal cost, so that two
// workers can run one each; returns n_m when one group is cheapest. The cut depends only on
// (n_data, m, block). Cost per block: the group's local prefix sums (workspace_doubles(),
// ~0.45 ns each) plus its sums of squares (block terms per factor, ~0.2 ns each with AVX2),
// measured with cpp/bench/bench_allan.cpp (octave taus, 1e7..1e8 samples). `scratch` is
// re-planned.
template <std::size_t MaxTaus>
inline std::size_t oadev_fused_cut(std::size_t n_data, const std::size_t* m, std::size_t n_m,
                                   std::size_t block, OadevFused<MaxTaus>& scratch) noexcept {
  return fused_balanced_cut(n_m, [&](std::size_t lo, std::size_t hi) {
    if (!scratch.plan(n_data, m + lo, hi - lo, block)) return -1.0;
    return static_cast<double>(scratch.workspace_doubles()) +
           0.45 * static_cast<double>((hi - lo) * block);
  });
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
