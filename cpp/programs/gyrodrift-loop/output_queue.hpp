// The loop's output queue: a fixed-capacity byte buffer written out non-blocking, that also
// accounts for whole output frames. A frame counts as written only when its last byte has
// been accepted by the device; at exit the frames still (partly) queued are dropped and
// counted, so that  frames_queued = frames_written + frames_dropped  holds exactly
// (a frame used to count as sent when it was queued).
#pragma once
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstring>

namespace gyrodrift::loop {

// Capacity bytes; at most MaxFrames frames queued at once (each frame is >= Capacity /
// MaxFrames bytes for the queue to fill by bytes first).
template <std::size_t Capacity, std::size_t MaxFrames>
struct OutQueue {
  std::array<std::uint8_t, Capacity> buf{};
  std::size_t head = 0;
  std::size_t tail = 0;
  // Frame boundaries as cumulative byte offsets (end of each queued frame), a ring.
  std::array<std::uint64_t, MaxFrames> frame_end{};
  std::size_t f_head = 0;
  std::size_t f_count = 0;
  std::uint64_t appended_bytes = 0;  // cumulative
  std::uint64_t written_bytes = 0;   // cumulative
  std::uint64_t frames_queued = 0;
  std::uint64_t frames_written = 0;
  std::uint64_t frames_dropped = 0;  // queued but never (fully) written: counted by drop_pending()

  std::size_t pending() const noexcept { return tail - head; }
  std::size_t room() const noexcept { return Capacity - pending(); }
  std::size_t frames_pending() const noexcept { return f_count; }

  // Appends n bytes; `frame` marks them as one output frame (else e.g. an SLCAN reply).
  // False (nothing appended) if they do not fit.
  bool append(const void* p, std::size_t n, bool frame) noexcept {
    if (n > room() || (frame && f_count == MaxFrames)) return false;
    if (n > Capacity - tail) {
      std::memmove(buf.data(), buf.data() + head, pending());
      tail -= head;
      head = 0;
    }
    std::memcpy(buf.data() + tail, p, n);
    tail += n;
    appended_bytes += n;
    if (frame) {
      frame_end[(f_head + f_count) % MaxFrames] = appended_bytes;
      ++f_count;
      ++frames_queued;
    }
    return true;
  }

  // Writes what the device takes now. Returns false on a hard write error (errno set).
  bool flush(int fd, std::uint64_t& bytes_out) noexcept {
    bool ok = true;
    while (pending() > 0) {
      const ssize_t w = write(fd, buf.data() + head, pending());
      if (w > 0) {
        head += static_cast<std::size_t>(w);
        bytes_out += static_cast<std::uint64_t>(w);
        written_bytes += static_cast<std::uint64_t>(w);
        continue;
      }
      if (w < 0 && errno == EINTR) continue;
      if (w < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
      ok = false;
      break;
    }
    while (f_count > 0 && frame_end[f_head] <= written_bytes) {
      ++frames_written;
      f_head = (f_head + 1) % MaxFrames;
      --f_count;
    }
    if (head == tail) head = tail = 0;
    return ok;
  }

  // At exit: everything still queued is dropped (a partly written frame counts as dropped).
  void drop_pending() noexcept {
    frames_dropped += f_count;
    f_count = 0;
    f_head = 0;
    head = tail = 0;
  }
};

}  // namespace gyrodrift::loop
