// Six-channel IMU processor (3 gyro + 3 accelerometer) of the fixed-rate navigation loop.
#pragma once

#include "imu/health_alarms.hpp"
#include "imu/imu_processor.hpp"
