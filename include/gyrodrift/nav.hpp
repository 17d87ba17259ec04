// Navigation: WGS-84 Earth model, attitude, strapdown, coarse and fine alignment (SINS).
#pragma once

#include "nav/align_pipeline.hpp"
#include "nav/attitude.hpp"
#include "nav/coarse_align.hpp"
#include "nav/earth.hpp"
#include "nav/fine_align_kf.hpp"
#include "nav/strapdown.hpp"
