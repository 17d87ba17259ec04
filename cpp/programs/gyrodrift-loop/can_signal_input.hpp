// gyrodrift-loop --can-signals FILE: input CAN frames decoded through a user's DBC, by the
// table python/gyrodrift/codecs/can_signals.py generates from it (decode_table_text) and
// include/gyrodrift/codecs/can_signal_decode.hpp reads. Self-contained so the loop's main needs
// only a load at start-up, one branch where a CAN frame arrives, and its counters in the JSON.
// The file is read once before the loop starts (stdio, no allocation after that).
#pragma once
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <gyrodrift/codecs/can_signal_decode.hpp>
#include <string>

namespace gyrodrift::loop {

class UserCanInput {
 public:
  bool active() const noexcept { return active_; }

  // Reads and checks the whole table; on failure `error` names the file, line and column.
  bool load(const std::string& path, std::string& error) {
    std::FILE* f = std::fopen(path.c_str(), "r");
    if (f == nullptr) {
      error = "--can-signals " + path + ": " + std::strerror(errno);
      return false;
    }
    char line[512];
    int line_no = 0;
    bool ok = true;
    while (ok && std::fgets(line, sizeof line, f) != nullptr) {
      ++line_no;
      if (std::strchr(line, '\n') == nullptr && !std::feof(f)) {
        error = path + ":" + std::to_string(line_no) + ": line too long";
        ok = false;
        break;
      }
      can::SignalEntry e;
      can::PageSet pages;
      const char* what = "";
      const can::LineResult r = can::parse_table_line(line, e, pages, &what);
      if (r == can::LineResult::kError) {
        error = path + ":" + std::to_string(line_no) + ": bad " + what;
        ok = false;
      } else if (r == can::LineResult::kPages && !table_.add_pages(pages)) {
        error = path + ":" + std::to_string(line_no) + ": pages of one message given twice";
        ok = false;
      } else if (r == can::LineResult::kEntry && !table_.add(e)) {
        error = path + ":" + std::to_string(line_no) + ": role mapped twice";
        ok = false;
      }
    }
    std::fclose(f);
    if (ok && !table_.complete()) {
      error = path + ": not all six channels (gx gy gz ax ay az) are mapped";
      ok = false;
    }
    active_ = ok;
    return ok;
  }

  bool push(const can::CanFrame& f, can::SignalSample& out) noexcept {
    return assembler_.push(f, out);
  }
  void finish() noexcept { assembler_.finish(); }
  const can::SignalRxStats& stats() const noexcept { return assembler_.stats(); }
  std::uint64_t pending_frames() const noexcept { return assembler_.pending_frames(); }

 private:
  can::SignalTable<> table_{};
  can::SignalSampleAssembler<> assembler_{table_};  // refers to table_ (declared first)
  bool active_ = false;
};

}  // namespace gyrodrift::loop
