#pragma once
// rtpack-bench: wall-clock helpers shared by its modes (never used in unit tests).
#include <algorithm>
#include <chrono>
#include <limits>

namespace rtp::bench {

using Clock = std::chrono::steady_clock;

inline double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// One warm-up run, then the best of `reps`.
template <class F>
double best_of(int reps, F&& f) {
  f();
  double best = std::numeric_limits<double>::infinity();
  for (int r = 0; r < reps; ++r) {
    const auto t0 = Clock::now();
    f();
    best = std::min(best, seconds_since(t0));
  }
  return best;
}

}  // namespace rtp::bench
