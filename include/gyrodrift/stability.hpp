// Frequency stability: Allan, modified Allan, Hadamard and total variances (host code), and the
// streaming octave Allan variance (streaming_allan.hpp, also for the target) with its online
// noise estimates (online_noise.hpp), edf and chi-square quantiles (allan_chi2.hpp) and the
// expected Allan variance of noise models (model_allan.hpp).
#pragma once

#include "stability/allan.hpp"
#include "stability/allan_chi2.hpp"
#include "stability/deviation_blocked.hpp"
#include "stability/deviation_fused.hpp"
#include "stability/deviation_hadamard.hpp"
#include "stability/deviation_modified.hpp"
#include "stability/deviation_total.hpp"
#include "stability/model_allan.hpp"
#include "stability/online_noise.hpp"
#include "stability/compensated_sum.hpp"
#include "stability/streaming_allan.hpp"
