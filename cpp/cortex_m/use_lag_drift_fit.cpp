// Cortex-M4F gate unit: the drift-model fit from whole-record lag statistics as a navigation
// computer would run it: float statistics (32 lags) of a simulated gyro record pushed sample
// by sample, then one fit in double (software double on the M4F: the likelihood must resolve
// 1e-7 of its value, below float's resolution; lag_drift_fit.hpp). This unit is the one the
// gate allows to link software double (tests/test_cortex_m_gate.py).
//
// The gate builds it at 32 lags with the first samples and the exact likelihood; the cost
// script (scripts/lag_drift_fit_cost.py) also builds it with -DGYRODRIFT_LAG_FIT_LAGS=L and
// -DGYRODRIFT_LAG_FIT_NO_HEAD=1: the statistics without the first samples at L lags and
// Whittle's likelihood without them (lag_drift_fit.hpp, whittle_no_head).
//
// Record: 60000 samples (150 s at 400 Hz) of the papers' pair (0.6868, -0.0213) with q = r
// (the pair next to the fold a2 = 0), Gaussian-like noise from an LCG (the sum of 12
// uniforms), in float, on the volatile input's first sample as its mean.
// Cost: SysTick counts the reference clock around the fit, and a loop of known length (2 instructions a turn, kCalibrationTurns turns, as the
// firmware's step timer calibration) turns counts into instructions under QEMU with
// -icount shift=0 (scripts/lag_drift_fit_cost.py). With semihosting the unit prints one line
//   lag-drift-fit status=S evaluations=E iterations=I runs=R systick=C calibration=K turns=T
//   a1_e6=A a2_e6=B lags=L no_head=H state_bytes=Z fit_stack=F
// (Z the statistics' sizeof, F the bytes of stack the fit used below its caller's frame: the
// free stack is painted again just before the fit, as the start-up paints it, and the lowest
// overwritten word found after it)
// and returns 0 when the fit is ok and near the simulated model.
#include <gyrodrift/filters/lag_drift_fit.hpp>
#include <gyrodrift/filters/lag_statistics.hpp>
#include <cstddef>
#include <cstdint>

#include "cortex_m_start.hpp"
#include "support.hpp"

#ifndef GYRODRIFT_LAG_FIT_LAGS
#define GYRODRIFT_LAG_FIT_LAGS 32
#endif
#ifndef GYRODRIFT_LAG_FIT_NO_HEAD
#define GYRODRIFT_LAG_FIT_NO_HEAD 0
#endif

namespace {

using gyrodrift::cortex_m::Noise;
constexpr bool kNoHead = GYRODRIFT_LAG_FIT_NO_HEAD != 0;
using Stats = gyrodrift::LagStatistics<float, GYRODRIFT_LAG_FIT_LAGS, !kNoHead>;
constexpr gyrodrift::LagLikelihoodKind kKind =
    kNoHead ? gyrodrift::LagLikelihoodKind::whittle_no_head : gyrodrift::LagLikelihoodKind::exact;
constexpr std::size_t kSamples = 60000;
constexpr std::uint32_t kCalibrationTurns = 1000000;

// Static storage, no heap.
Stats& statistics() noexcept {
  static Stats stats;
  return stats;
}

// SysTick (ARMv7-M ARM B3.3) on the reference clock (the core clock / 8 on the STM32F4), 24
// bits without its interrupt: 2^24 counts are about 8e8 instructions, longer than a fit;
// COUNTFLAG tells when the counter wrapped (the count is then not valid).
constexpr std::uintptr_t kSystCsr = 0xE000E010U;
constexpr std::uintptr_t kSystRvr = 0xE000E014U;
constexpr std::uintptr_t kSystCvr = 0xE000E018U;
constexpr std::uint32_t kCountFlag = 1U << 16U;
volatile std::uint32_t& reg(std::uintptr_t a) noexcept { return *reinterpret_cast<volatile std::uint32_t*>(a); }

void systick_start() noexcept {
  reg(kSystRvr) = 0xFFFFFFU;
  reg(kSystCvr) = 0U;
  reg(kSystCsr) = 0x1U;  // CLKSOURCE = reference clock, no interrupt, ENABLE
  // Past the first reload from the cleared counter, then COUNTFLAG cleared by the read.
  std::uint32_t turns = 4096;
  __asm volatile("1: subs %0, %0, #1\n\tbne 1b" : "+r"(turns) : : "cc");
  const std::uint32_t clear = reg(kSystCsr);
  static_cast<void>(clear);
}

// Counts between two readings of the down-counter (modulo 2^24).
std::uint32_t elapsed(std::uint32_t from, std::uint32_t to) noexcept { return (from - to) & 0xFFFFFFU; }

#if defined(GYRODRIFT_CM_SEMIHOSTING)
char* put_text(char* out, const char* text) noexcept {
  while (*text != '\0') *out++ = *text++;
  return out;
}
char* put_int(char* out, std::int64_t value) noexcept {
  if (value < 0) {
    *out++ = '-';
    value = -value;
  }
  char digits[24];
  int n = 0;
  do {
    digits[n++] = static_cast<char>('0' + value % 10);
    value /= 10;
  } while (value > 0);
  while (n > 0) *out++ = digits[--n];
  return out;
}
void report(const char* line) noexcept {
  register int r0 __asm("r0") = 0x04;  // SYS_WRITE0
  register const char* r1 __asm("r1") = line;
  __asm volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
}
#endif
}  // namespace

extern "C" int app_main(void) {
  using gyrodrift::cortex_m::input;
  using gyrodrift::cortex_m::sink;
  // The record: AR(2) drift (0.6868, -0.0213) driven by q = 1, white noise r = 1, after 2000
  // samples of burn-in, pushed sample by sample.
  Noise w{12345U}, v{67890U};
  const float mean = input(0);
  float x1 = 0.0F, x2 = 0.0F;
  for (std::size_t k = 0; k < kSamples + 2000; ++k) {
    const float x = 0.6868F * x1 - 0.0213F * x2 + w.normal();
    x2 = x1;
    x1 = x;
    if (k >= 2000) statistics().push(mean + x + v.normal());
  }
  if (statistics().samples() != kSamples) return 1;
  systick_start();
  std::uint32_t turns = kCalibrationTurns;
  const std::uint32_t c0 = reg(kSystCvr);
  __asm volatile("1: subs %0, %0, #1\n\tbne 1b" : "+r"(turns) : : "cc");
  const std::uint32_t c1 = reg(kSystCvr);
  const bool calibration_wrapped = (reg(kSystCsr) & kCountFlag) != 0U;
  // The free stack below this frame painted again (cortex_m_start.hpp's word).
  std::uint32_t* sp = nullptr;
  __asm volatile("mov %0, sp" : "=r"(sp));
  for (volatile std::uint32_t* w = &_ebss; w < sp;) *w++ = gyrodrift::cortex_m_start::kStackPaint;
  const std::uint32_t t0 = reg(kSystCvr);
  const gyrodrift::LagDriftFitResult<double> fit = gyrodrift::lag_drift_fit<double>(statistics(), kKind);
  const std::uint32_t t1 = reg(kSystCvr);
  const volatile std::uint32_t* low = &_ebss;
  while (low < sp && *low == gyrodrift::cortex_m_start::kStackPaint) ++low;
  const auto fit_stack = static_cast<std::int64_t>(reinterpret_cast<std::uintptr_t>(sp) -
                                                   reinterpret_cast<std::uintptr_t>(low));
  const bool wrapped = calibration_wrapped || (reg(kSystCsr) & kCountFlag) != 0U;
  reg(kSystCsr) = 0U;
  // A count that wrapped is reported as -1.
  const std::int64_t counts = wrapped ? -1 : static_cast<std::int64_t>(elapsed(t0, t1));
  const std::int64_t calibration = wrapped ? -1 : static_cast<std::int64_t>(elapsed(c0, c1));
  sink(static_cast<float>(fit.model.a1));
  sink(static_cast<float>(fit.model.a2));
  sink(static_cast<float>(fit.model.q));
  sink(static_cast<float>(fit.model.r));
  sink(static_cast<float>(fit.model.mean));
  sink(static_cast<std::int32_t>(fit.evaluations));
  sink(static_cast<std::int32_t>(counts));
  sink(static_cast<std::int32_t>(fit_stack));
#if defined(GYRODRIFT_CM_SEMIHOSTING)
  char line[256];
  char* p = put_text(line, "lag-drift-fit status=");
  p = put_int(p, static_cast<std::int64_t>(fit.status));
  p = put_text(p, " evaluations=");
  p = put_int(p, fit.evaluations);
  p = put_text(p, " iterations=");
  p = put_int(p, fit.iterations);
  p = put_text(p, " runs=");
  p = put_int(p, fit.runs);
  p = put_text(p, " systick=");
  p = put_int(p, counts);
  p = put_text(p, " calibration=");
  p = put_int(p, calibration);
  p = put_text(p, " turns=");
  p = put_int(p, kCalibrationTurns);
  p = put_text(p, " a1_e6=");
  p = put_int(p, static_cast<std::int64_t>(fit.model.a1 * 1e6));
  p = put_text(p, " a2_e6=");
  p = put_int(p, static_cast<std::int64_t>(fit.model.a2 * 1e6));
  p = put_text(p, " lags=");
  p = put_int(p, static_cast<std::int64_t>(Stats::lags));
  p = put_text(p, " no_head=");
  p = put_int(p, kNoHead ? 1 : 0);
  p = put_text(p, " state_bytes=");
  p = put_int(p, static_cast<std::int64_t>(sizeof(Stats)));
  p = put_text(p, " fit_stack=");
  p = put_int(p, fit_stack);
  p = put_text(p, "\n");
  *p = '\0';
  report(line);
#endif
  // The estimate is near the simulated model (60000 samples: standard errors of about 0.05
  // for a1 and a2, 6 % for q and r).
  const bool near = fit.model.a1 > 0.4 && fit.model.a1 < 0.95 && fit.model.a2 > -0.3 && fit.model.a2 < 0.25 &&
                    fit.model.q > 0.6 && fit.model.q < 1.6 && fit.model.r > 0.6 && fit.model.r < 1.6;
  return fit.status == gyrodrift::LagDriftFitStatus::ok && near ? 0 : 2;
}
