#pragma once
// Mesh preparation of a whole Scene: clean every mesh, then optional subdivision (uniform or to a
// world-space edge length). One entry point for the tools.
#include <nlohmann/json.hpp>
#include <string>

#include "mesh/mesh.h"

namespace rtp {

struct PrepareOptions {
  CleanOptions clean;
  int subdivide_levels = 0;  // uniform Loop levels (--subdivide N)
  double subdivide_to = 0;   // > 0: adaptive, longest world edge below this (--subdivide-to LENGTH)
  int subdivide_max_levels = 6;
  // Memory a uniform subdivision may need, in bytes; 0 = this machine's (machine_memory_bytes()).
  uint64_t memory_bytes = 0;
};

// Physical memory, or the cgroup's (v2 memory.max) when that is lower; 0 when unknown.
uint64_t machine_memory_bytes();

struct PrepareReport {
  CleanReport clean;            // summed over meshes
  uint64_t meshes_emptied = 0;  // meshes with no triangle left after cleaning (dropped with their instances)
  int uniform_levels = 0;
  uint64_t uniform_fallbacks = 0;  // meshes where OpenSubdiv refused the topology (midpoint split used)
  bool adaptive = false;
  SubdivideReport subdivide;                           // adaptive mode only
  uint64_t triangles_before = 0, triangles_after = 0;  // unique triangles
};

// Cleans, subdivides, drops emptied meshes (and their instances, with a warning in scene.warnings)
// and recomputes the exact world bounds when the geometry changed. A uniform subdivision whose
// refined meshes would need more than options.memory_bytes (kSubdivideBytesPerTriangle each) is
// refused with Error(kUsage) before any work.
PrepareReport prepare_scene(Scene& scene, const PrepareOptions& options);

nlohmann::json prepare_report_json(const PrepareReport& report);
std::string prepare_report_text(const PrepareReport& report);

}  // namespace rtp
