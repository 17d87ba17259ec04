// A sum carried as a renormalised pair sum + comp: the accumulator of the streaming Allan
// curve and of the lag statistics, which add 10^7 and more terms in float.
#pragma once

namespace gyrodrift {

// Compensated sum carried as a renormalised pair sum + comp (a "double-Scalar" accumulator):
// TwoSum of the running sum and the term, the error added to comp, then comp folded back
// into sum (Fast2Sum) so |comp| stays below half an ulp of sum. Plain Kahan/Neumaier leaves
// the lost parts in comp; with 10^7 terms below an ulp of the sum (squared differences of a
// float gyro record) comp grows to a fair part of the sum and is itself summed naively.
// Error: a few eps of Scalar on the total, independent of the term count.
template <class Scalar>
struct CompensatedSum {
  Scalar sum{0};
  Scalar comp{0};

  void add(Scalar x) noexcept {
    const Scalar t = sum + x;
    const Scalar xx = t - sum;
    const Scalar err = (sum - (t - xx)) + (x - xx);  // TwoSum: sum + x = t + err exactly
    const Scalar c = comp + err;
    sum = t + c;            // Fast2Sum (|t| >= |c|): renormalise
    comp = c - (sum - t);
  }
  Scalar value() const noexcept { return sum + comp; }
};

}  // namespace gyrodrift
