// Cortex-M4F gate unit: the firmware IMU path in FLOAT. Serial bytes (42-byte frames built
// from volatile input, with a corrupted one and garbage in between) go through the
// resynchronising parser, each frame through ImuProcessor<float> (AR(2)-Kalman gyros,
// real-time db4 wavelet accelerometers, 64-sample window), and each output is encoded back
// into a frame. Also the CAN encoder/assembler and the SLCAN encoder/parser. No heap, no
// exceptions, no double arithmetic.
#include <gyrodrift/codecs/can_frames.hpp>
#include <gyrodrift/codecs/serial_frame.hpp>
#include <gyrodrift/codecs/slcan.hpp>
#include <gyrodrift/filters/realtime_wavelet.hpp>
#include <gyrodrift/imu/imu_processor.hpp>

#include "support.hpp"

namespace {

using Wavelet = gyrodrift::RealtimeWavelet<float, 64>;
using Processor = gyrodrift::ImuProcessor<float, Wavelet>;

gyrodrift::ImuConfig<float> make_config() noexcept {
  gyrodrift::ImuConfig<float> cfg;
  for (std::size_t c = 0; c < 3; ++c) {
    auto& cc = cfg.channels[c];
    cc.filter = gyrodrift::ChannelFilter::ar2_kalman;
    cc.model = gyrodrift::Ar2Model<float>{0.6868f, -0.0213f, 0.01f, 0.5f};  // paper 002 values
    cc.q = 0.01f;
    cc.r = 0.02f;
    // the shipped default configuration's detection (gyrodrift/imu/config_schema.hpp)
    cc.saturation = static_cast<float>(gyrodrift::config_schema::kDefaultGyroSaturationRadS);
    cc.stuck_samples = gyrodrift::config_schema::kDefaultGyroStuckSamples;
  }
  for (std::size_t c = 3; c < 6; ++c) cfg.channels[c].filter = gyrodrift::ChannelFilter::wavelet;
  return cfg;
}

// Static storage: six wavelet windows do not belong on an 8 KiB stack.
Processor processor(make_config(), Wavelet(gyrodrift::WaveletKind::db4, 3));
gyrodrift::serial::SerialFrameParser<128> parser;
gyrodrift::can::CanSampleAssembler<4> assembler(gyrodrift::can::kOutputBaseId);
gyrodrift::slcan::SlcanParser<> slcan_parser;

}  // namespace

extern "C" int app_main(void) {
  using gyrodrift::cortex_m::input;
  using gyrodrift::cortex_m::sink;
  namespace serial = gyrodrift::serial;
  if (processor.status() != gyrodrift::ImuStatus::ok) return 100;
  std::uint8_t wire[serial::kFrameSize];
  std::uint8_t out_wire[serial::kFrameSize];
  char line[gyrodrift::slcan::kMaxFrameLine];
  std::uint32_t outputs = 0;
  for (std::uint16_t k = 0; k < 300; ++k) {
    serial::ImuFrame in;
    in.seq = k;
    in.t_us = std::uint64_t{gyrodrift::kImuDefaultPeriodUs} * static_cast<std::uint64_t>(k);
    for (std::size_t c = 0; c < 6; ++c) in.values[c] = input(k + c);
    serial::encode_frame(in, wire, sizeof wire);
    if (k % 50 == 7) wire[20] ^= 0x5Au;  // a corrupted frame: dropped by its CRC
    parser.feed(wire, sizeof wire);
    if (k % 64 == 3) parser.feed(wire + 5, 9);  // garbage between frames
    serial::ImuFrame frame;
    while (parser.next(frame)) {
      gyrodrift::ImuSample<float> s;
      s.seq = frame.seq;
      s.t_us = frame.t_us;
      s.values = frame.values;
      gyrodrift::ImuOutput<float> y;
      if ((processor.step(s, y) & gyrodrift::kFlagRejected) != 0u) continue;
      serial::ImuFrame out;
      out.type = serial::kTypeOutput;
      out.seq = y.seq;
      out.flags = y.flags;
      out.t_us = y.t_us;
      out.values = y.values;
      serial::encode_frame(out, out_wire, sizeof out_wire);
      sink(static_cast<std::int32_t>(out_wire[40] | (out_wire[41] << 8)));
      // the same sample as CAN frames over SLCAN, parsed back and reassembled
      gyrodrift::can::CanSample cs;
      cs.seq = y.seq;
      cs.flags = y.flags;
      cs.values = y.values;
      std::array<gyrodrift::can::CanFrame, 4> frames{};
      gyrodrift::can::encode_sample(cs, gyrodrift::can::kOutputBaseId, frames);
      for (const auto& f : frames) {
        const std::size_t n = gyrodrift::slcan::encode_frame(f, line, sizeof line);
        gyrodrift::slcan::Event ev;
        for (std::size_t i = 0; i < n; ++i) {
          if (slcan_parser.push(static_cast<std::uint8_t>(line[i]), ev) &&
              ev.kind == gyrodrift::slcan::EventKind::kFrame) {
            gyrodrift::can::CanSample back;
            if (assembler.push(ev.frame, back)) sink(back.values[0] + back.values[5]);
          }
        }
      }
      ++outputs;
    }
  }
  const auto& h = processor.health();
  sink(static_cast<std::int32_t>(h.seq_gaps + parser.stats().crc_errors));
  // 300 frames, 6 corrupted (k % 50 == 7) -> 294 outputs; all reassembled from SLCAN.
  if (outputs != 294 || assembler.stats().complete_samples != 294) return 1;
  return 0;
}
