"""Wire codecs of the IMU loop: serial frames and CAN frames (DBC + cantools).

Python twins of include/gyrodrift/codecs/serial_frame.hpp and codecs/can_frames.hpp. SLCAN
needs no twin here: python-can's `slcan` interface is the Python peer of
include/gyrodrift/codecs/slcan.hpp.
"""

from __future__ import annotations

from .can_frames import (
    FRAMES_PER_SAMPLE,
    INPUT_BASE_ID,
    OUTPUT_BASE_ID,
    CanRxStats,
    CanSample,
    SampleAssembler,
    encode_sample,
    load_dbc,
)
from .serial_frame import (
    FRAME_DTYPE,
    FRAME_SIZE,
    TYPE_HEALTH_REPORT,
    TYPE_HEALTH_REQUEST,
    TYPE_INPUT,
    TYPE_OUTPUT,
    FrameError,
    FrameParser,
    ImuFrame,
    ParserStats,
    crc16_ccitt_false,
    decode_frame,
    encode_frame,
    encode_frames,
)

__all__ = [
    "FRAMES_PER_SAMPLE",
    "FRAME_DTYPE",
    "FRAME_SIZE",
    "INPUT_BASE_ID",
    "OUTPUT_BASE_ID",
    "TYPE_HEALTH_REPORT",
    "TYPE_HEALTH_REQUEST",
    "TYPE_INPUT",
    "TYPE_OUTPUT",
    "CanRxStats",
    "CanSample",
    "FrameError",
    "FrameParser",
    "ImuFrame",
    "ParserStats",
    "SampleAssembler",
    "crc16_ccitt_false",
    "decode_frame",
    "encode_frame",
    "encode_frames",
    "encode_sample",
    "load_dbc",
]
