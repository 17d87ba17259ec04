// Frequency stability: Allan, modified Allan, Hadamard and total variances (host code), and the
// streaming octave Allan variance (streaming_allan.hpp, also for the target).
#pragma once

#include "stability/allan.hpp"
#include "stability/deviation_blocked.hpp"
#include "stability/deviation_fused.hpp"
#include "stability/deviation_hadamard.hpp"
#include "stability/deviation_modified.hpp"
#include "stability/deviation_total.hpp"
#include "stability/streaming_allan.hpp"
