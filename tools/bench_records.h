#pragma once
// rtpack-bench's default mode: one timed configuration's record, its table row and its JSON form
// (docs/json.md: "trace", "build" and "sah" records).
#include <cstdint>
#include <cstdio>
#include <string>

#include <nlohmann/json.hpp>

#include "bench_agreement.h"
#include "bvh/bvh.h"
#include "oracle/rays.h"
#include "trace/trace.h"

namespace rtp::bench {

// One (kind, W, order or packet, threads) timing: rtpack and Embree on the same rays, answers checked.
struct Record {
  RayKind kind;
  int width = 0;
  TraversalOrder order;
  uint32_t packet = 0;  // rays per packet (0: single rays)
  int threads = 0;
  // Embree on its faster path for these rays (the ratio's peer): 16-ray packets for primary rays; for the
  // others the faster of the rtcIntersect1M/rtcOccluded1M stream and one rtcIntersect1/rtcOccluded1 per ray.
  double rtpack_mrays = 0, embree_mrays = 0;
  double embree_stream_mrays = 0, embree_single_mrays = 0;  // both timed for incoherent rays (0: not timed)
  const char* embree_path = "stream";                       // "packet16", "stream" or "per-ray"
  double bytes_per_triangle = 0;
  Agreement agreement;
};

// One BVH build timing against an Embree HIGH build of the same triangles (--build-stats).
struct BuildRecord {
  int width = 0;
  int threads = 0;
  double rtpack_seconds = 0, embree_seconds = 0;
  double bytes_per_triangle = 0;
  uint64_t bvh_bytes = 0;
};

// The table row of a record, printed as its configuration finishes.
void print_row(FILE* o, const Record& r);

// hot_rays: --hot-rays (0: every ray distinct).
nlohmann::json trace_record_json(const Record& r, const KindData& k, const std::string& scene_path, Isa isa,
                                 const std::string& cpu, size_t hot_rays);
nlohmann::json build_record_json(const BuildRecord& b, const std::string& scene_path, const std::string& cpu);
nlohmann::json sah_record_json(const BvhStatsRow& r, const std::string& scene_path);

}  // namespace rtp::bench
