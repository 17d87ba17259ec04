// Six-channel IMU processor (3 gyro + 3 accelerometer) of the fixed-rate navigation loop, and
// the on-target monitor of its gyro channels.
#pragma once

#include "imu/gyro_monitor.hpp"
#include "imu/health_alarms.hpp"
#include "imu/imu_processor.hpp"
