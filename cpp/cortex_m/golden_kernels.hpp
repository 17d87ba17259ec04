// MCU equals host: the float kernels run identically on the Cortex-M4F (under QEMU,
// golden_io_unit.cpp, I/O through semihosting) and on the host (golden_host.cpp, stdio), on
// the same golden input; tests/test_cortex_m_golden.py compares the two outputs bit for bit
// and with the double reference.
//
// Input record (32 B, little endian): u16 seq, u16 0, u32 t_us, f32 values[6].
// Output record (44 B): f32 ar2_kalman(v0), f32 fir(v1) (flash taps of the generated header),
// f32 realtime_wavelet_forced(v1) (taps computed on the device), f32 chain(v2) (flash FIR ->
// steady-state AR(2)-Kalman, missing input stays missing), f32 processor values[6] (the
// six-channel processor of the generated header), u16 flags, u16 0.
#pragma once
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include <gyrodrift/filters/ar2_kalman.hpp>
#include <gyrodrift/filters/ar2_steady_state.hpp>
#include <gyrodrift/filters/fir_prefilter.hpp>
#include <gyrodrift/filters/realtime_wavelet.hpp>

#include "generated/gyrodrift_budget_config.hpp"

namespace gyrodrift::golden {

inline constexpr std::size_t kInRecord = 32;
inline constexpr std::size_t kOutRecord = 44;

// The paper-002 model of the budget configuration (float32 values of the generated header).
inline Ar2Model<float> model() noexcept { return budget_config::kImuConfig.channels[0].model; }

struct Kernels {
  Ar2Kalman<float> kalman{model(), budget_config::kImuConfig.channels[0].q, budget_config::kImuConfig.channels[0].r};
  FirPrefilter<float, 256> fir{budget_config::kTaps_db4_n256_j5};
  RealtimeWavelet<float, 256, false> rtw{WaveletKind::db4, 5, WaveletMode::forced};
  FirPrefilter<float, 256> chain_fir{budget_config::kTaps_db4_n256_j5};
  Ar2SteadyStateKalman<float> chain_kf{model(), budget_config::kImuConfig.channels[0].q,
                                       budget_config::kImuConfig.channels[0].r};
  budget_config::Processor proc{budget_config::kImuConfig, budget_config::make_wavelet};

  bool ok() const noexcept {
    return kalman.status() == Ar2Status::ok && rtw.status() == RealtimeWaveletStatus::ok &&
           chain_kf.status() == Ar2Status::ok && proc.status() == ImuStatus::ok;
  }

  // One input record -> one output record.
  void step(const std::uint8_t* in, std::uint8_t* out) noexcept {
    std::uint16_t seq = 0;
    std::uint32_t t_us = 0;
    float v[6];
    std::memcpy(&seq, in, 2);
    std::memcpy(&t_us, in + 4, 4);
    std::memcpy(v, in + 8, sizeof v);
    float r[4];
    r[0] = kalman.step(v[0]);
    r[1] = fir.step(v[1]);
    r[2] = rtw.step(v[1]);
    const float pre = chain_fir.step(v[2]);
    r[3] = chain_kf.step(std::isfinite(v[2]) ? pre : std::numeric_limits<float>::quiet_NaN());
    ImuSample<float> s;
    s.seq = seq;
    s.t_us = t_us;
    for (std::size_t c = 0; c < 6; ++c) s.values[c] = v[c];
    ImuOutput<float> y;
    const std::uint16_t flags = proc.step(s, y);
    if ((flags & kFlagRejected) != 0u) {
      for (std::size_t c = 0; c < 6; ++c) y.values[c] = std::numeric_limits<float>::quiet_NaN();
    }
    std::memcpy(out, r, sizeof r);
    std::memcpy(out + 16, y.values.data(), 24);
    const std::uint16_t f2[2] = {flags, 0};
    std::memcpy(out + 40, f2, 4);
  }
};

}  // namespace gyrodrift::golden
