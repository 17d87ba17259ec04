// AR filter (paper 000 sec. 2.1): remove the one-step residual r_k of eq. (1) from y_k, i.e.
// output the one-step AR(2) prediction plus the mean:
//   out_k = y_k - r_k = m + a1 (y_{k-1} - m) + a2 (y_{k-2} - m).
// The two samples before the first are taken as the mean (zero deviation, like X_0 = 0 of the
// Kalman filter), so out_0 = m and out_1 = m + a1 (y_0 - m). A NaN/Inf sample is replaced by
// its own prediction in the history (and counted), so one bad sample cannot poison the output;
// so is a finite sample beyond filter_input_limit() (input_range.hpp), which would overflow
// the prediction. A model whose mean is beyond that limit is refused (bad_argument).
#pragma once

#include <cmath>
#include <cstdint>

#include "ar2_model.hpp"
#include "input_range.hpp"

namespace gyrodrift {

template <class Scalar>
class ArFilter {
 public:
  explicit ArFilter(const Ar2Model<Scalar>& model) noexcept
      : a1_(model.a1), a2_(model.a2), mean_(model.mean),
        status_(std::isfinite(model.a1) && std::isfinite(model.a2) && std::isfinite(model.mean)
                    ? (!ar2_is_stationary(model.a1, model.a2) ? Ar2Status::non_stationary
                       : filter_input_ok(model.mean)          ? Ar2Status::ok
                                                              : Ar2Status::bad_argument)
                    : Ar2Status::non_finite) {}

  Scalar step(Scalar y) noexcept {
    if (status_ != Ar2Status::ok) return y;
    const Scalar pred = a1_ * d1_ + a2_ * d2_;  // demeaned one-step prediction
    Scalar d = y - mean_;
    if (!filter_input_ok(d)) {  // NaN, Inf or out of range
      ++faults_;
      d = pred;
    }
    d2_ = d1_;
    d1_ = d;
    return pred + mean_;
  }

  void reset() noexcept {
    d1_ = Scalar(0);
    d2_ = Scalar(0);
    faults_ = 0;
  }

  std::uint32_t fault_count() const noexcept { return faults_; }
  Ar2Status status() const noexcept { return status_; }

 private:
  Scalar a1_, a2_, mean_;
  Ar2Status status_;
  Scalar d1_ = Scalar(0), d2_ = Scalar(0);  // y_{k-1} - m, y_{k-2} - m
  std::uint32_t faults_ = 0;
};

}  // namespace gyrodrift
