#pragma once
// The whole conversion as one call, used by rtpack-convert and rtpack-bench --convert alike:
// import (lib/scene) -> preparation (lib/mesh) -> batching points (lib/cluster) -> chunks
// (write_package). The metadata chunk is built here from the settings, so every caller writes the
// same bytes for the same settings, at any thread count.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "cluster/cluster.h"
#include "mesh/prepare.h"
#include "package/write_package.h"
#include "scene/scene.h"

namespace rtp {

// rtpack-convert's options, with its defaults.
struct ConvertSettings {
  std::string input, output;                       // output is ignored with dry_run
  int scene = -1;                                  // glTF scene; -1: the file's default
  std::vector<std::string> allow_paths;            // further directories for external buffers
  std::vector<std::string> attributes;             // "normal", "uv": stored as per-chunk streams
  double weld = -1;                                // < 0: no welding
  int subdivide = 0;                               // uniform Loop levels
  double subdivide_to = 0;                         // > 0: adaptive, longest world edge below this
  int width = 8, leaf_width = 0;                   // leaf_width 0: W (8 for W = 16)
  std::string bvh_build = "collapse";              // or "split"
  uint64_t chunk_target = 0;                       // 0: derived from the scene
  std::string chunk_by = "instanced";              // or "unique"
  int zstd_level = kDefaultZstdLevel;              // 0 = store
  bool zstd_raw_literals = true;                   // ConvertOptions::zstd_raw_literals
  int zstd_leaf_min_match = kDefaultLeafMinMatch;  // ConvertOptions::zstd_leaf_min_match
  bool dag = true;                                 // culling DAGs
  uint32_t dag_resolution = 0;                     // 0: per batching point
  bool dry_run = false;                            // stop after preparation
  bool topology = false;                           // CleanOptions::topology (OpenMesh half-edge analysis; report only)
};

// The caller's view while it runs: a stage starts (counts = false: progress in work units, not items),
// progress within it, and the prepared scene (warnings) before the long stages.
struct ConvertHooks {
  std::function<void(const std::string& stage, bool counts)> stage;
  std::function<void(uint64_t done, uint64_t total)> progress;
  std::function<void(const Scene& scene, const PrepareReport& report)> prepared;
};

struct StageCost {
  double seconds = 0;
  double peak_rss_mib = 0;  // peak RSS of the process when the stage ended
};

struct ConvertOutcome {
  Scene scene;
  PrepareReport prepare;
  Plan plan;             // empty with dry_run
  ConvertReport report;  // empty with dry_run
  StageCost import_cost, prepare_cost, plan_cost, chunks_cost;
  double total_seconds() const { return import_cost.seconds + prepare_cost.seconds + plan_cost.seconds + chunks_cost.seconds; }
};

// Throws rtp::Error (kUsage for an unsupported W/B pair, else as the stages do).
ConvertOutcome convert_scene(const ConvertSettings& settings, const ConvertHooks& hooks = {});

}  // namespace rtp
