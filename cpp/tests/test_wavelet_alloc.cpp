// The float real-time wavelet filter does not allocate after construction, in any mode.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <gyrodrift/filters/lifting_transform.hpp>
#include <gyrodrift/filters/realtime_wavelet.hpp>

#include "alloc_counter.hpp"

using gyrodrift::RealtimeWavelet;
using gyrodrift::WaveletKind;
using gyrodrift::WaveletMode;
using gyrodrift::test::AllocationScope;

namespace {
// Static storage: the filter (8 KiB per channel at N=256, float) is not on the test stack.
RealtimeWavelet<float, 256> g_forced(WaveletKind::db4, 5, WaveletMode::forced);
RealtimeWavelet<float, 256> g_soft(WaveletKind::db8, 5, WaveletMode::soft);
RealtimeWavelet<float, 256> g_hard(WaveletKind::db8, 5, WaveletMode::hard);
RealtimeWavelet<float, 256, false> g_lean(WaveletKind::db4, 5);
float g_data[512];
float g_scratch[512];
}  // namespace

TEST_CASE("step, reset and the transform are allocation-free") {
  float acc = 0.0F;
  long n_alloc = 0;
  {
    AllocationScope scope;
    for (int i = 0; i < 600; ++i) {
      const float x = static_cast<float>((i * 37) % 101) * 0.01F;
      acc += g_forced.step(x) + g_soft.step(x) + g_hard.step(x) + g_lean.step(x);
    }
    g_forced.reset();
    acc += g_forced.step(1.0F);
    for (int i = 0; i < 512; ++i) g_data[i] = static_cast<float>(i % 13);
    gyrodrift::LiftingTransform<float>::forward(WaveletKind::db8, g_data, 512, 5, g_scratch);
    gyrodrift::LiftingTransform<float>::inverse(WaveletKind::db8, g_data, 512, 5, g_scratch);
    n_alloc = scope.allocations();
  }
  CHECK(n_alloc == 0);
  CHECK(g_soft.ready());
  CHECK(acc == acc);  // keeps the work observable (not NaN)
}
