// C++-only timing of the alignment step: per IMU sample at 400 Hz, strapdown with
// coning/sculling alone, and the whole pipeline (mechanization + 15-state KF at 10 Hz, and
// + the 256-tap wavelet prefilter), double and float, on synthetic static-base increments
// with pseudo-noise. Process CPU time, median of 5 repeats. Usage: bench_align [N]
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <gyrodrift/nav/align_pipeline.hpp>
#include <memory>
#include <vector>

namespace {

double cpu_seconds() { return static_cast<double>(std::clock()) / static_cast<double>(CLOCKS_PER_SEC); }

template <class S>
struct Data {
  std::vector<Eigen::Matrix<S, 3, 1>> dth, dv;
  explicit Data(std::size_t n) : dth(n), dv(n) {
    std::uint64_t s = 7;
    auto u = [&s]() {
      s = s * 6364136223846793005ULL + 1442695040888963407ULL;
      return static_cast<double>(s >> 11) * 0x1.0p-53 - 0.5;
    };
    const double dt = 0.0025;
    for (std::size_t k = 0; k < n; ++k) {
      dth[k] = Eigen::Matrix<double, 3, 1>(2.8e-5 * dt + 1e-7 * u(), 4.9e-5 * dt + 1e-7 * u(),
                                           4.6e-5 * dt + 1e-7 * u()).cast<S>();
      dv[k] = Eigen::Matrix<double, 3, 1>(1e-5 * u(), 1e-5 * u(), 9.8 * dt + 1e-5 * u()).cast<S>();
    }
  }
};

template <class S>
double time_strapdown(const Data<S>& d) {
  gyrodrift::Strapdown<S> sd;
  sd.reset(gyrodrift::Quat<S>(S(1), S(0), S(0), S(0)), Eigen::Matrix<S, 3, 1>::Zero(),
           Eigen::Matrix<S, 3, 1>(S(0.68), S(2.0), S(50)));
  Eigen::Matrix<S, 3, 1> dvn;
  const double t0 = cpu_seconds();
  for (std::size_t k = 0; k < d.dth.size(); ++k) sd.step(d.dth[k], d.dv[k], S(0.0025), dvn);
  const double t = cpu_seconds() - t0;
  if (!sd.q().allFinite()) std::printf("non-finite\n");
  return t;
}

template <class S>
double time_pipeline(const Data<S>& d, bool prefilter) {
  using Pipe = gyrodrift::AlignPipeline<S, 15, 256, 32>;
  auto pipe = std::make_unique<Pipe>();
  gyrodrift::AlignSettings<S> s;
  s.dt_s = S(0.0025);
  s.lat_rad = S(0.68);
  s.lon_rad = S(2.0);
  s.h_m = S(50);
  s.coarse_samples = 400;  // short coarse phase: the timed part is fine alignment
  s.kf_every = 40;
  s.accel_delay_samples = prefilter ? 8 : 0;
  typename Pipe::VecN p0, q, fl;
  p0 << S(3e-4), S(3e-4), S(3e-2), S(0.25), S(0.25), S(0.25), S(1), S(1), S(1), S(1e-14), S(1e-14),
      S(1e-14), S(1e-6), S(1e-6), S(1e-6);
  q << S(8e-14), S(8e-14), S(8e-14), S(1e-8), S(1e-8), S(1e-8), S(0), S(0), S(0), S(0), S(0), S(0),
      S(0), S(0), S(0);
  fl.setConstant(S(1e-20));
  std::array<S, 256> taps;
  taps.fill(S(1) / S(256));
  pipe->reset(s, p0, q, typename Pipe::Vec3(S(1e-4), S(1e-4), S(1e-4)), fl, taps.data(),
              prefilter ? 256 : 0);
  const double t0 = cpu_seconds();
  for (std::size_t k = 0; k < d.dth.size(); ++k) pipe->step(d.dth[k], d.dv[k]);
  const double t = cpu_seconds() - t0;
  if (pipe->failed()) std::printf("pipeline failed\n");
  return t;
}

template <class F>
double median5(F f) {
  std::array<double, 5> t{};
  for (double& x : t) x = f();
  std::sort(t.begin(), t.end());
  return t[2];
}

}  // namespace

int main(int argc, char** argv) {
  const std::size_t n = argc > 1 ? static_cast<std::size_t>(std::atof(argv[1])) : 720000;
  const Data<double> dd(n);
  const Data<float> df(n);
  std::printf("| step (400 Hz, KF 15 states at 10 Hz) | scalar | ns/sample | samples/s | ratio vs strapdown |\n");
  std::printf("| --- | --- | --- | --- | --- |\n");
  auto row = [n](const char* name, const char* scalar, double t, double t_ref) {
    const double ns = t / static_cast<double>(n) * 1e9;
    std::printf("| %s | %s | %.0f | %.3g | %.2f |\n", name, scalar, ns,
                static_cast<double>(n) / t, t / t_ref);
  };
  const double sd_d = median5([&] { return time_strapdown(dd); });
  const double sd_f = median5([&] { return time_strapdown(df); });
  row("strapdown (coning + sculling)", "double", sd_d, sd_d);
  row("mechanization + KF", "double", median5([&] { return time_pipeline(dd, false); }), sd_d);
  row("prefilter + mechanization + KF", "double", median5([&] { return time_pipeline(dd, true); }), sd_d);
  row("strapdown (coning + sculling)", "float", sd_f, sd_f);
  row("mechanization + KF", "float", median5([&] { return time_pipeline(df, false); }), sd_f);
  row("prefilter + mechanization + KF", "float", median5([&] { return time_pipeline(df, true); }), sd_f);
  std::printf("\nN = %zu samples per repeat (30 min at 400 Hz by default); process CPU time, median of 5.\n", n);
  return 0;
}
