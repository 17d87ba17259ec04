// Strapdown, coarse alignment, fine-alignment KF and the whole pipeline, in double
// and float, on ideal static-base increments built here from the Earth model:
//   omega_ib^b = C_n^b [0, W cos L, W sin L],  f^b = C_n^b [0, 0, g(L, h)].
// The Python suite (tests/test_align_*.py) compares the same headers with the numpy reference
// on rocking-base data; this file proves the C++ side on its own, incl. allocation-freedom.
#define EIGEN_RUNTIME_NO_MALLOC
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <cmath>
#include <gyrodrift/nav/align_pipeline.hpp>
#include <gyrodrift/nav/attitude.hpp>
#include <gyrodrift/nav/coarse_align.hpp>
#include <gyrodrift/nav/earth.hpp>
#include <gyrodrift/nav/fine_align_kf.hpp>
#include <gyrodrift/nav/strapdown.hpp>
#include <limits>

#include "alloc_counter.hpp"

namespace {

using namespace gyrodrift;
constexpr double kDeg = 3.14159265358979323846 / 180.0;
constexpr double kArcsec = kDeg / 3600.0;
constexpr double kDph = kDeg / 3600.0;
constexpr double kUg = 9.80665e-6;

template <class S>
struct StaticImu {
  Eigen::Matrix<S, 3, 1> dth, dv;
  Eigen::Matrix<S, 3, 3> cnb;
  StaticImu(double lat, double h, const Eigen::Vector3d& att, double dt,
            const Eigen::Vector3d& eps_b = Eigen::Vector3d::Zero(),
            const Eigen::Vector3d& nab_b = Eigen::Vector3d::Zero()) {
    const Eigen::Matrix3d c = euler2dcm<double>(att);
    EarthParams<double> ep;
    ep.update(lat, h, Eigen::Vector3d::Zero());
    dth = ((c.transpose() * ep.wnie + eps_b) * dt).template cast<S>();
    dv = ((c.transpose() * (-ep.gn) + nab_b) * dt).template cast<S>();
    cnb = c.template cast<S>();
  }
};

template <class S>
Eigen::Matrix<S, 3, 1> misalignment(const Eigen::Matrix<S, 3, 3>& est, const Eigen::Matrix<S, 3, 3>& tru) {
  const Eigen::Matrix<S, 3, 3> d = tru * est.transpose();  // I + [phi x]
  return Eigen::Matrix<S, 3, 1>(d(2, 1) - d(1, 2), d(0, 2) - d(2, 0), d(1, 0) - d(0, 1)) * S(0.5);
}

const double kLat = 39.0 * kDeg;
const Eigen::Vector3d kAtt(1.0 * kDeg, -2.0 * kDeg, 30.0 * kDeg);

}  // namespace

TEST_CASE("attitude helpers round-trip") {
  const Eigen::Matrix3d c = euler2dcm<double>(kAtt);
  CHECK((q2dcm(dcm2q(c)) - c).cwiseAbs().maxCoeff() < 1e-15);
  CHECK((dcm2euler(c) - kAtt).cwiseAbs().maxCoeff() < 1e-15);
  const Eigen::Vector3d rv(1e-5, -2e-5, 3e-5);  // small-angle series branch vs closed form
  const Eigen::Vector4d q = rv2q(rv);
  const double a = rv.norm();
  CHECK(std::fabs(q(0) - std::cos(a / 2)) < 1e-16);
  CHECK(std::fabs(q(3) - std::sin(a / 2) / a * rv(2)) < 1e-19);
}

TEST_CASE("static-base strapdown stays put for 10 min with ideal sensors (double)") {
  const double dt = 1.0 / 400.0;
  const StaticImu<double> imu(kLat, 50.0, kAtt, dt);
  Strapdown<double> sd;
  sd.reset(dcm2q(imu.cnb), Eigen::Vector3d::Zero(), Eigen::Vector3d(kLat, 2.0, 50.0));
  Eigen::Vector3d dvn;
  for (int k = 0; k < 400 * 600; ++k) REQUIRE(sd.step(imu.dth, imu.dv, dt, dvn));
  // Bounds: the mechanization is exact for constant rates up to rounding; 1e-4 arcsec and
  // 1e-6 m/s leave ~100x margin over the observed 1e-6 arcsec / 1e-8 m/s (rounding growth
  // over 240000 steps, including the unstable vertical channel's slow amplification).
  const Eigen::Vector3d phi = misalignment<double>(q2dcm(sd.q()), imu.cnb);
  CHECK(phi.cwiseAbs().maxCoeff() < 1e-4 * kArcsec);
  CHECK(sd.vn().cwiseAbs().maxCoeff() < 1e-6);
}

TEST_CASE("strapdown rejects non-finite input without touching its state") {
  Strapdown<double> sd;
  sd.reset(Eigen::Vector4d(1, 0, 0, 0), Eigen::Vector3d::Zero(), Eigen::Vector3d(kLat, 0, 0));
  Eigen::Vector3d dvn;
  const Eigen::Vector3d nan3 = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  CHECK_FALSE(sd.step(nan3, Eigen::Vector3d::Zero(), 0.01, dvn));
  CHECK_FALSE(sd.step(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), -0.01, dvn));
  CHECK(sd.q() == Eigen::Vector4d(1, 0, 0, 0));
}

TEST_CASE("coarse alignment on ideal static data: double and float") {
  const double dt = 0.01;
  for (const bool position : {false, true}) {
    const StaticImu<double> imu(kLat, 50.0, kAtt, dt);
    InertialCoarseAlign<double> c;
    REQUIRE(c.reset(6000, dt, kLat, 50.0, position));
    Eigen::Matrix3d cnb;
    CHECK_FALSE(c.solve(cnb));  // incomplete window
    for (int k = 0; k < 6000; ++k) REQUIRE(c.add(imu.dth, imu.dv));
    REQUIRE(c.solve(cnb));
    // Truth at the end equals the start (static base, attitude relative to local level).
    // Ideal data: only rounding remains; 1e-3 arcsec is far above it (observed 1e-8 arcsec).
    CHECK(misalignment<double>(cnb, imu.cnb).cwiseAbs().maxCoeff() < 1e-3 * kArcsec);

    const StaticImu<float> imuf(kLat, 50.0, kAtt, dt);
    InertialCoarseAlign<float> cf;
    REQUIRE(cf.reset(6000, static_cast<float>(dt), static_cast<float>(kLat), 50.0f, position));
    for (int k = 0; k < 6000; ++k) REQUIRE(cf.add(imuf.dth, imuf.dv));
    Eigen::Matrix3f cnbf;
    REQUIRE(cf.solve(cnbf));
    // Float: the heading rests on the Earth-rate part of the accumulated vectors, about 1e-4
    // of the gravity part after 60 s, so float rounding (6e-8 relative per sum over 6000 sums)
    // costs ~1e-3 rad of heading (observed 2e-4..8e-4 rad); level is observed at 2e-6 rad.
    const Eigen::Vector3f phif = misalignment<float>(cnbf, imuf.cnb);
    CHECK(std::fabs(phif(0)) < 2e-5f);
    CHECK(std::fabs(phif(1)) < 2e-5f);
    CHECK(std::fabs(phif(2)) < 5e-3f);
  }
}

TEST_CASE("KF numerics: Joseph update keeps P symmetric positive, bad input leaves P unchanged") {
  using Kf = FineAlignKF<double, 15>;
  Kf kf;
  Kf::VecN p0, q, fl;
  p0 << 3e-4, 3e-4, 3e-2, 0.25, 0.25, 0.25, 1, 1, 1, 1e-14, 1e-14, 1e-14, 1e-6, 1e-6, 1e-6;
  q.setConstant(1e-12);
  fl.setConstant(1e-30);
  REQUIRE(kf.reset(p0, q, Eigen::Vector3d::Constant(1e-4), fl));
  CHECK_FALSE(kf.reset(-p0, q, Eigen::Vector3d::Constant(1e-4), fl));
  EarthParams<double> ep;
  ep.update(kLat, 50.0, Eigen::Vector3d::Zero());
  Kf::MatN f;
  Kf::transition(euler2dcm<double>(kAtt), Eigen::Vector3d(0, 0, 9.8), ep, kLat, f);
  for (int i = 0; i < 200; ++i) {
    REQUIRE(kf.predict(f, 0.1));
    REQUIRE(kf.update(Eigen::Vector3d(1e-3, -2e-3, 5e-4)));
  }
  CHECK((kf.P() - kf.P().transpose()).cwiseAbs().maxCoeff() == 0.0);
  CHECK(kf.P().diagonal().minCoeff() > 0.0);
  const Kf::MatN before = kf.P();
  CHECK_FALSE(kf.update(Eigen::Vector3d(std::numeric_limits<double>::quiet_NaN(), 0, 0)));
  CHECK_FALSE(kf.predict(f, 0.0));
  CHECK(kf.P() == before);
}

namespace {
template <class S, int N>
struct PipeRun {
  AlignPipeline<S, N, 256, 32> pipe;
  void setup(double dt, long coarse, int kf_every, long stage_cycles = 0, double stage_q = 0.0) {
    AlignSettings<S> s;
    s.heading_stage_cycles = stage_cycles;
    s.heading_stage_q = static_cast<S>(stage_q);
    s.dt_s = static_cast<S>(dt);
    s.lat_rad = static_cast<S>(kLat);
    s.lon_rad = S(2);
    s.h_m = S(50);
    s.coarse_samples = coarse;
    s.kf_every = kf_every;
    using VecN = typename AlignPipeline<S, N>::VecN;
    VecN p0, q, fl;
    Eigen::Matrix<double, 15, 1> p15, q15, f15;
    const double p_eb = 0.02 * kDph, p_db = 100 * kUg;
    p15 << std::pow(kDeg, 2), std::pow(kDeg, 2), std::pow(10 * kDeg, 2), 0.25, 0.25, 0.25, 1, 1, 1,
        p_eb * p_eb, p_eb * p_eb, p_eb * p_eb, p_db * p_db, p_db * p_db, p_db * p_db;
    q15.setZero();
    q15.head<3>().setConstant(std::pow(0.001 * kDeg / 60.0, 2));
    q15.segment<3>(3).setConstant(std::pow(10 * kUg, 2));
    f15.setConstant(1e-30);
    if constexpr (N == 15) {
      p0 = p15.cast<S>();
      q = q15.cast<S>();
      fl = f15.cast<S>();
    } else {
      p0 << p15.head<6>().cast<S>(), p15.tail<6>().cast<S>();
      q << q15.head<6>().cast<S>(), q15.tail<6>().cast<S>();
      fl << f15.head<6>().cast<S>(), f15.tail<6>().cast<S>();
    }
    const Eigen::Matrix<S, 3, 1> r = Eigen::Matrix<S, 3, 1>::Constant(S(1e-6));
    REQUIRE(pipe.reset(s, p0, q, r, fl, nullptr, 0));
  }
};
}  // namespace

TEST_CASE("fine alignment converges to the steady-state formulas (static, biases, double)") {
  // Biases chosen with the nav-frame gyro drift purely East (eps_N = eps_U = 0 are the
  // observable components a 15-min alignment only partly estimates), so the residual
  // misalignment must be phi_E = -nab_N/g, phi_N = nab_E/g,
  // phi_U = -eps_E/(W cos L) + (nab_E/g) tan L   (the steady-state heading-error formula).
  const double dt = 0.05;
  const Eigen::Matrix3d c = euler2dcm<double>(kAtt);
  const Eigen::Vector3d eps_n(0.01 * kDph, 0, 0), nab_n(100 * kUg, -80 * kUg, 50 * kUg);
  const StaticImu<double> imu(kLat, 50.0, kAtt, dt, c.transpose() * eps_n, c.transpose() * nab_n);
  PipeRun<double, 15> run;
  run.setup(dt, 1200, 2);
  for (int k = 0; k < 20 * 60 * 20; ++k) REQUIRE(run.pipe.step(imu.dth, imu.dv) != AlignStatus::kFailed);
  const Eigen::Vector3d phi = misalignment<double>(q2dcm(run.pipe.nav().q()), c);
  const double g = gravity_m_s2(kLat, 50.0);
  const double w = EarthConstants<double>::rate_rad_s;
  const Eigen::Vector3d theory(-nab_n(1) / g, nab_n(0) / g,
                               -eps_n(0) / (w * std::cos(kLat)) + nab_n(0) / g * std::tan(kLat));
  for (int i = 0; i < 3; ++i) {
    INFO("axis " << i << " phi " << phi(i) / kArcsec << " theory " << theory(i) / kArcsec);
    CHECK(std::fabs(phi(i) - theory(i)) < 0.05 * std::fabs(theory(i)));  // 5%
  }
}

TEST_CASE("pipeline counts and skips non-finite samples; float runs; no heap in steps") {
  const double dt = 0.05;
  const StaticImu<double> imu(kLat, 50.0, kAtt, dt);
  const StaticImu<float> imuf(kLat, 50.0, kAtt, dt);
  PipeRun<double, 15> run;
  run.setup(dt, 1200, 2);
  PipeRun<float, 12> runf;
  runf.setup(dt, 1200, 2);
  const Eigen::Vector3d nan3 = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  const Eigen::Vector3f nan3f = nan3.cast<float>();
  gyrodrift::test::AllocationScope scope;
  Eigen::internal::set_is_malloc_allowed(false);
  for (int k = 0; k < 6000; ++k) {
    if (k % 1000 == 500) {
      CHECK(run.pipe.step(nan3, imu.dv) == AlignStatus::kSkippedBad);
      CHECK(runf.pipe.step(imuf.dth, nan3f) == AlignStatus::kSkippedBad);
    }
    REQUIRE(run.pipe.step(imu.dth, imu.dv) != AlignStatus::kFailed);
    REQUIRE(runf.pipe.step(imuf.dth, imuf.dv) != AlignStatus::kFailed);
  }
  Eigen::internal::set_is_malloc_allowed(true);
  CHECK(scope.allocations() == 0);
  CHECK(run.pipe.bad_samples() == 6);
  CHECK(runf.pipe.bad_samples() == 6);
  CHECK(run.pipe.samples_used() == 6000);
  // Ideal data: double heading within 1 arcsec; float 12-state within 60 arcsec (float
  // rounding of the 1e-6-relative Earth-rate signal in coarse alignment, then KF-refined).
  const Eigen::Matrix3d c = euler2dcm<double>(kAtt);
  CHECK(misalignment<double>(q2dcm(run.pipe.nav().q()), c).cwiseAbs().maxCoeff() < 1.0 * kArcsec);
  const Eigen::Vector3f phif = misalignment<float>(q2dcm(runf.pipe.nav().q()), c.cast<float>());
  CHECK(phif.cwiseAbs().maxCoeff() < static_cast<float>(60 * kArcsec));
}

TEST_CASE("heading acquisition stage: no heap in steps, float and double, bad settings rejected") {
  const double dt = 0.05;
  const StaticImu<double> imu(kLat, 50.0, kAtt, dt);
  const StaticImu<float> imuf(kLat, 50.0, kAtt, dt);
  const double q_stage = std::pow(0.1 * kDeg, 2);
  PipeRun<double, 15> run;
  run.setup(dt, 1200, 2, 500, q_stage);
  PipeRun<float, 15> runf;
  runf.setup(dt, 1200, 2, 500, q_stage);
  gyrodrift::test::AllocationScope scope;
  Eigen::internal::set_is_malloc_allowed(false);
  double sigma_stage_end = 0.0;
  for (int k = 0; k < 6000; ++k) {
    REQUIRE(run.pipe.step(imu.dth, imu.dv) != AlignStatus::kFailed);
    REQUIRE(runf.pipe.step(imuf.dth, imuf.dv) != AlignStatus::kFailed);
    if (k == 1200 + 2 * 500 - 1) sigma_stage_end = std::sqrt(run.pipe.kf().P()(2, 2));
  }
  Eigen::internal::set_is_malloc_allowed(true);
  CHECK(scope.allocations() == 0);
  // The acquisition noise keeps the heading sigma open (> 0.1 deg after 50 s); after the
  // restart the small-angle filter converges as without the stage (ideal static data).
  CHECK(sigma_stage_end > 0.1 * kDeg);
  const Eigen::Matrix3d c = euler2dcm<double>(kAtt);
  CHECK(misalignment<double>(q2dcm(run.pipe.nav().q()), c).cwiseAbs().maxCoeff() < 5.0 * kArcsec);
  const Eigen::Vector3f phif = misalignment<float>(q2dcm(runf.pipe.nav().q()), c.cast<float>());
  CHECK(phif.cwiseAbs().maxCoeff() < static_cast<float>(60 * kArcsec));
  // Bad stage settings are rejected by reset().
  AlignPipeline<double, 15, 256, 32> bad;
  AlignSettings<double> s;
  s.heading_stage_cycles = -1;
  using VecN = AlignPipeline<double, 15>::VecN;
  const VecN ones = VecN::Ones();
  const Eigen::Vector3d r = Eigen::Vector3d::Ones();
  CHECK_FALSE(bad.reset(s, ones, ones, r, ones, nullptr, 0));
  s.heading_stage_cycles = 10;
  s.heading_stage_q = std::numeric_limits<double>::quiet_NaN();
  CHECK_FALSE(bad.reset(s, ones, ones, r, ones, nullptr, 0));
  s.heading_stage_q = 1e-8;
  CHECK(bad.reset(s, ones, ones, r, ones, nullptr, 0));
}
