#pragma once
// rtpack-inspect: a package's sizes, batching points, mesh segments and per-chunk BVH statistics
// (Benthin 2008 §4 cost model), computed on the reader side from the stored bytes only, and with
// verify = true every invariant of formats/SPEC.md checked, each failure named by chunk and object.
// Reader side: includes formats/, lib/package reader headers and lib/core only (inspect_dag.cpp also
// uses lib/voxel's read-only DAG checks).
#include <array>
#include <cstdint>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "core/aligned.h"
#include "formats/bvh_layout.h"
#include "formats/chunk.h"
#include "formats/dag.h"
#include "formats/top_level.h"
#include "inspect/inspect_attributes.h"
#include "layout/dag_query.h"
#include "reader/reader.h"

namespace rtp {

struct InspectOptions {
  bool chunks = false;     // per-chunk rows (kind, sizes, BVH statistics)
  bool verify = false;     // check every invariant (checksums and decompression are always checked)
  size_t max_listed = 20;  // problems kept verbatim; the rest are only counted
};

struct InspectResult {
  nlohmann::json report;            // everything rtpack-inspect prints (as tables, or --json as is)
  uint64_t problems = 0;            // chunks that failed to read or parse, failed invariants
  std::vector<std::string> listed;  // the first max_listed problem messages
};

// Reads every chunk once (CRC-checked, decompressed) and analyses it. Never throws for a bad chunk:
// each becomes a problem naming it. Throws rtp::Error only for what the reader itself throws.
InspectResult inspect_package(const PackageReader& reader, const InspectOptions& options = {});

// ---- reader-side BVH statistics (inspect_stats.cpp) ---------------------------------------------

// A box in double. Empty: lo = +inf, hi = -inf.
struct Box3d {
  static constexpr double kInf = std::numeric_limits<double>::infinity();
  double lo[3] = {kInf, kInf, kInf};
  double hi[3] = {-kInf, -kInf, -kInf};
  bool empty() const { return !(lo[0] <= hi[0] && lo[1] <= hi[1] && lo[2] <= hi[2]); }
  void grow(const double p[3]);
  void grow(const Box3d& b);
};

// Benthin 2008 §4, relative to the surface area of the root (the union of the root node's lanes):
//   c_box = Σ_{inner nodes M} SA(M) / SA(root)            (the root counts 1)
//   c_tri = Σ_{leaves L} SA(L)·⌈N(L)/B⌉ / SA(root)        N = distinct triangles (instances) of L;
//                                                          B = 1 for instance BVHs
// When SA(root) = 0 every ratio is 1. A root that is a leaf: c_box = 0, c_tri = ⌈N/B⌉, depth 0.
struct BvhShape {
  double c_box = 0, c_tri = 0;
  double branching = 0;     // filled lanes per inner node (0 without inner nodes)
  double leaf_fill = 0;     // primitives / (blocks·B) (0 without blocks)
  uint32_t max_depth = 0;   // inner nodes on the longest root-to-leaf path
  uint64_t nodes = 0;       // inner nodes reached
  uint64_t leaves = 0;      // leaf lanes (or a leaf root)
  uint64_t blocks = 0;      // leaf blocks (instance BVH: instance-index entries) referenced
  uint64_t primitives = 0;  // distinct triangles (instances) over the leaves
};

// Problems found by a check, with the first few messages kept verbatim.
class Problems {
 public:
  explicit Problems(size_t keep = 20) : keep_(keep) {}
  void add(const std::string& message);
  uint64_t count() const { return count_; }
  const std::vector<std::string>& listed() const { return listed_; }

 private:
  size_t keep_;
  uint64_t count_ = 0;
  std::vector<std::string> listed_;
};

// A conservative bound an instance-BVH leaf must contain: box, minus tol per axis (float rounding).
struct ItemBound {
  Box3d box;
  double tol[3] = {0, 0, 0};
};

// Optional invariant checks and outputs of a BVH walk. Without `problems` nothing is checked (the
// walk still never reads out of range, and visits each node at most once).
struct BvhCheck {
  Problems* problems = nullptr;
  std::string label;                       // message prefix: "<chunk label>: piece 3 (entry 0)"
  std::vector<uint32_t>* prims = nullptr;  // out: prim of every non-padding lane (instance BVH: ids)
  const ItemBound* items = nullptr;        // instance BVH: the bound each local instance needs
  uint64_t item_count = 0;
  Box3d root_box;  // out: root lanes' union (a leaf root: its contents)
};

// A mesh or piece BVH: `root` is a ChildRef relative to `nodes` and `blocks`.
template <int W, int B>
BvhShape mesh_bvh_shape(const fmt::WideNode<W>* nodes, uint64_t node_count, const fmt::LeafBlock<B>* blocks, uint64_t block_count,
                        uint32_t root, BvhCheck* check = nullptr);

// A batching point's instance BVH: leaves index `ids` (local instance indices).
template <int W>
BvhShape instance_bvh_shape(const fmt::WideNode<W>* nodes, uint64_t node_count, const uint32_t* ids, uint64_t id_count,
                            uint32_t root, BvhCheck* check = nullptr);

// min / mean / max of a statistic over BVHs (or chunks).
struct Spread {
  double min = std::numeric_limits<double>::infinity(), max = -std::numeric_limits<double>::infinity(), sum = 0;
  uint64_t n = 0;
  void add(double v);
  nlohmann::json json() const;  // {"min", "mean", "max"} (nulls when empty)
};

// The statistics of a group of BVHs (one chunk kind, or one chunk).
struct BvhGroup {
  uint64_t bvhs = 0, root_leaves = 0, triangles = 0, nodes = 0, blocks = 0;
  Spread c_box, c_tri, sah, branching, leaf_fill, max_depth;
  void add(const BvhShape& s);
  nlohmann::json json() const;
};

// Power-of-two histogram: bucket 0 holds 0, bucket k ≥ 1 holds [2^(k-1), 2^k).
struct Histogram {
  std::vector<uint64_t> buckets;
  void add(uint64_t v);
  nlohmann::json json() const;  // [{"min", "max" (exclusive), "count"}] over the non-empty range
};

// ---- internal: shared by inspect.cpp (reading, statistics) and inspect_verify.cpp (invariants) ----
namespace inspect_detail {

using Pair = std::array<uint32_t, 2>;

inline std::string str(uint64_t v) { return std::to_string(v); }

// The resident sections as read (a flag is false when its chunk is missing or unreadable).
struct Resident {
  bool meta_ok = false, top_ok = false, descs_ok = false, instances_ok = false, meshes_ok = false, source_ok = false;
  bool instances_checked = false;  // the instance table passed check_instance_table against the mesh table
  nlohmann::json meta;
  std::vector<fmt::TopNode> top;
  std::vector<fmt::BatchingPointDesc> descs;
  std::vector<uint32_t> segment_refs;
  std::vector<fmt::InstanceRef> instances;  // the instance table (SPEC §2.5)
  std::vector<fmt::MeshInfo> meshes;
  std::vector<Pair> source_prims, source_tris;
  std::string top_label, descs_label, instances_label, meshes_label, source_label, meta_label;
  // Culling DAGs (2.0, SPEC §4.5): section kPointGrids of the descriptors chunk and the DAG pool chunk
  // (kind 7). `*_present`: the section / chunk exists (even when unreadable); `*_ok`: it was parsed.
  bool grids_present = false, grids_ok = false, dag_present = false, dag_ok = false;
  std::vector<fmt::DagGrid> grids;
  std::vector<uint32_t> dag_words;
  std::vector<uint64_t> dag_leaves;
  AlignedBytes cull_nodes;  // 7.0: section kCullNodes of the DAG pool chunk, CullNode<W>[cull_count]
  uint64_t cull_count = 0;
  std::string dag_label;
};

// The "dag" block of the report (pool bytes and counts, resolutions, sharing, set cells) from the
// resident sections alone. Structural DAG problems are reported in every mode, as the tracer refuses
// them (SPEC §4.6): pool chunk iff grids iff header flag, one grid per batching point, every grid's DAG
// sound (voxel::check_dag); with `verify` also every grid covering its point's bounds.
// The pool as the DAG queries read it (its cull nodes with the header's width).
voxel::DagView dag_view(const PackageReader& reader, const Resident& resident);
nlohmann::json dag_report(const PackageReader& reader, const Resident& resident, Problems& problems);

// One mesh segment: its entries and, per entry, the prims of its leaves (non-padding lanes).
struct SegmentData {
  uint64_t id = 0;
  std::string label;
  std::vector<fmt::MeshEntry> entries;
  std::vector<std::vector<uint32_t>> prims;
};

// One batching point as read; `bounds` per local instance (pieces: root box; instances: the
// transformed root box of its mesh in the segment, with the float-rounding tolerance).
struct PointData {
  uint64_t id = 0;
  std::string label;
  uint64_t te_count = 0, inode_count = 0, id_count = 0;
  fmt::MeshEntry te{};
  std::vector<fmt::InstanceRecord> records;
  std::vector<uint32_t> global_ids, slots;
  std::vector<fmt::MeshEntry> entries;
  std::vector<std::vector<uint32_t>> piece_prims;
  std::vector<uint32_t> instance_refs;  // local instances referenced by the instance BVH's leaves
  std::vector<ItemBound> bounds;
};

// Cross-chunk invariants (SPEC §4): resident tables against each other, each chunk against them,
// and coverage (every instance, every triangle exactly once) once every chunk has been seen.
class Verifier {
 public:
  Verifier(const PackageReader& reader, const Resident& resident, Problems& problems);
  void segment(const SegmentData& s);
  void point(const PointData& p);
  void attributes(size_t toc_index, const AlignedBytes& bytes);  // kinds 18, 19
  // A geometry chunk that failed to read or decode (already a problem): finish() does not report what it
  // would have held as missing, so the cause is not buried under its consequences.
  void unreadable(uint32_t kind, uint64_t id) {
    (kind == uint32_t(fmt::ChunkKind::kBatchingPoint) ? bad_points_ : bad_segments_).insert(id);
  }
  void finish();

 private:
  void check_toc();
  void check_padding();
  void check_tables();
  void check_top();
  const PackageReader& r_;
  const Resident& res_;
  Problems& out_;
  std::vector<uint32_t> instance_seen_;             // per scene instance: as a non-piece instance
  std::vector<std::vector<uint8_t>> unique_cover_;  // per scene instance of a unique mesh: per triangle
  struct PieceHome {  // a unique mesh's instance: its first piece (by point, local index) and that record
    uint32_t point = ~0u, local = 0;
    fmt::InstanceRecord rec{};
  };
  std::map<uint32_t, PieceHome> piece_home_;
  std::vector<uint8_t> mesh_in_segment_;     // per mesh: entries in segments
  std::map<uint32_t, uint32_t> piece_seen_;  // piece id -> times stored
  std::set<uint64_t> bad_points_, bad_segments_;
  AttributeChecker attrs_;
  uint64_t pieces_ = 0, segments_ = 0, points_ = 0;
};

}  // namespace inspect_detail
}  // namespace rtp
