// Wire codecs of the IMU loop: serial frame with CRC-16, CAN frames, DBC signal decoding, SLCAN.
#pragma once

#include "codecs/can_frames.hpp"
#include "codecs/can_signal_decode.hpp"
#include "codecs/crc16.hpp"
#include "codecs/serial_frame.hpp"
#include "codecs/slcan.hpp"
