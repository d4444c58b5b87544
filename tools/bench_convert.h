#pragma once
// rtpack-bench --convert: the converter pipeline (as rtpack-convert runs it) timed stage by stage
// against an Embree 3 HIGH build of the same prepared triangles and instances, in the same process.
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "package/write_package.h"  // kDefaultZstdLevel

namespace rtp::bench {

struct ConvertBenchConfig {
  std::string scene_path;
  std::vector<std::string> allow_paths;  // --allow-path
  std::string output;                    // --convert-output: keep the package there (else a temporary file, deleted)
  int bvh_width = 8;                     // leaf width = W, 8 for W = 16 (rtpack-convert's default)
  int zstd_level = kDefaultZstdLevel;
  bool zstd_raw_literals = true;                   // --zstd-huffman-literals: false
  int zstd_leaf_min_match = kDefaultLeafMinMatch;  // --zstd-leaf-min-match
  uint64_t chunk_target = 0;                       // 0 = derived from the scene
  bool dag = true;                                 // --no-dag: false (no culling DAGs, as rtpack-convert --no-dag)
  int threads = 0;                                 // 0 = all hardware threads
  int reps = 3;                                    // best of reps after one warm-up (convert and Embree alike)
  bool json = false;
};

// Runs the benchmark; prints the table (stdout, or stderr when --json puts the record on stdout).
// Throws rtp::Error like the converter (the caller names the input in the message).
int run_convert_bench(const ConvertBenchConfig& cfg);

// The CPU's model name from /proc/cpuinfo ("unknown" when absent), for bench records.
std::string cpu_model();

// The JSON document of one rtpack-bench mode run (--multi-hit, --packets): the tool's stamp, the scene,
// this CPU, the ISA name, threads (0 = all), reps and the mode's records.
nlohmann::json mode_run_json(const std::string& scene, const char* isa, int threads, int reps, nlohmann::json records);

}  // namespace rtp::bench
