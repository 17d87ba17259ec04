// Shared helpers of the wavelet C++ tests: an independent oracle (direct periodized
// convolution with PyWavelets' published filter taps) and a deterministic noise source.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <gyrodrift/filters/lifting_transform.hpp>

namespace wavelet_test {

// PyWavelets' rec_lo (Daubechies extremal phase), copied from pywt.Wavelet(name).rec_lo.
inline const std::vector<double>& rec_lo(gyrodrift::WaveletKind w) {
  static const std::vector<double> db4 = {0.2303778133088965,  0.7148465705529157,  0.6308807679298589,
                                          -0.027983769416859854, -0.18703481171909309, 0.030841381835560764,
                                          0.0328830116668852,  -0.010597401785069032};
  static const std::vector<double> db8 = {
      0.05441584224310401,   0.31287159091429995,  0.6756307362972898,     0.5853546836542067,
      -0.015829105256349306, -0.2840155429615469,  0.0004724845739132828,  0.12874742662047847,
      -0.017369301001807547, -0.044088253930794755, 0.013981027917398282,  0.008746094047405777,
      -0.004870352993451574, -0.00039174037337694705, 0.0006754494064505693, -0.00011747678412476953};
  return w == gyrodrift::WaveletKind::db8 ? db8 : db4;
}

// One periodized analysis level as PyWavelets defines it:
// cA[k] = sum_m h[m + N - 1] x[(2k + m) mod n], cD likewise with g[i] = (-1)^i h[L-1-i].
template <class T>
void direct_level(gyrodrift::WaveletKind w, std::vector<T>& x, std::size_t n) {
  const auto& h = rec_lo(w);
  const std::size_t taps = h.size();
  const auto m0 = -static_cast<std::ptrdiff_t>(taps / 2 - 1);
  std::vector<T> out(n);
  const auto sn = static_cast<std::ptrdiff_t>(n);
  for (std::size_t k = 0; k < n / 2; ++k) {
    T a = T(0), d = T(0);
    for (std::size_t i = 0; i < taps; ++i) {
      std::ptrdiff_t idx = (2 * static_cast<std::ptrdiff_t>(k) + m0 + static_cast<std::ptrdiff_t>(i)) % sn;
      if (idx < 0) idx += sn;
      const T xv = x[static_cast<std::size_t>(idx)];
      const T hv = static_cast<T>(h[i]);
      const T gv = static_cast<T>((i % 2 == 0 ? 1.0 : -1.0) * h[taps - 1 - i]);
      a += hv * xv;
      d += gv * xv;
    }
    out[k] = a;
    out[n / 2 + k] = d;
  }
  for (std::size_t i = 0; i < n; ++i) x[i] = out[i];
}

template <class T>
std::vector<T> direct_wavedec(gyrodrift::WaveletKind w, std::vector<T> x, int levels) {
  for (int j = 0; j < levels; ++j) direct_level(w, x, x.size() >> static_cast<unsigned>(j));
  return x;
}

// Deterministic unit-variance-ish noise (sum of 12 uniforms - 6), no <random> distribution
// differences between standard libraries.
struct Noise {
  std::uint64_t s = 0x9E3779B97F4A7C15ull;
  double uniform() {
    s ^= s << 13;
    s ^= s >> 7;
    s ^= s << 17;
    return static_cast<double>(s >> 11) * (1.0 / 9007199254740992.0);
  }
  double normal() {
    double acc = -6.0;
    for (int i = 0; i < 12; ++i) acc += uniform();
    return acc;
  }
};

}  // namespace wavelet_test
