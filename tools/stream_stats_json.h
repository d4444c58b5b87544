#pragma once
// A ray stream's counters (rtpack::StreamStats) as JSON, as rtpack-trace --path-trace and rtpack-bench
// --kinds path print them.
#include <nlohmann/json.hpp>

#include "rtpack/rtpack.h"

namespace rtp::tools {

inline nlohmann::json stream_stats_json(const rtpack::StreamStats& s) {
  return {{"rays", s.rays},
          {"rounds", s.rounds},
          {"passes", s.passes},
          {"batching_point_visits", s.batching_point_visits},
          {"culled_visits", s.culled_visits},
          {"dag_tests", s.dag_tests},
          {"chunks_loaded", s.chunks_loaded},
          {"bytes_read", s.bytes_read},
          {"raw_bytes_loaded", s.raw_bytes_loaded},
          {"peak_resident_bytes", s.peak_resident_bytes},
          {"seconds", s.seconds},
          {"load_seconds", s.load_seconds},
          {"trace_seconds", s.trace_seconds},
          {"walk_seconds", s.walk_seconds}};
}

}  // namespace rtp::tools
