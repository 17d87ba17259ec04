// Drift filters: AR(2) model + Kalman filters, AR filter, real-time wavelet, drift likelihood,
// the whole-record lag statistics of the drift model and the fit from them.
#pragma once

#include "filters/ar2_kalman.hpp"
#include "filters/ar2_model.hpp"
#include "filters/ar2_steady_state.hpp"
#include "filters/ar_filter.hpp"
#include "filters/axis_bank.hpp"
#include "filters/drift_likelihood.hpp"
#include "filters/fir_prefilter.hpp"
#include "filters/input_range.hpp"
#include "filters/lag_drift_fit.hpp"
#include "filters/lag_drift_identifier.hpp"
#include "filters/lag_statistics.hpp"
#include "filters/lifting_transform.hpp"
#include "filters/online_drift_identifier.hpp"
#include "filters/shared_drift_identifier.hpp"
#include "filters/realtime_wavelet.hpp"
#include "filters/realtime_wavelet_noise.hpp"
#include "filters/realtime_wavelet_windows.hpp"
