// Deviation-family kernels (include/gyrodrift/stability/deviation_*.hpp) against their definitions
// (explicit window sums in long double, NIST SP 1065 eqs. 14, 18, 20, 25 on the rate),
// the fused in-memory kernels (DeviationFused, HdevCascade) against the streaming ones,
// chunk splits, a large constant rate, a drifting record, float input, bad factors, and no
// allocation.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/stability/deviation_blocked.hpp>
#include <gyrodrift/stability/deviation_fused.hpp>
#include <gyrodrift/stability/deviation_hadamard.hpp>
#include <gyrodrift/stability/deviation_modified.hpp>
#include <gyrodrift/stability/deviation_total.hpp>
#include <vector>

#include "alloc_counter.hpp"

namespace {

std::vector<double> record(std::size_t n, double offset, std::uint64_t seed) {
  std::vector<double> y(n);
  std::uint64_t s = seed;
  double walk = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    const double u = static_cast<double>(s >> 11) * 0x1.0p-53 * 2.0 - 1.0;
    walk += 1e-3 * u;
    y[i] = offset + u + walk;
  }
  return y;
}

long double window(const std::vector<double>& y, std::ptrdiff_t start, std::size_t m,
                   bool reflect) {
  long double s = 0.0L;
  for (std::size_t k = 0; k < m; ++k) {
    const std::ptrdiff_t idx = start + static_cast<std::ptrdiff_t>(k);
    s += static_cast<long double>(
        reflect ? gyrodrift::totdev_reflected(y.data(), y.size(), idx)
                : y[static_cast<std::size_t>(idx)]);
  }
  return s;
}

// Definitions, O(N m) (long double window sums S_i).
long double def_mdev(const std::vector<double>& y, std::size_t m) {
  const std::size_t n = y.size() - 3 * m + 2;
  long double sum = 0.0L;
  for (std::size_t j = 0; j < n; ++j) {
    long double v = 0.0L;
    for (std::size_t i = j; i < j + m; ++i) {
      const auto is = static_cast<std::ptrdiff_t>(i);
      const auto ms = static_cast<std::ptrdiff_t>(m);
      v += window(y, is + ms, m, false) - window(y, is, m, false);
    }
    sum += v * v;
  }
  const long double mm = static_cast<long double>(m);
  return sum / (2.0L * mm * mm * mm * mm * static_cast<long double>(n));
}

long double def_hadamard(const std::vector<double>& y, std::size_t m, std::size_t stride) {
  long double sum = 0.0L;
  std::size_t n = 0;
  for (std::size_t i = 0; i + 3 * m <= y.size(); i += stride) {
    const auto is = static_cast<std::ptrdiff_t>(i);
    const auto ms = static_cast<std::ptrdiff_t>(m);
    const long double h = window(y, is + 2 * ms, m, false) -
                          2.0L * window(y, is + ms, m, false) + window(y, is, m, false);
    sum += h * h;
    ++n;
  }
  const long double mm = static_cast<long double>(m);
  return sum / (6.0L * mm * mm * static_cast<long double>(n));
}

long double def_totdev(const std::vector<double>& y, std::size_t m) {
  const std::size_t n = y.size() - 1;
  long double sum = 0.0L;
  const auto ms = static_cast<std::ptrdiff_t>(m);
  for (std::size_t i = 1; i <= n; ++i) {
    const auto is = static_cast<std::ptrdiff_t>(i);
    const long double d = window(y, is, m, true) - window(y, is - ms, m, true);
    sum += d * d;
  }
  const long double mm = static_cast<long double>(m);
  return sum / (2.0L * mm * mm * static_cast<long double>(n));
}

double rel(double a, long double b) {
  return static_cast<double>(std::fabs(static_cast<long double>(a) / b - 1.0L));
}

// The fused kernel for the factors m[0..n_m) (block B), results in out.
template <class Scalar>
bool fused(const std::vector<Scalar>& y, gyrodrift::FusedDeviation dev, const std::size_t* m,
           std::size_t n_m, std::size_t block, double* out, std::size_t* terms) {
  gyrodrift::DeviationFused<16> f;
  if (!f.plan(y.size(), dev, m, n_m, block)) return false;
  std::vector<double> work(f.workspace_doubles());
  return f.run(y.data(), work.data(), work.size(), out, terms);
}

}  // namespace

TEST_CASE("every kernel equals its definition, streaming and fused, large offset") {
  using gyrodrift::FusedDeviation;
  const auto y = record(3001, 1.0e4, 7);  // offset 1e4 on unit noise
  double work[3 * 512];
  for (std::size_t m : {1u, 2u, 5u, 64u, 333u, 1000u}) {
    double s2 = 0.0;
    std::size_t terms = 0;
    const long double md = def_mdev(y, m);
    REQUIRE(gyrodrift::mdev<double, double>(y.data(), y.size(), &m, 1, &s2, &terms));
    CHECK(rel(s2, md) < 1e-10);
    for (std::size_t block : {16u, 100u, 4096u}) {  // block edges, anchors, one block
      REQUIRE(fused(y, FusedDeviation::mdev, &m, 1, block, &s2, &terms));
      CHECK(rel(s2, md) < 1e-10);
      CHECK(terms == y.size() - 3 * m + 2);
    }
    const long double oh = def_hadamard(y, m, 1);
    REQUIRE(gyrodrift::ohdev<double, double>(y.data(), y.size(), &m, 1, &s2, &terms));
    CHECK(rel(s2, oh) < 1e-10);
    for (std::size_t block : {16u, 100u, 4096u}) {
      REQUIRE(fused(y, FusedDeviation::ohdev, &m, 1, block, &s2, &terms));
      CHECK(rel(s2, oh) < 1e-10);
      CHECK(terms == y.size() - 3 * m + 1);
    }
    if (m <= gyrodrift::hdev_max_m(y.size())) {
      const long double hd = def_hadamard(y, m, m);
      REQUIRE(gyrodrift::hdev<double, double>(y.data(), y.size(), &m, 1, &s2, &terms));
      CHECK(rel(s2, hd) < 1e-10);
      gyrodrift::HdevCascade<4> hc;
      REQUIRE(hc.plan(y.size(), &m, 1));
      std::vector<double> wk(hc.workspace_len());
      REQUIRE(hc.run(y.data(), wk.data(), wk.size(), &s2, &terms));
      CHECK(rel(s2, hd) < 1e-10);
    }
    const long double td = def_totdev(y, m);
    REQUIRE(gyrodrift::totdev<double, double>(y.data(), y.size(), &m, 1, work, 512, &s2,
                                              &terms));
    CHECK(rel(s2, td) < 1e-10);
    for (std::size_t block : {16u, 100u, 4096u}) {
      REQUIRE(fused(y, FusedDeviation::totdev, &m, 1, block, &s2, &terms));
      CHECK(rel(s2, td) < 1e-10);
      CHECK(terms == y.size() - 1);
    }
  }
}

TEST_CASE("fused groups equal the per-tau long double kernels on a drifting record") {
  // 2e5 samples, offset 15, a random walk on top (the level moves across the record), an
  // octave grid and a few uneven factors in one group; the fused kernels against the
  // streaming long double ones. 1e-12: double prefix sums over one segment of level-removed
  // data (~B eps relative) and, for mdev, V integrated over at most max(B, 16 m) terms
  // between exact restarts; measured <= 2e-13.
  using gyrodrift::FusedDeviation;
  std::vector<double> y = record(200000, 15.0, 5);
  for (std::size_t i = 0; i < y.size(); ++i) y[i] += 1e-5 * static_cast<double>(i);
  const std::size_t ms[] = {1, 2, 3, 4, 8, 16, 32, 64, 100, 128, 256, 512, 1024, 4096,
                            16384, 65536};
  const std::size_t n_m = sizeof(ms) / sizeof(ms[0]);
  double out[n_m];
  double per[n_m];
  std::size_t t_out[n_m];
  std::size_t t_per[n_m];
  REQUIRE(fused(y, FusedDeviation::ohdev, ms, n_m, 4096, out, t_out));
  REQUIRE(gyrodrift::ohdev<double, double>(y.data(), y.size(), ms, n_m, per, t_per));
  for (std::size_t j = 0; j < n_m; ++j) {
    CHECK(rel(out[j], per[j]) < 1e-12);
    CHECK(t_out[j] == t_per[j]);
  }
  REQUIRE(fused(y, FusedDeviation::mdev, ms, n_m, 4096, out, t_out));
  REQUIRE(gyrodrift::mdev<double, double>(y.data(), y.size(), ms, n_m, per, t_per));
  for (std::size_t j = 0; j < n_m; ++j) {
    CHECK(rel(out[j], per[j]) < 1e-12);
    CHECK(t_out[j] == t_per[j]);
  }
  const std::size_t mt[] = {1, 2, 5, 64, 1000, 65536, 150000, 200000};  // up to m = N
  double wk[3 * 512];
  REQUIRE(fused(y, FusedDeviation::totdev, mt, 8, 4096, out, t_out));
  REQUIRE(gyrodrift::totdev<double, double>(y.data(), y.size(), mt, 8, wk, 512, per, t_per));
  for (std::size_t j = 0; j < 8; ++j) {
    CHECK(rel(out[j], per[j]) < 1e-12);
    CHECK(t_out[j] == t_per[j]);
  }
}

TEST_CASE("fused kernels on a steep rate ramp equal the per-tau long double kernels") {
  // 2e5 samples of uniform noise (sigma 0.58) plus a ramp of 3e-2 per sample (1e4 sigma over
  // the record): the fused kernels remove the record's rate line in their prefix sums and
  // start values (totdev adds the mirrored ends back in closed form). With one level per
  // block they lost 1e-9..1e-8 here; measured now <= 1e-13. Bound 1e-11.
  using gyrodrift::FusedDeviation;
  std::vector<double> y = record(200000, 15.0, 9);
  for (std::size_t i = 0; i < y.size(); ++i) y[i] += 3e-2 * static_cast<double>(i);
  const std::size_t ms[] = {1, 2, 3, 8, 64, 100, 1024, 4096, 16384, 65536};
  constexpr std::size_t n_m = sizeof(ms) / sizeof(ms[0]);
  double out[n_m];
  double per[n_m];
  std::size_t t_out[n_m];
  std::size_t t_per[n_m];
  REQUIRE(fused(y, FusedDeviation::ohdev, ms, n_m, 4096, out, t_out));
  REQUIRE(gyrodrift::ohdev<double, double>(y.data(), y.size(), ms, n_m, per, t_per));
  for (std::size_t j = 0; j < n_m; ++j) CHECK(rel(out[j], per[j]) < 1e-11);
  REQUIRE(fused(y, FusedDeviation::mdev, ms, n_m, 4096, out, t_out));
  REQUIRE(gyrodrift::mdev<double, double>(y.data(), y.size(), ms, n_m, per, t_per));
  for (std::size_t j = 0; j < n_m; ++j) CHECK(rel(out[j], per[j]) < 1e-11);
  const std::size_t mt[] = {1, 2, 5, 64, 1000, 65536, 150000, 200000};  // up to m = N
  double wk[3 * 512];
  REQUIRE(fused(y, FusedDeviation::totdev, mt, 8, 4096, out, t_out));
  REQUIRE(gyrodrift::totdev<double, double>(y.data(), y.size(), mt, 8, wk, 512, per, t_per));
  for (std::size_t j = 0; j < 8; ++j) CHECK(rel(out[j], per[j]) < 1e-11);
  const std::size_t mh[] = {1, 2, 4, 8, 64, 1024, 16384, 32768};
  gyrodrift::HdevCascade<64> cascade;
  REQUIRE(cascade.plan(y.size(), mh, 8));
  std::vector<double> work(cascade.workspace_len());
  REQUIRE(cascade.run(y.data(), work.data(), work.size(), out, t_out));
  REQUIRE(gyrodrift::hdev<double, double>(y.data(), y.size(), mh, 8, per, t_per));
  for (std::size_t j = 0; j < 8; ++j) CHECK(rel(out[j], per[j]) < 1e-11);
}

TEST_CASE("ohdev start values: streams in segments that sit back to back") {
  // Block 4095 and m = 4096: each of the four streams gets its own segment of 4096 Q values,
  // laid out back to back in the workspace exactly as the data are, so the stream positions
  // look like one run; the start value H_0 must still come from the samples (each segment's
  // Q restarts at 0). With m = 5 added the first segment is shared (H_0 from Q).
  using gyrodrift::FusedDeviation;
  const std::vector<double> y = record(40000, 15.0, 13);
  const std::size_t ms[] = {5, 4096};
  double out[2];
  double per[2];
  std::size_t t_out[2];
  std::size_t t_per[2];
  REQUIRE(gyrodrift::ohdev<double, double>(y.data(), y.size(), ms, 2, per, t_per));
  for (const std::size_t block : {std::size_t{4095}, std::size_t{4096}, std::size_t{1000}}) {
    REQUIRE(fused(y, FusedDeviation::ohdev, ms + 1, 1, block, out, t_out));
    CHECK(rel(out[0], per[1]) < 1e-12);
    REQUIRE(fused(y, FusedDeviation::ohdev, ms, 2, block, out, t_out));
    CHECK(rel(out[0], per[0]) < 1e-12);
    CHECK(rel(out[1], per[1]) < 1e-12);
  }
}

TEST_CASE("fused kernels: same bits at any workspace alignment; odd sizes equal per tau") {
  // The workspace's segments start at multiples of 8 doubles (64-byte aligned streams read
  // faster); the arithmetic must not depend on where the workspace sits: runs from every
  // offset 0..7 (in doubles) of one buffer give the same bits. N just above three blocks
  // of 4096 (odd), factors not powers of two, blocks 4096, 1000, 777 (pieces of the mdev
  // chains not multiples of 4 steps), against the long double per-tau kernels at the
  // fused kernels' 1e-12 (measured <= 1e-13 here).
  using gyrodrift::FusedDeviation;
  std::vector<double> y = record(3 * 4096 + 5, 15.0, 13);
  for (std::size_t i = 0; i < y.size(); ++i) y[i] += 2e-5 * static_cast<double>(i);
  const std::size_t ms[] = {1, 2, 3, 5, 7, 12, 24, 100, 200, 1000, 3001, 4097};
  constexpr std::size_t n_m = sizeof(ms) / sizeof(ms[0]);
  double wk[3 * 512];
  for (auto dev : {FusedDeviation::ohdev, FusedDeviation::mdev, FusedDeviation::totdev}) {
    double per[n_m];
    std::size_t t_per[n_m];
    if (dev == FusedDeviation::ohdev) {
      REQUIRE(gyrodrift::ohdev<double, double>(y.data(), y.size(), ms, n_m, per, t_per));
    } else if (dev == FusedDeviation::mdev) {
      REQUIRE(gyrodrift::mdev<double, double>(y.data(), y.size(), ms, n_m, per, t_per));
    } else {
      REQUIRE(gyrodrift::totdev<double, double>(y.data(), y.size(), ms, n_m, wk, 512, per,
                                                t_per));
    }
    for (std::size_t block : {4096u, 1000u, 777u}) {
      gyrodrift::DeviationFused<16> f;
      REQUIRE(f.plan(y.size(), dev, ms, n_m, block));
      std::vector<double> store(f.workspace_doubles() + 8);
      double first[n_m];
      for (std::size_t shift = 0; shift < 8; ++shift) {
        double out[n_m];
        std::size_t t_out[n_m];
        REQUIRE(f.run(y.data(), store.data() + shift, f.workspace_doubles(), out, t_out));
        for (std::size_t j = 0; j < n_m; ++j) {
          if (shift == 0) {
            first[j] = out[j];
            CHECK(rel(out[j], per[j]) < 1e-12);
            CHECK(t_out[j] == t_per[j]);
          } else {
            CHECK(out[j] == first[j]);
          }
        }
      }
      if (dev == FusedDeviation::ohdev) {
        // taus m, 2 m (1-2, 12-24, 100-200) summed as pairs (default) or each alone: the
        // same terms in another order
        f.use_pairs(false);
        double alone[n_m];
        std::size_t t_alone[n_m];
        REQUIRE(f.run(y.data(), store.data(), f.workspace_doubles(), alone, t_alone));
        for (std::size_t j = 0; j < n_m; ++j) CHECK(rel(alone[j], first[j]) < 1e-14);
      }
    }
  }
}

TEST_CASE("hdev cascade over several chunks equals per tau") {
  // 3 chunks of 2**14 and 5 samples: the levels cascade across chunk edges (the one-chunk
  // test above never crosses one).
  const auto y = record(3 * (std::size_t{1} << 14) + 5, 15.0, 17);
  const std::size_t ms[] = {1, 2, 3, 4, 8, 12, 100, 4096, 12288};
  constexpr std::size_t n_m = sizeof(ms) / sizeof(ms[0]);
  double cascade[n_m];
  std::size_t ct[n_m];
  gyrodrift::HdevCascade<16> hc;
  REQUIRE(hc.plan(y.size(), ms, n_m));
  std::vector<double> wk(hc.workspace_len());
  REQUIRE(hc.run(y.data(), wk.data(), wk.size(), cascade, ct));
  for (std::size_t j = 0; j < n_m; ++j) {
    double per = 0.0;
    std::size_t t = 0;
    REQUIRE(gyrodrift::hdev<double, double>(y.data(), y.size(), &ms[j], 1, &per, &t));
    CHECK(rel(cascade[j], per) < 1e-13);  // as the one-chunk test above
    CHECK(ct[j] == t);
  }
}

TEST_CASE("fused term-range parts add up to the whole run, for any number of parts") {
  // Parts after the first start from values recomputed from the samples; for mdev a part
  // may start at the last term (V without H: m = 995 on 3000 samples, 17 terms, block 16).
  using gyrodrift::FusedDeviation;
  const auto y = record(3000, 7.0, 9);
  const std::size_t ms[] = {1, 3, 16, 100, 995};
  for (auto dev : {FusedDeviation::ohdev, FusedDeviation::mdev, FusedDeviation::totdev}) {
    for (std::size_t j = 0; j < 5; ++j) {
      if (dev == FusedDeviation::ohdev && ms[j] > gyrodrift::ohdev_max_m(y.size())) continue;
      double whole = 0.0;
      std::size_t t_whole = 0;
      REQUIRE(fused(y, dev, &ms[j], 1, 16, &whole, &t_whole));
      for (std::size_t n_parts : {2u, 3u, 7u}) {
        std::vector<gyrodrift::DeviationFused<4>> parts(n_parts);
        std::vector<const gyrodrift::DeviationFused<4>*> ptrs;
        for (std::size_t k = 0; k < n_parts; ++k) {
          auto& f = parts[k];
          REQUIRE(f.plan(y.size(), dev, &ms[j], 1, 16));
          std::vector<double> work(f.workspace_doubles());
          REQUIRE(f.accumulate(y.data(), work.data(), work.size(), f.part_begin(k, n_parts),
                               f.part_begin(k + 1, n_parts)));
          ptrs.push_back(&f);
        }
        double split = 0.0;
        std::size_t t_split = 0;
        REQUIRE(gyrodrift::DeviationFused<4>::finish_parts(ptrs.data(), n_parts, &split,
                                                            &t_split));
        CHECK(rel(split, whole) < 1e-12);
        CHECK(t_split == t_whole);
      }
    }
  }
}

TEST_CASE("streaming splits give the whole-array result; hdev cascade equals per tau") {
  const auto y = record(5000, 3.0, 11);
  const std::size_t m = 37;
  double whole = 0.0;
  std::size_t terms = 0;
  REQUIRE(gyrodrift::mdev<double, double>(y.data(), y.size(), &m, 1, &whole, &terms));
  gyrodrift::ModAllanSums<long double> s;
  const double* p = y.data();
  gyrodrift::mdev_rate_seed_diff(s, p, p + m, 10);
  gyrodrift::mdev_rate_seed_diff(s, p + 10, p + m + 10, m - 10);
  gyrodrift::mdev_rate_seed_inner(s, p, p + m, p + 2 * m, 20);
  gyrodrift::mdev_rate_seed_inner(s, p + 20, p + m + 20, p + 2 * m + 20, m - 20);
  const std::size_t n_adv = y.size() - 3 * m;
  gyrodrift::mdev_rate_advance(s, p, p + m, p + 2 * m, p + 3 * m, 1000);
  gyrodrift::mdev_rate_advance(s, p + 1000, p + m + 1000, p + 2 * m + 1000, p + 3 * m + 1000,
                               n_adv - 1000);
  gyrodrift::mdev_rate_finish(s);
  double split = 0.0;
  REQUIRE(gyrodrift::mdev_sigma2(s, m, split));
  CHECK(split == whole);
  const std::size_t ms[] = {1, 2, 4, 8, 12, 16, 48, 300, 1024};
  double cascade[9];
  std::size_t ct[9];
  gyrodrift::HdevCascade<16> hc;
  REQUIRE(hc.plan(y.size(), ms, 9));
  std::vector<double> wk(hc.workspace_len());
  REQUIRE(hc.run(y.data(), wk.data(), wk.size(), cascade, ct));
  for (std::size_t j = 0; j < 9; ++j) {
    double per = 0.0;
    std::size_t t = 0;
    REQUIRE(gyrodrift::hdev<double, double>(y.data(), y.size(), &ms[j], 1, &per, &t));
    // double block sums of (y - level), pairwise for the octave levels: ~log2(m) eps
    CHECK(rel(cascade[j], per) < 1e-13);
    CHECK(ct[j] == t);
  }
}

TEST_CASE("float input, bad factors, no allocation") {
  using gyrodrift::FusedDeviation;
  const auto y = record(2000, 0.5, 3);
  std::vector<float> yf(y.begin(), y.end());
  const std::size_t m = 9;
  double a = 0.0;
  double b = 0.0;
  std::size_t t = 0;
  std::vector<double> yd(yf.begin(), yf.end());
  for (auto dev : {FusedDeviation::ohdev, FusedDeviation::mdev, FusedDeviation::totdev}) {
    REQUIRE(fused(yf, dev, &m, 1, 64, &a, &t));
    REQUIRE(fused(yd, dev, &m, 1, 64, &b, &t));
    CHECK(rel(a, b) < 1e-14);  // same values, float only in storage
  }
  gyrodrift::DeviationFused<4> f;
  const std::size_t too_big = gyrodrift::mdev_max_m(y.size()) + 1;
  CHECK_FALSE(f.plan(y.size(), FusedDeviation::mdev, &too_big, 1, 64));
  const std::size_t zero = 0;
  CHECK_FALSE(f.plan(y.size(), FusedDeviation::ohdev, &zero, 1, 64));
  const std::size_t beyond = y.size() + 1;
  CHECK_FALSE(f.plan(y.size(), FusedDeviation::totdev, &beyond, 1, 64));
  const std::size_t unsorted[] = {4, 2};
  CHECK_FALSE(f.plan(y.size(), FusedDeviation::ohdev, unsorted, 2, 64));
  CHECK_FALSE(f.plan(y.size(), FusedDeviation::ohdev, &m, 1, 8));  // block < 16
  std::size_t largest = 0;
  for (auto dev : {FusedDeviation::ohdev, FusedDeviation::mdev, FusedDeviation::totdev}) {
    REQUIRE(f.plan(y.size(), dev, &m, 1, 64));
    largest = f.workspace_doubles() > largest ? f.workspace_doubles() : largest;
  }
  REQUIRE(f.plan(y.size(), FusedDeviation::mdev, &m, 1, 64));
  std::vector<double> work(largest);
  CHECK_FALSE(f.run(y.data(), work.data(), f.workspace_doubles() - 1, &a, &t));  // too short
  std::vector<double> bad(y);
  bad[1500] = std::nan("");
  CHECK_FALSE(f.run(bad.data(), work.data(), work.size(), &a, &t));
  gyrodrift::HdevCascade<4> hc;
  REQUIRE(hc.plan(y.size(), &m, 1));
  std::vector<double> hwork(hc.workspace_len());
  bool ok = true;
  gyrodrift::test::AllocationScope scope;
  for (auto dev : {FusedDeviation::ohdev, FusedDeviation::mdev, FusedDeviation::totdev}) {
    ok = ok && f.plan(y.size(), dev, &m, 1, 64) && work.size() >= f.workspace_doubles() &&
         f.run(y.data(), work.data(), work.size(), &a, &t);
  }
  ok = ok && hc.run(y.data(), hwork.data(), hwork.size(), &a, &t);
  ok = ok && gyrodrift::ohdev<double, double>(y.data(), y.size(), &m, 1, &a, &t);
  const long n_alloc = scope.allocations();  // read before any CHECK (doctest allocates)
  CHECK(ok);
  CHECK(n_alloc == 0);
}
