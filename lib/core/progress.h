#pragma once
// Progress on stderr for long work: stage, percent, ETA and resident memory, redrawn in place —
// only when stderr is a terminal (never in logs or pipes), at most a few times a second.
#include <chrono>
#include <cstdint>
#include <string>

namespace rtp {

double peak_rss_mib();     // getrusage max RSS
double current_rss_mib();  // /proc/self/statm
std::string human_bytes(double bytes);  // "512 B", "1.5 KiB", "2.3 MiB" ... (powers of 1024)

class Progress {
 public:
  explicit Progress(bool enabled);  // enabled && isatty(stderr)
  ~Progress();
  void stage(const std::string& name);            // starts a stage (ends the previous line)
  void update(uint64_t done, uint64_t total);     // thread-safe enough: called from one thread
  void finish();                                  // clears the line

 private:
  bool on_;
  std::string stage_;
  std::chrono::steady_clock::time_point start_, last_;
  bool drawn_ = false;
};

}  // namespace rtp
