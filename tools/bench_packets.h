#pragma once
// rtpack-bench SCENE --packets 0,4,8,16: coherent ray packets (Wu 2016) against single rays and against
// Embree 3's 16-ray packets, same rays, same run, at the default width (W = B = 8). Primary rays come
// in 4x4 pixel tiles (oracle/rays.h), so packets of 4, 8 and 16 consecutive rays are 4x1, 4x2 and 4x4
// tiles. Prints Mrays/s, the ratio to Embree, SIMD utilization (active rays per packet node test / P,
// Wu 2016 §4.2.1) and the share of rays traced in packets; every packet answer must equal the
// single-ray answer bit for bit, and the single-ray answers must agree with Embree ray by ray.
#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "bench_mode.h"

namespace rtp::bench {

struct PacketBenchConfig : ModeConfig {
  PacketBenchConfig() { kinds = {RayKind::kPrimary}; }
  std::string sizes_text;  // --packets as given
  std::vector<uint32_t> sizes;
};

// Registers --packets LIST (returned, for the caller's excludes).
CLI::Option* add_packet_options(CLI::App& app, PacketBenchConfig& cfg);

// Prints the table (stdout, or stderr with --json and the records on stdout). Returns kInternal when a
// packet answer differs from the single-ray one or rtpack disagrees with Embree; throws Error(kUsage)
// for a bad list.
int run_packet_bench(PacketBenchConfig cfg);

}  // namespace rtp::bench
