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

// The default zstd level of every chunk, chosen by docs/package/zstd.md (scripts/chart-zstd): the level
// with the least time to make a package and read it once from a 100 MB/s disk (convert + load + bytes /
// 100 MB/s) over FlightHelmet and forest-2k, times within 3 % of the least counting as a tie that the
// faster convert wins (the convert has its own bound: at most 3x an Embree HIGH build). Levels 1 and 2
// tie (their order flips between runs); level 1 (zstd 1.5's fast matcher with a 2^14-entry hash table;
// level 2 the same matcher with 2^16, level 3 double-fast) converts 3 % faster over the two scenes
// (0.203 against 0.210 s, one thread; FlightHelmet's leaf-block chunks 8.8 against 10.8 ms, forest-1m's
// 340 MB of chunks 1.02 against 1.28 s) and stores 2.0 % more. Levels 6 and 9 store 11-14 % less at
// 1.7-2.5x level 1's chunks stage.
inline constexpr int kDefaultZstdLevel = 1;
// zstd's shortest match in the leaf-block chunks (ConvertOptions::zstd_leaf_min_match), zstd's longest
// choice: level 3's own 5 finds the many 5- and 6-byte repeats of the leaf blocks' floats, each a
// sequence to decode. On unique-50m's batching points (232 MB, one thread, raw literals): 5 → ratio
// 1.840 at 1311 MB/s decompressed, 6 → 1.634 at 1640 MB/s, 7 → 1.585 at 1941 MB/s; out of core at a
// 10 % budget that is the load stage's main cost (docs/trace/budget.md, docs/package/zstd.md).
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
  // half their bytes are compressed with zstd's literals left raw, not Huffman-coded: on unique-50m's
  // float-heavy leaf blocks this decompresses 1.4x faster (977 vs 694 MB/s, one 34 MB chunk, level 3)
  // for 4 % more bytes; the out-of-core tracer's loads are mostly decompression (docs/trace/budget.md).
  // Chunks of instance BVHs and records keep Huffman literals (raw ones made forest-1m 7.5 % larger for
  // nothing: its loads are small). --zstd-huffman-literals turns it off everywhere.
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
