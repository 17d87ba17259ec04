// The AR(2) filter/identification doctests again under AddressSanitizer + UBSan (built when
// GYRODRIFT_SANITIZE=ON): out-of-range reads in the buffer passes, signed overflow, etc.
#include "test_ar2_kalman.cpp"
