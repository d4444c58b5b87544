#pragma once
// Wall-clock seconds for the stage times the tools print (never used in unit tests).
#include <chrono>

namespace rtp {

using Clock = std::chrono::steady_clock;

inline double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

}  // namespace rtp
