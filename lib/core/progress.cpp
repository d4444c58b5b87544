#include "core/progress.h"

#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <fstream>

namespace rtp {

double peak_rss_mib() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return double(ru.ru_maxrss) / 1024.0;
}

double current_rss_mib() {
  std::ifstream f("/proc/self/statm");
  uint64_t size = 0, resident = 0;
  f >> size >> resident;
  return double(resident) * double(sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
}

namespace {
bool forced() {
  const char* v = std::getenv("RTP_PROGRESS");
  return v && std::string(v) == "1";
}
}  // namespace

Progress::Progress(bool enabled) : on_(enabled && (isatty(STDERR_FILENO) || forced())), lines_(enabled && forced()) {}
Progress::~Progress() { finish(); }

void Progress::stage(const std::string& name, bool counts) {
  finish();
  stage_ = name;
  counts_ = counts;
  start_ = last_ = std::chrono::steady_clock::now();
  if (on_) {
    std::fprintf(stderr, lines_ ? "%s ...\n" : "\r\033[K%s ...", stage_.c_str());
    drawn_ = !lines_;
  }
}

void Progress::update(uint64_t done, uint64_t total) {
  if (!on_ || total == 0) return;
  const auto now = std::chrono::steady_clock::now();
  if (done < total && now - last_ < std::chrono::milliseconds(200)) return;
  last_ = now;
  const double el = std::chrono::duration<double>(now - start_).count();
  const double frac = double(done) / double(total);
  const double eta = frac > 0 ? el * (1 - frac) / frac : 0;
  char counts[64] = "";
  if (counts_)
    std::snprintf(counts, sizeof counts, "  %llu/%llu", static_cast<unsigned long long>(done),
                  static_cast<unsigned long long>(total));
  std::fprintf(stderr, "%s%s %5.1f%%%s  ETA %.0f s  peak RSS %.0f MiB%s", lines_ ? "" : "\r\033[K", stage_.c_str(), 100 * frac,
               counts, eta, peak_rss_mib(), lines_ ? "\n" : "");
  drawn_ = !lines_;
}

void Progress::finish() {
  if (on_ && drawn_) std::fprintf(stderr, "\r\033[K");
  drawn_ = false;
}

std::string human_bytes(double bytes) {
  const char* unit[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (bytes >= 1024 && u < 4) bytes /= 1024, ++u;
  char b[32];
  std::snprintf(b, sizeof b, u ? "%.1f %s" : "%.0f %s", bytes, unit[u]);
  return b;
}

}  // namespace rtp
