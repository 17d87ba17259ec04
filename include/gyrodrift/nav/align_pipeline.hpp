// Whole SINS alignment of paper 004 per IMU sample: optional gyro prefilter (an FIR, e.g. the
// forced real-time wavelet's taps) with a matching accelerometer delay, inertial-frame coarse
// alignment, then strapdown mechanization + fine-alignment KF (zero-velocity updates every
// kf_every samples) with closed-loop feedback:
//   q <- q(phi) q  (C_true = (I + [phi x]) C_est),  v <- v - dv,  pos <- pos - dp,
//   eps_hat += eps, nabla_hat += nabla; later increments are corrected by eps_hat dt, nabla_hat dt.
// Prefilter timing: the wavelet FIR delays the gyro by its DC group delay (about 8.2 samples
// for db4/level 5/N = 256); accel_delay_samples = 8 delays the accelerometers to match, so the
// attitude used to project the specific force refers to the same instant, and the whole
// navigation solution then refers to accel_delay_samples earlier than the newest input.
// Warm-up: alignment starts only when the prefilter window and the delay line are full
// (max(n_taps - 1, delay) samples). Starting on the unfiltered pass-through samples and
// switching to the filtered (delayed) stream later would drop ~8 samples of angle increments
// at the switch, i.e. a permanent attitude error of 8 dt times the rocking rate (about
// 160 arcsec on the mild ship scenario).
// Heading acquisition (two-stage fine alignment): for the first heading_stage_cycles KF cycles
// the Up attitude process noise is q_diag(2) + heading_stage_q, so that after a coarse heading
// error of tens of degrees (1 m of sway in a 60 s coarse window) the small-angle filter keeps
// following the heading while the neglected sin/cos terms are large, instead of shrinking its
// heading variance on a wrong model; then it continues with q_diag. 0 cycles = off.
// Python reference: gyrodrift.align.pipeline.run_alignment_reference (same operations).
#pragma once
#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstddef>

#include "attitude.hpp"
#include "coarse_align.hpp"
#include "earth.hpp"
#include "fine_align_kf.hpp"
#include "strapdown.hpp"

namespace gyrodrift {

// Sliding-window FIR on three axes: y_k = sum_j h_j x_{k-n+1+j} (taps oldest first); the first
// n - 1 outputs are the raw input while the window fills (paper 004 sec. 2.2 step 1).
// Each sample is stored twice (at w and w + n) so the window is always contiguous.
template <class Scalar, int MaxTaps>
class FirPrefilter3 {
 public:
  using Vec3 = Eigen::Matrix<Scalar, 3, 1>;
  bool reset(const Scalar* taps, int n_taps) noexcept {
    if (n_taps < 0 || n_taps > MaxTaps || (n_taps > 0 && taps == nullptr)) return false;
    for (int j = 0; j < n_taps; ++j) {
      if (!std::isfinite(taps[j])) return false;
      taps_[static_cast<std::size_t>(j)] = taps[j];
    }
    n_ = n_taps;
    w_ = 0;
    count_ = 0;
    buf_.setZero();
    return true;
  }
  Vec3 step(const Vec3& x) noexcept {
    if (n_ == 0) return x;
    buf_.col(w_) = x;
    buf_.col(w_ + n_) = x;
    Vec3 y = x;
    if (count_ + 1 >= n_) {
      const Eigen::Map<const Eigen::Matrix<Scalar, 1, Eigen::Dynamic>> h(taps_.data(), n_);
      for (int i = 0; i < 3; ++i) y(i) = buf_.row(i).segment(w_ + 1, n_).dot(h);
    }
    if (count_ < n_) ++count_;
    w_ = (w_ + 1) % n_;
    return y;
  }
  int taps() const noexcept { return n_; }

 private:
  std::array<Scalar, static_cast<std::size_t>(MaxTaps)> taps_{};
  // Row-major so each axis' window is contiguous for the dot product.
  Eigen::Matrix<Scalar, 3, 2 * MaxTaps, Eigen::RowMajor> buf_ =
      Eigen::Matrix<Scalar, 3, 2 * MaxTaps, Eigen::RowMajor>::Zero();
  int n_{0};
  int w_{0};
  int count_{0};
};

template <class Scalar>
struct AlignSettings {
  Scalar dt_s{Scalar(0.0025)};
  Scalar lat_rad{Scalar(0)};
  Scalar lon_rad{Scalar(0)};
  Scalar h_m{Scalar(0)};
  long coarse_samples{24000};
  bool coarse_position_integral{true};
  int kf_every{40};
  int accel_delay_samples{0};
  long heading_stage_cycles{0};   // KF cycles with the acquisition noise (0 = off)
  Scalar heading_stage_q{Scalar(0)};  // added Up attitude process noise PSD, rad^2/s
};

enum class AlignStatus : int {
  kCoarse = 0,       // sample used by coarse alignment
  kCoarseDone = 1,   // coarse alignment finished at this sample, fine alignment starts
  kNavigate = 2,     // mechanization step, no KF update
  kKfUpdated = 3,    // KF predict + update + feedback done at this sample
  kSkippedBad = 4,   // non-finite sample: counted and skipped, state untouched
  kFailed = 5,       // coarse solve or KF numerics failed; the pipeline stops (see failed())
  kWarmup = 6,       // sample only fills the prefilter window / accelerometer delay line
};

template <class Scalar, int N, int MaxTaps = 256, int MaxDelay = 32>
class AlignPipeline {
 public:
  using Vec3 = Eigen::Matrix<Scalar, 3, 1>;
  using Mat3 = Eigen::Matrix<Scalar, 3, 3>;
  using VecN = Eigen::Matrix<Scalar, N, 1>;
  using Kf = FineAlignKF<Scalar, N>;

  // taps may be null with n_taps = 0 (no prefilter). Returns false on invalid settings.
  bool reset(const AlignSettings<Scalar>& s, const VecN& p0_diag, const VecN& q_diag,
             const Vec3& r_diag, const VecN& floor_diag, const Scalar* taps,
             int n_taps) noexcept {
    ok_ = false;
    if (s.kf_every < 1 || s.accel_delay_samples < 0 || s.accel_delay_samples > MaxDelay) return false;
    if (s.heading_stage_cycles < 0 || !std::isfinite(s.heading_stage_q) ||
        s.heading_stage_q < Scalar(0))
      return false;
    if (!coarse_.reset(s.coarse_samples, s.dt_s, s.lat_rad, s.h_m, s.coarse_position_integral))
      return false;
    if (!prefilter_.reset(taps, n_taps)) return false;
    if (!kf_.reset(p0_diag, q_diag, r_diag, floor_diag)) return false;
    s_ = s;
    p0_ = p0_diag;
    q_ = q_diag;
    q_stage_ = q_diag;
    q_stage_(2) += s.heading_stage_q;
    cycles_ = 0;
    r_ = r_diag;
    floor_ = floor_diag;
    k_ = 0;
    warmup_ = n_taps > 0 ? (n_taps - 1 > s.accel_delay_samples ? n_taps - 1 : s.accel_delay_samples)
                         : s.accel_delay_samples;
    bad_ = 0;
    count_ = 0;
    dvn_sum_.setZero();
    eb_.setZero();
    db_.setZero();
    coarse_cnb_.setIdentity();
    failed_ = false;
    ok_ = true;
    return true;
  }

  AlignStatus step(const Vec3& dth_raw, const Vec3& dv_raw) noexcept {
    if (!ok_ || failed_) return AlignStatus::kFailed;
    if (!dth_raw.allFinite() || !dv_raw.allFinite()) {
      ++bad_;
      return AlignStatus::kSkippedBad;
    }
    const Vec3 g = prefilter_.step(dth_raw);
    const Vec3 a = delay(dv_raw);
    const long k = k_++ - warmup_;
    if (k < 0) return AlignStatus::kWarmup;
    if (k < s_.coarse_samples) {
      coarse_.add(g, a);
      if (!coarse_.complete()) return AlignStatus::kCoarse;
      if (!coarse_.solve(coarse_cnb_)) {
        failed_ = true;
        return AlignStatus::kFailed;
      }
      Vec3 pos(s_.lat_rad, s_.lon_rad, s_.h_m);
      sd_.reset(dcm2q(coarse_cnb_), Vec3::Zero(), pos);
      kf_.reset(p0_, q_, r_, floor_);
      return AlignStatus::kCoarseDone;
    }
    Vec3 dvn;
    if (!sd_.step(Vec3(g - eb_ * s_.dt_s), Vec3(a - db_ * s_.dt_s), s_.dt_s, dvn)) {
      failed_ = true;
      return AlignStatus::kFailed;
    }
    dvn_sum_ += dvn;
    if (++count_ < s_.kf_every) return AlignStatus::kNavigate;
    const Scalar t_kf = static_cast<Scalar>(count_) * s_.dt_s;
    const Vec3 fn = dvn_sum_ / t_kf;
    EarthParams<Scalar> ep;
    ep.update(sd_.pos()(0), sd_.pos()(2), sd_.vn());
    Kf::transition(q2dcm(sd_.q()), fn, ep, sd_.pos()(0), f_);
    if (s_.heading_stage_cycles > 0 && cycles_ == s_.heading_stage_cycles) {
      // End of acquisition: drift/bias estimates learnt while the small-angle model was wrong
      // (a heading error psi leaks into eps_E as W cos L sin psi) are discarded and the
      // small-angle filter restarts from P0 around the acquired attitude.
      kf_.reset(p0_, q_, r_, floor_);
      eb_.setZero();
      db_.setZero();
    }
    kf_.set_process_noise(cycles_ < s_.heading_stage_cycles ? q_stage_ : q_);  // validated in reset
    ++cycles_;
    if (!kf_.predict(f_, t_kf) || !kf_.update(sd_.vn())) {
      failed_ = true;
      return AlignStatus::kFailed;
    }
    const VecN& x = kf_.x();
    sd_.q_mut() = qnormalize(qmul(rv2q<Scalar>(x.template segment<3>(0)), sd_.q()));
    sd_.vn_mut() -= x.template segment<3>(3);
    if constexpr (N == 15) {
      Vec3 dpos(x(7) / ep.rm_h_m, x(6) / (ep.rn_h_m * std::cos(sd_.pos()(0))), x(8));
      sd_.pos_mut() -= dpos;
    }
    eb_ += x.template segment<3>(Kf::kEb);
    db_ += x.template segment<3>(Kf::kDb);
    dvn_sum_.setZero();
    count_ = 0;
    return AlignStatus::kKfUpdated;
  }

  Vec3 attitude() const noexcept { return dcm2euler(q2dcm(sd_.q())); }  // pitch, roll, yaw
  const Strapdown<Scalar>& nav() const noexcept { return sd_; }
  const Kf& kf() const noexcept { return kf_; }
  const Vec3& gyro_drift() const noexcept { return eb_; }
  const Vec3& accel_bias() const noexcept { return db_; }
  const Mat3& coarse_cnb() const noexcept { return coarse_cnb_; }
  long samples_used() const noexcept { return k_; }
  long warmup_samples() const noexcept { return warmup_; }
  long bad_samples() const noexcept { return bad_; }
  bool failed() const noexcept { return failed_; }

 private:
  Vec3 delay(const Vec3& dv) noexcept {
    const int d = s_.accel_delay_samples;
    if (d == 0) return dv;
    const auto slot = static_cast<int>(k_ % d);
    const Vec3 out = (k_ >= d) ? Vec3(ring_.col(slot)) : dv;
    ring_.col(slot) = dv;
    return out;
  }

  AlignSettings<Scalar> s_;
  FirPrefilter3<Scalar, MaxTaps> prefilter_;
  Eigen::Matrix<Scalar, 3, MaxDelay> ring_ = Eigen::Matrix<Scalar, 3, MaxDelay>::Zero();
  InertialCoarseAlign<Scalar> coarse_;
  Strapdown<Scalar> sd_;
  Kf kf_;
  typename Kf::MatN f_;  // transition matrix workspace (a member: keeps step()'s frame small)
  VecN p0_, q_, q_stage_, floor_;
  Vec3 r_;
  Vec3 dvn_sum_ = Vec3::Zero();
  Vec3 eb_ = Vec3::Zero();
  Vec3 db_ = Vec3::Zero();
  Mat3 coarse_cnb_ = Mat3::Identity();
  long k_{0};
  long warmup_{0};
  long bad_{0};
  long cycles_{0};  // KF cycles since the start of fine alignment
  int count_{0};
  bool ok_{false};
  bool failed_{false};
};

}  // namespace gyrodrift
