#pragma once
// Scene + batching-point plan -> .rtp package (formats/SPEC.md §4). Chunks are built in parallel and
// written in order as they complete (memory bounded by the chunks in flight), so the bytes are the
// same for any thread count.
#include <cstdint>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "bvh/bvh.h"
#include "cluster/cluster.h"
#include "voxel/point_voxels.h"

namespace rtp {

// The default zstd level of every chunk: the least convert + load + read-at-100-MB/s time over
// FlightHelmet and forest-2k (docs/package/zstd.md); level 1 converts 3 % faster than the tied level 2
// (docs/notes/2026-12-07-writer-measurements.md §1).
inline constexpr int kDefaultZstdLevel = 1;
// zstd's shortest match in the leaf-block chunks (ConvertOptions::zstd_leaf_min_match), zstd's longest
// choice: decompressed 1.5x faster than level 3's own 5 on unique-50m's points (1941 vs 1311 MB/s;
// docs/notes/2026-12-07-writer-measurements.md §2).
inline constexpr int kDefaultLeafMinMatch = 7;
// Batching points of instances only, at least this many, cull by their instance boxes instead of voxels
// (formats/dag.h kDagBoxes; write_package.cpp says why).
inline constexpr size_t kBoxProxyMinInstances = 64;

struct ConvertOptions {
  int width = 8;       // W: 4, 8 or 16
  int leaf_width = 8;  // B: 4, 8 or 16 (combinations: see supported_widths())
  BuildOptions bvh;
  int zstd_level = kDefaultZstdLevel;
  // Batching points and mesh segments (the chunks read while tracing) whose leaf blocks are more than
  // half their bytes are compressed with zstd's literals left raw, not Huffman-coded: 1.4x faster to
  // decompress for 4 % more bytes (docs/notes/2026-12-07-writer-measurements.md §3). Chunks of instance
  // BVHs and records keep Huffman literals. --zstd-huffman-literals turns it off everywhere.
  bool zstd_raw_literals = true;
  // The same chunks' shortest zstd match (3..7; 0: the level's own: level 3's 5, level 2's 5 or 6 by
  // chunk size): 16 % more bytes in them than level 3's 5, decompressed 1.5x faster (kDefaultLeafMinMatch,
  // measured at level 3). --zstd-leaf-min-match 0 restores the level's.
  int zstd_leaf_min_match = kDefaultLeafMinMatch;
  bool dag = true;                                     // store a culling DAG per batching point (--no-dag: none)
  voxel::VoxelOptions voxel;                           // resolution (0 = per point), thin (tests only)
  nlohmann::json metadata = nlohmann::json::object();  // merged into the metadata chunk
  // Called from the writing thread after each chunk: (chunks written, chunks total).
  std::function<void(uint64_t, uint64_t)> progress;
};

struct SectionBytes {
  uint64_t chunks = 0, raw = 0, stored = 0;
};

struct ConvertReport {
  uint64_t package_bytes = 0;
  uint64_t chunks = 0;
  std::map<std::string, SectionBytes> by_kind;  // "mesh segment", "batching point", "metadata", ...
  uint64_t node_bytes = 0, block_bytes = 0;     // raw BVH bytes over all chunks
  uint64_t unique_triangles = 0;                // triangles stored (pieces + segment meshes)
  // Culling DAGs (0 without): pool bytes, the sum of each point's DAG built alone, set cells, and the
  // resolution of every batching point.
  uint64_t dag_pool_bytes = 0, dag_separate_bytes = 0, dag_set_cells = 0;
  std::map<uint32_t, uint64_t> dag_resolutions;  // resolution -> batching points culled by voxels
  uint64_t box_points = 0, box_node_bytes = 0;   // points culled by their instance boxes (7.0), their nodes' raw bytes
  double voxelize_seconds = 0;                   // summed over threads
};

// True for the (W, B) pairs the kernels are built for: (4,4) (8,8) (16,16) (8,4) (16,8).
bool supported_widths(int width, int leaf_width);

// Writes `path` atomically; throws rtp::Error (kOutput for I/O, kInputInvalid for format limits).
ConvertReport write_package(const Scene& scene, const Plan& plan, const std::string& path, const ConvertOptions& options);

}  // namespace rtp
