// The whole library: every area's umbrella header (stability is host code; firmware includes
// the areas or headers it needs).
#pragma once

#include "codecs.hpp"
#include "filters.hpp"
#include "imu.hpp"
#include "nav.hpp"
#include "stability.hpp"
