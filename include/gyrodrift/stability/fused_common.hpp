// Pieces shared by the fused multi-tau kernels (OadevFused in allan.hpp, DeviationFused in
// deviation_fused.hpp): local prefix sums of level-removed samples, read forwards or
// backwards (the reflected ends of the total variance), and the run-time test for the
// AVX2+FMA builds of their hot loops. No allocation, no exceptions.
#pragma once
#include <cmath>
#include <cstddef>
#include <type_traits>

// Run-time choice of AVX2+FMA builds of the fused kernels' hot loops (GCC/Clang on x86;
// define GYRODRIFT_ALLAN_NO_DISPATCH to compile the portable loops only).
#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__)) && \
    !defined(GYRODRIFT_ALLAN_NO_DISPATCH)
#define GYRODRIFT_ALLAN_X86_DISPATCH 1
#else
#define GYRODRIFT_ALLAN_X86_DISPATCH 0
#endif
#if GYRODRIFT_ALLAN_X86_DISPATCH
#include <immintrin.h>
#endif

// Helpers always inlined, so that a caller built for AVX2 (target attribute) compiles them
// for AVX2 too.
#if defined(__GNUC__)
#define GYRODRIFT_FUSED_INLINE __attribute__((always_inline)) inline
#else
#define GYRODRIFT_FUSED_INLINE inline
#endif

namespace gyrodrift {
namespace fused_detail {

// q[t+1] = q[t] + (y[t * step] - (a + slope t)) for t < len, q[0] given by the caller (the
// running value carried in); a + slope t is the line removed (a level when slope = 0; with
// a and slope multiples of a RampLine unit every a + slope t is exact). Four independent
// chains over quarters, then the quarter offsets are added, so the adds pipeline instead of
// waiting on each other. step is +1 or -1 (a mirrored stretch read backwards).
template <class Scalar>
GYRODRIFT_FUSED_INLINE void prefix_sum(const Scalar* y, std::ptrdiff_t step, std::size_t len,
                                       double a, double slope, double* q) noexcept {
  const std::size_t h = len / 4;
  const auto at = [&](std::size_t t) {
    return static_cast<double>(y[static_cast<std::ptrdiff_t>(t) * step]);
  };
  // the line's value at each chain's position, advanced by slope per sample (exact on the
  // RampLine grid; no integer-to-double conversion per sample)
  double l0 = a;
  double l1 = a + slope * static_cast<double>(h);
  double l2 = a + slope * static_cast<double>(2 * h);
  double l3 = a + slope * static_cast<double>(3 * h);
  double s0 = q[0];
  double s1 = 0.0;
  double s2 = 0.0;
  double s3 = 0.0;
  for (std::size_t t = 0; t < h; ++t) {
    s0 += at(t) - l0;
    s1 += at(h + t) - l1;
    s2 += at(2 * h + t) - l2;
    s3 += at(3 * h + t) - l3;
    l0 += slope;
    l1 += slope;
    l2 += slope;
    l3 += slope;
    q[t + 1] = s0;
    q[h + t + 1] = s1;
    q[2 * h + t + 1] = s2;
    q[3 * h + t + 1] = s3;
  }
  double l4 = a + slope * static_cast<double>(4 * h);
  for (std::size_t t = 4 * h; t < len; ++t) {
    s3 += at(t) - l4;
    l4 += slope;
    q[t + 1] = s3;
  }
  for (std::size_t part = 1; part < 4; ++part) {
    const std::size_t lo = part * h + 1;
    const std::size_t hi = part == 3 ? len + 1 : (part + 1) * h + 1;
    const double base = q[part * h];
    for (std::size_t t = lo; t < hi; ++t) q[t] += base;
  }
}

#if GYRODRIFT_ALLAN_X86_DISPATCH
// The same prefix sums with AVX2 (for callers built with target("avx2,fma")): four samples
// at a time are scanned inside the register (two shifted adds) and the running value added;
// four quarters run interleaved so the carry's latency (add + broadcast) is hidden. About
// 1.5x faster than the scalar chains; the additions are grouped differently, so the
// rounding differs from prefix_sum() (both double, ~len eps |q|).
// Four samples y[t*step .. (t+3)*step] minus line (the four values removed; step +1 or -1).
template <class Scalar>
__attribute__((target("avx2,fma"), always_inline)) inline __m256d load4_avx2(
    const Scalar* y, std::ptrdiff_t step, std::size_t t, __m256d line) noexcept {
  __m256d x;
  const std::ptrdiff_t at =
      step == 1 ? static_cast<std::ptrdiff_t>(t) : -static_cast<std::ptrdiff_t>(t) - 3;
  if constexpr (std::is_same<Scalar, float>::value) {
    x = _mm256_cvtps_pd(_mm_loadu_ps(y + at));
  } else {
    static_assert(std::is_same<Scalar, double>::value, "float or double samples");
    x = _mm256_loadu_pd(y + at);
  }
  if (step != 1) x = _mm256_permute4x64_pd(x, 0x1B);  // read backwards
  return _mm256_sub_pd(x, line);
}

// Inclusive scan of four values plus the running value; the carry becomes the last one.
__attribute__((target("avx2,fma"), always_inline)) inline __m256d scan4_avx2(
    __m256d x, __m256d& carry) noexcept {
  const __m256d zero = _mm256_setzero_pd();
  x = _mm256_add_pd(x, _mm256_blend_pd(_mm256_permute4x64_pd(x, 0x90), zero, 1));
  x = _mm256_add_pd(x, _mm256_permute2f128_pd(x, x, 0x08));
  x = _mm256_add_pd(x, carry);
  carry = _mm256_permute4x64_pd(x, 0xFF);
  return x;
}

template <class Scalar>
__attribute__((target("avx2,fma"))) inline void prefix_sum_avx2(const Scalar* y,
                                                                std::ptrdiff_t step,
                                                                std::size_t len, double a,
                                                                double slope,
                                                                double* q) noexcept {
  const std::size_t h = (len / 16) * 4;  // quarter length, a multiple of 4
  const __m256d zero = _mm256_setzero_pd();
  __m256d c0 = _mm256_set1_pd(q[0]);
  __m256d c1 = zero;
  __m256d c2 = zero;
  __m256d c3 = zero;
  // the line's values at t .. t + 3 of each quarter, advanced by 4 slope per step (exact
  // when a and slope are multiples of a RampLine unit; a level when slope = 0)
  const __m256d ramp4 = _mm256_set_pd(3.0 * slope, 2.0 * slope, slope, 0.0);
  __m256d l0 = _mm256_add_pd(_mm256_set1_pd(a), ramp4);
  __m256d l1 = _mm256_add_pd(_mm256_set1_pd(a + slope * static_cast<double>(h)), ramp4);
  __m256d l2 = _mm256_add_pd(_mm256_set1_pd(a + slope * static_cast<double>(2 * h)), ramp4);
  __m256d l3 = _mm256_add_pd(_mm256_set1_pd(a + slope * static_cast<double>(3 * h)), ramp4);
  const __m256d step4 = _mm256_set1_pd(4.0 * slope);
  for (std::size_t t = 0; t < h; t += 4) {
    _mm256_storeu_pd(q + t + 1, scan4_avx2(load4_avx2(y, step, t, l0), c0));
    _mm256_storeu_pd(q + h + t + 1, scan4_avx2(load4_avx2(y, step, h + t, l1), c1));
    _mm256_storeu_pd(q + 2 * h + t + 1, scan4_avx2(load4_avx2(y, step, 2 * h + t, l2), c2));
    _mm256_storeu_pd(q + 3 * h + t + 1, scan4_avx2(load4_avx2(y, step, 3 * h + t, l3), c3));
    l0 = _mm256_add_pd(l0, step4);
    l1 = _mm256_add_pd(l1, step4);
    l2 = _mm256_add_pd(l2, step4);
    l3 = _mm256_add_pd(l3, step4);
  }
  for (std::size_t part = 1; part < 4 && h > 0; ++part) {
    const double base = q[part * h];
    for (std::size_t t = part * h + 1; t <= (part + 1) * h; ++t) q[t] += base;
  }
  double s = q[4 * h];
  for (std::size_t t = 4 * h; t < len; ++t) {
    s += static_cast<double>(y[static_cast<std::ptrdiff_t>(t) * step]) -
         (a + slope * static_cast<double>(t));
    q[t + 1] = s;
  }
}
#endif

// Segments start at multiples of kAlignDoubles in the workspace: with a 64-byte aligned
// workspace (the bindings and the benchmark allocate one), every stream whose offset from
// its segment's start is a multiple of 4 (all but m = 1, 2 on octave grids) is read with
// 32-byte loads that never straddle two cache lines. Measured on the sums of squares
// (L1-resident, AVX2): 0.15 ns per term aligned against 0.21-0.23 ns when the streams sit
// at odd offsets, where a line-split load costs two load slots.
constexpr std::size_t kAlignDoubles = 8;

// Greedy segments over sorted distinct offsets: an offset within `block` of the previous
// segment's stretch joins it. Writes start, length (span + block + 1: Q[0..]) and workspace
// position of each segment (a multiple of kAlignDoubles); returns the segment count, `total`
// the workspace doubles.
inline std::size_t plan_segments(const std::size_t* offsets, std::size_t n_off,
                                 std::size_t block, std::size_t* seg_start, std::size_t* seg_len,
                                 std::size_t* seg_q, std::size_t& total) noexcept {
  std::size_t n_seg = 0;
  for (std::size_t k = 0; k < n_off; ++k) {
    if (n_seg == 0 || offsets[k] > seg_start[n_seg - 1] + seg_len[n_seg - 1] - 1) {
      seg_start[n_seg] = offsets[k];
      seg_len[n_seg] = block + 1;  // Q[0..B]
      ++n_seg;
    } else {
      seg_len[n_seg - 1] = offsets[k] - seg_start[n_seg - 1] + block + 1;
    }
  }
  total = 0;
  for (std::size_t k = 0; k < n_seg; ++k) {
    seg_q[k] = total;
    total += (seg_len[k] + kAlignDoubles - 1) / kAlignDoubles * kAlignDoubles;
  }
  return n_seg;
}

// Workspace position of `offset` (inside one of the n_seg planned segments).
inline std::size_t segment_position(const std::size_t* seg_start, const std::size_t* seg_q,
                                    std::size_t n_seg, std::size_t offset) noexcept {
  std::size_t k = n_seg - 1;
  while (seg_start[k] > offset) --k;
  return seg_q[k] + (offset - seg_start[k]);
}

// Mean of the first min(n, 64) samples in long double: the level removed before summing in
// double (any constant works where it cancels; one near the data keeps the sums small).
template <class Scalar>
inline double leading_level(const Scalar* y, std::size_t n) noexcept {
  const std::size_t n_level = n < 64 ? n : 64;
  if (n_level == 0) return 0.0;
  long double level{0};
  for (std::size_t i = 0; i < n_level; ++i) level += static_cast<long double>(y[i]);
  return static_cast<double>(level / static_cast<long double>(n_level));
}

// The rate line removed inside the fused kernels' prefix sums, so that a strong ramp leaves
// them small: per block the kernels subtract level + slope k (k the sample index) instead
// of a level. slope is the record's mean ramp (the means of its first and last 64 samples);
// slope and every level are rounded to multiples of unit, a power of two chosen so that
// every value of the line up to 4x the record's end levels (and any sum of such values
// along a stretch read by the AVX2 prefix sums) is an exact double: the removed line is
// then exactly a line, and a line drops out exactly where the estimator's coefficients
// annihilate it (third differences: ohdev, hdev, mdev; increments of second differences:
// oadev, totdev inside the record). unit = 0: no line (slope 0, levels as computed).
struct RampLine {
  double slope{0.0};
  double unit{0.0};
  double snap(double v) const noexcept {
    return unit > 0.0 ? std::nearbyint(v / unit) * unit : v;
  }
};

// From the record's first and last kRampEnd samples (head = &y[0], tail = &y[n - kRampEnd];
// a streaming reader passes copies); none for n < 4 kRampEnd.
constexpr std::size_t kRampEnd = 64;
template <class Scalar>
inline RampLine ramp_line(const Scalar* head, const Scalar* tail, std::size_t n) noexcept {
  RampLine line;
  constexpr std::size_t kEnd = kRampEnd;
  if (n < 4 * kEnd) return line;
  long double first{0};
  long double last{0};
  for (std::size_t i = 0; i < kEnd; ++i) {
    first += static_cast<long double>(head[i]);
    last += static_cast<long double>(tail[i]);
  }
  first /= static_cast<long double>(kEnd);
  last /= static_cast<long double>(kEnd);
  const long double big = 4.0L * (std::fabs(first) > std::fabs(last) ? std::fabs(first)
                                                                       : std::fabs(last));
  if (!std::isfinite(big) || big == 0.0L) return line;
  int e = 0;
  std::frexp(static_cast<double>(big), &e);  // big < 2^e
  line.unit = std::ldexp(1.0, e - 52);        // values below 2^e: multiples of 2^(e-52) exact
  line.slope = line.snap(static_cast<double>((last - first) /
                                             static_cast<long double>(n - kEnd)));
  return line;
}

template <class Scalar>
inline RampLine ramp_line(const Scalar* y, std::size_t n) noexcept {
  return n < 4 * kRampEnd ? RampLine{} : ramp_line(y, y + (n - kRampEnd), n);
}

// sum_{i < len} term(i)^2 in sixteen independent lanes (the add or FMA latency is hidden at
// any vector width), combined pairwise. term is inlined into the caller's build (AVX2 too).
template <class Term>
GYRODRIFT_FUSED_INLINE double sum_sq16(std::size_t len, Term term) noexcept {
  constexpr std::size_t kLanes = 16;
  double acc[kLanes] = {};
  std::size_t i = 0;
  for (; i + kLanes <= len; i += kLanes) {
    for (std::size_t k = 0; k < kLanes; ++k) {
      const double v = term(i + k);
      acc[k] += v * v;
    }
  }
  for (; i < len; ++i) {
    const double v = term(i);
    acc[0] += v * v;
  }
  for (std::size_t w = kLanes / 2; w > 0; w /= 2) {
    for (std::size_t k = 0; k < w; ++k) acc[k] += acc[k + w];
  }
  return acc[0];
}

// sum_i (k0 + ((p2 - 2 p1) + p0)[i])^2 (the Allan second difference).
GYRODRIFT_FUSED_INLINE double sum_sq_second(const double* p0, const double* p1,
                                            const double* p2, std::size_t len,
                                            double k0) noexcept {
  return sum_sq16(len, [&](std::size_t i) { return k0 + ((p2[i] - 2.0 * p1[i]) + p0[i]); });
}

// sum_i (k0 + ((p3 - p0) + 3 (p1 - p2))[i])^2 (the Hadamard third difference).
GYRODRIFT_FUSED_INLINE double sum_sq_third(const double* p0, const double* p1, const double* p2,
                                           const double* p3, std::size_t len,
                                           double k0) noexcept {
  return sum_sq16(len, [&](std::size_t i) {
    return k0 + ((p3[i] - p0[i]) + 3.0 * (p1[i] - p2[i]));
  });
}

#if GYRODRIFT_ALLAN_X86_DISPATCH
// Keeps a loaded vector in its register: GCC otherwise folds a value that two operations
// use back into two memory operands (two loads of the same address), and the pair kernels
// below are bound by their loads (2 per cycle on Zen 4): the six streams of a pair were
// eight loads per four terms. Same result; measured ~15 % faster on L1-resident streams, ~5 %
// on a whole ohdev call (1e6 samples, octave taus).
__attribute__((target("avx2,fma"), always_inline)) inline void pin_register(__m256d& v) noexcept {
  asm("" : "+x"(v));
}

// One step of both pair kernels: four terms of tau m (streams z, x1, x2, x3) and of tau 2 m
// (z, x2, y2, y3), their squares added to the accumulators a and b.
__attribute__((target("avx2,fma"), always_inline)) inline void sum_sq_third_pair_step(
    __m256d z, __m256d x1, __m256d x2, __m256d x3, __m256d y2, __m256d y3, __m256d ka,
    __m256d kb, __m256d three, __m256d& a, __m256d& b) noexcept {
  const __m256d ha =
      _mm256_add_pd(ka, _mm256_fmadd_pd(three, _mm256_sub_pd(x1, x2), _mm256_sub_pd(x3, z)));
  const __m256d hb =
      _mm256_add_pd(kb, _mm256_fmadd_pd(three, _mm256_sub_pd(x2, y2), _mm256_sub_pd(y3, z)));
  a = _mm256_fmadd_pd(ha, ha, a);
  b = _mm256_fmadd_pd(hb, hb, b);
}

// The end of both pair kernels: the scalar terms i in [i, len) of the pair (streams p0, p1,
// p2a, p3a for tau m; p0, p2a, p2b, p3b for tau 2 m), then the four lanes of each pair of
// accumulators added pairwise.
__attribute__((target("avx2,fma"), always_inline)) inline void sum_sq_third_pair_finish(
    const double* p0, const double* p1, const double* p2a, const double* p3a,
    const double* p2b, const double* p3b, std::size_t i, std::size_t len, const double* k0,
    __m256d a0, __m256d a1, __m256d b0, __m256d b1, double* out) noexcept {
  double ta = 0.0;
  double tb = 0.0;
  for (; i < len; ++i) {
    const double ha = k0[0] + ((p3a[i] - p0[i]) + 3.0 * (p1[i] - p2a[i]));
    const double hb = k0[1] + ((p3b[i] - p0[i]) + 3.0 * (p2a[i] - p2b[i]));
    ta += ha * ha;
    tb += hb * hb;
  }
  alignas(32) double la[4];
  alignas(32) double lb[4];
  _mm256_store_pd(la, _mm256_add_pd(a0, a1));
  _mm256_store_pd(lb, _mm256_add_pd(b0, b1));
  out[0] = ((la[0] + la[1]) + (la[2] + la[3])) + ta;
  out[1] = ((lb[0] + lb[1]) + (lb[2] + lb[3])) + tb;
}

// Two taus m and 2 m of the overlapping Hadamard variance in one pass (AVX2): tau m reads
// the streams at offsets 0, m, 2 m, 3 m, tau 2 m those at 0, 2 m, 4 m, 6 m, so six loads
// serve both (eight apart). out[g] = sum_i (k0[g] + ((p3[g] - p0) + 3 (p1[g] - p2[g]))[i])^2
// with p1[1] = p2[0].
__attribute__((target("avx2,fma"))) inline void sum_sq_third_pair_avx2(
    const double* p0, const double* p1, const double* p2a, const double* p3a,
    const double* p2b, const double* p3b, std::size_t len, const double* k0,
    double* out) noexcept {
  __m256d a0 = _mm256_setzero_pd();
  __m256d a1 = a0;
  __m256d b0 = a0;
  __m256d b1 = a0;
  const __m256d ka = _mm256_set1_pd(k0[0]);
  const __m256d kb = _mm256_set1_pd(k0[1]);
  const __m256d three = _mm256_set1_pd(3.0);
  std::size_t i = 0;
  for (; i + 8 <= len; i += 8) {
    for (std::size_t u = 0; u < 8; u += 4) {
      __m256d z = _mm256_loadu_pd(p0 + i + u);
      const __m256d x1 = _mm256_loadu_pd(p1 + i + u);
      __m256d x2 = _mm256_loadu_pd(p2a + i + u);
      const __m256d x3 = _mm256_loadu_pd(p3a + i + u);
      const __m256d y2 = _mm256_loadu_pd(p2b + i + u);
      const __m256d y3 = _mm256_loadu_pd(p3b + i + u);
      pin_register(z);  // both taus read z and x2
      pin_register(x2);
      if (u == 0) {
        sum_sq_third_pair_step(z, x1, x2, x3, y2, y3, ka, kb, three, a0, b0);
      } else {
        sum_sq_third_pair_step(z, x1, x2, x3, y2, y3, ka, kb, three, a1, b1);
      }
    }
  }
  sum_sq_third_pair_finish(p0, p1, p2a, p3a, p2b, p3b, i, len, k0, a0, a1, b0, b1, out);
}

// The pair of taus m = 1, 2 (streams q + 0, 1, 2, 3 and q + 0, 2, 4, 6 of one run of Q),
// q 32-byte aligned: one aligned load per four terms, the streams at odd offsets and at 2, 6
// formed in registers (two lane-crossing permutes and two in-lane shuffles) instead of four
// loads that straddle 32-byte boundaries. The same operations, lanes and accumulators as
// sum_sq_third_pair_avx2, so the same result to the bit. Reads q[0 .. len + 7] (the pair's
// streams need q[0 .. len + 5]; a Q run for offsets 0..6 holds block + 7 values, padded to
// a multiple of kAlignDoubles, so the two extra values are inside the workspace and unused).
__attribute__((target("avx2,fma"))) inline void sum_sq_third_pair12_avx2(
    const double* q, std::size_t len, const double* k0, double* out) noexcept {
  __m256d a0 = _mm256_setzero_pd();
  __m256d a1 = a0;
  __m256d b0 = a0;
  __m256d b1 = a0;
  const __m256d ka = _mm256_set1_pd(k0[0]);
  const __m256d kb = _mm256_set1_pd(k0[1]);
  const __m256d three = _mm256_set1_pd(3.0);
  std::size_t i = 0;
  if (len >= 8) {
    __m256d va = _mm256_load_pd(q);      // q[i .. i + 3]
    __m256d vb = _mm256_load_pd(q + 4);  // q[i + 4 .. i + 7]
    for (; i + 8 <= len; i += 8) {
      for (std::size_t u = 0; u < 8; u += 4) {
        const __m256d vc = _mm256_load_pd(q + i + u + 8);
        const __m256d x2 = _mm256_permute2f128_pd(va, vb, 0x21);  // q[i + 2 .. i + 5]
        const __m256d x1 = _mm256_shuffle_pd(va, x2, 0x5);        // q[i + 1 .. i + 4]
        const __m256d x3 = _mm256_shuffle_pd(x2, vb, 0x5);        // q[i + 3 .. i + 6]
        const __m256d y2 = vb;                                    // q[i + 4 .. i + 7]
        const __m256d y3 = _mm256_permute2f128_pd(vb, vc, 0x21);  // q[i + 6 .. i + 9]
        if (u == 0) {
          sum_sq_third_pair_step(va, x1, x2, x3, y2, y3, ka, kb, three, a0, b0);
        } else {
          sum_sq_third_pair_step(va, x1, x2, x3, y2, y3, ka, kb, three, a1, b1);
        }
        va = vb;
        vb = vc;
      }
    }
  }
  sum_sq_third_pair_finish(q, q + 1, q + 2, q + 3, q + 4, q + 6, i, len, k0, a0, a1, b0, b1,
                           out);
}

// sum_i (k0 + ((p2 - 2 p1) + p0)[i] - slope (l_i^2 + r_i^2))^2, l_i = max(lo - i, 0),
// r_i = max(hi + i, 0) (AVX2): the total variance's terms that read a mirrored end of the
// reflected record, where the removed rate line leaves a quadratic (DeviationFused).
// Side: 1 only l (r_i = 0 for every i < len), 2 only r, 3 both.
template <int Side>
__attribute__((target("avx2,fma"))) inline double sum_sq_second_edge_side_avx2(
    const double* p0, const double* p1, const double* p2, std::size_t len, double k0,
    double lo, double hi, double slope) noexcept {
  const __m256d zero = _mm256_setzero_pd();
  const __m256d vk = _mm256_set1_pd(k0);
  const __m256d vs = _mm256_set1_pd(slope);
  const __m256d two = _mm256_set1_pd(2.0);
  const __m256d four = _mm256_set1_pd(4.0);
  const __m256d iota = _mm256_set_pd(3.0, 2.0, 1.0, 0.0);
  __m256d l = _mm256_sub_pd(_mm256_set1_pd(lo), iota);  // lo - i, i = 0..3
  __m256d r = _mm256_add_pd(_mm256_set1_pd(hi), iota);  // hi + i
  __m256d a0 = zero;
  __m256d a1 = zero;
  std::size_t i = 0;
  for (; i + 8 <= len; i += 8) {
    for (std::size_t h = 0; h < 8; h += 4) {
      const __m256d x = _mm256_add_pd(
          vk, _mm256_add_pd(_mm256_fnmadd_pd(two, _mm256_loadu_pd(p1 + i + h),
                                             _mm256_loadu_pd(p2 + i + h)),
                            _mm256_loadu_pd(p0 + i + h)));
      __m256d d = x;
      if (Side & 1) {
        const __m256d lp = _mm256_max_pd(l, zero);
        d = _mm256_fnmadd_pd(_mm256_mul_pd(vs, lp), lp, d);
        l = _mm256_sub_pd(l, four);
      }
      if (Side & 2) {
        const __m256d rp = _mm256_max_pd(r, zero);
        d = _mm256_fnmadd_pd(_mm256_mul_pd(vs, rp), rp, d);
        r = _mm256_add_pd(r, four);
      }
      if (h == 0) {
        a0 = _mm256_fmadd_pd(d, d, a0);
      } else {
        a1 = _mm256_fmadd_pd(d, d, a1);
      }
    }
  }
  double tail = 0.0;
  for (; i < len; ++i) {
    const double ui = static_cast<double>(i);
    const double lp = lo - ui > 0.0 ? lo - ui : 0.0;
    const double rp = hi + ui > 0.0 ? hi + ui : 0.0;
    const double d = (k0 + ((p2[i] - 2.0 * p1[i]) + p0[i])) - slope * (lp * lp + rp * rp);
    tail += d * d;
  }
  alignas(32) double la[4];
  _mm256_store_pd(la, _mm256_add_pd(a0, a1));
  return ((la[0] + la[1]) + (la[2] + la[3])) + tail;
}

__attribute__((target("avx2,fma"))) inline double sum_sq_second_edge_avx2(
    const double* p0, const double* p1, const double* p2, std::size_t len, double k0,
    double lo, double hi, double slope) noexcept {
  const double last = static_cast<double>(len) - 1.0;
  if (hi + last <= 0.0) {
    return sum_sq_second_edge_side_avx2<1>(p0, p1, p2, len, k0, lo, hi, slope);
  }
  if (lo <= 0.0) return sum_sq_second_edge_side_avx2<2>(p0, p1, p2, len, k0, lo, hi, slope);
  return sum_sq_second_edge_side_avx2<3>(p0, p1, p2, len, k0, lo, hi, slope);
}
#endif

// True when the AVX2+FMA builds can run on this CPU.
inline bool wide_simd() noexcept {
#if GYRODRIFT_ALLAN_X86_DISPATCH
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
  return false;
#endif
}

}  // namespace fused_detail

// Where to cut n_m factors into two groups [0, cut) and [cut, n_m) of about equal cost (so
// that two workers can run one each); n_m when one group is cheapest. cost(lo, hi) is the
// estimated cost of the group [lo, hi), negative when it cannot be planned. The cut must
// depend only on the plan (never on the thread count), so results are the same for any
// number of workers.
template <class Cost>
inline std::size_t fused_balanced_cut(std::size_t n_m, Cost cost) noexcept {
  std::size_t best_cut = n_m;
  double best = cost(std::size_t{0}, n_m);
  for (std::size_t cut = 1; cut < n_m; ++cut) {
    const double a = cost(std::size_t{0}, cut);
    const double b = cost(cut, n_m);
    const double c = a > b ? a : b;
    if (a >= 0.0 && b >= 0.0 && c < best) {
      best = c;
      best_cut = cut;
    }
  }
  return best_cut;
}

}  // namespace gyrodrift
