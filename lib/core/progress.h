#pragma once
// Progress on stderr for long work: stage, percent, ETA and peak resident memory (the same measure
// as the tools' summaries), redrawn in place — only when stderr is a terminal (never in logs or pipes;
// RTP_PROGRESS=1 in the environment forces it, one line per update, for tests), at most a few times a second.
#include <chrono>
#include <cstdint>
#include <string>

namespace rtp {

double peak_rss_mib();                  // getrusage max RSS
double current_rss_mib();               // /proc/self/statm
std::string human_bytes(double bytes);  // "512 B", "1.5 KiB", "2.3 MiB" ... (powers of 1024)

class Progress {
 public:
  explicit Progress(bool enabled);  // enabled && isatty(stderr)
  ~Progress();
  // Starts a stage (ends the previous line). counts = false: the stage's units are work estimates,
  // shown only as a percentage.
  void stage(const std::string& name, bool counts = true);
  void update(uint64_t done, uint64_t total);  // thread-safe enough: called from one thread
  void finish();                               // clears the line

 private:
  bool on_, lines_ = false, counts_ = true;
  std::string stage_;
  std::chrono::steady_clock::time_point start_, last_;
  bool drawn_ = false;
};

}  // namespace rtp
