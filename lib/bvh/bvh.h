#pragma once
// lib/bvh: wide BVHs in the formats/ layout (SPEC §2) for one chunk's meshes and for instances.
//
//   binary binned SAH (binned_sah.cpp) ─┬─ SAH collapse to W-wide (collapse.cpp)     Benthin 2008 §4.2
//                                       └─ or top-down W-way split (split.cpp)        Benthin 2008 §4.3
//   ─► WideNode<W> + pre-gathered LeafBlock<B> (layout.cpp)                         Benthin 2008 §4, §5.7
//      with per-octant child orders                                                 Molenaar 2019 §4.1
//
// Output is a pure function of the input and the options: byte-identical for any thread count
// (TBB parallelism never decides anything; work is split by fixed sizes and merged exactly).
// Bad input (non-finite vertex, index out of range, a limit of the format exceeded) throws
// rtp::Error(ExitCode::kInputInvalid) naming the mesh; bad options throw ExitCode::kUsage.
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "formats/bvh_layout.h"
#include "scene/scene.h"
#include "layout/scene_view.h"

namespace rtp {

enum class BuildMethod {
  kCollapse,  // binary binned SAH, then SAH collapse (Benthin 2008 §4.2)
  kSplit,     // top-down greedy W-way splitting (Benthin 2008 §4.3, Algorithm 1)
};
const char* method_name(BuildMethod method);  // "collapse", "split"

struct BuildOptions {
  BuildMethod method = BuildMethod::kCollapse;
  uint32_t bins = 32;          // SAH bins per axis, 2..64
  uint32_t max_depth = 64;     // binary split depth limit; the W-wide tree is never deeper. Near the
                               // limit the builders switch to median splits so every leaf fits.
  uint32_t leaf_size = 0;      // a-priori leaf collapse (Benthin §4.2): a subtree with <= leaf_size
                               // triangles becomes one leaf. 0 = W. At most 16·B (16 blocks per leaf).
  uint32_t top_leaf_size = 1;  // the same for the instance BVH, 1..16 instances
  // In core (InCoreScene): a scene of two or more instances that share one transform, each of a mesh of
  // its own (FlightHelmet's six identity parts; mesh nodes under one root transform), is built as one
  // mesh BVH under one instance, walked without the instance level when the transform is the identity;
  // hits still name the original instance and triangle. Same answers bit for bit; false keeps one BVH
  // per mesh under an instance BVH.
  bool merge_instances = true;
  // In core, with merge_instances: a scene of two or more instances each of a mesh of its own but under
  // different transforms (Lantern's three parts; the usual glTF layout) is merged in world space: the
  // vertices moved by their instance's transform (double, rounded once) under one identity instance,
  // when that rounding costs no instance more than 2^-17 of its own extent (max |world coordinate| <=
  // 128 x extent); hits still name the original instance and triangle. Answers may differ from the
  // two-level walk's in the last bits of t, u, v (the vertices are rounded in world space, not local).
  bool flatten_instances = true;
  // Parallelism (never changes the result): ranges of at least `task_threshold` primitives build
  // their two halves / their children as TBB tasks; ranges of at least `parallel_threshold` bin and
  // partition with parallel loops.
  uint32_t task_threshold = 4096;
  uint32_t parallel_threshold = 65536;
};

// Benthin 2008 §4 cost model, relative to the root's surface area SA(root):
//   c_box = Σ_{inner nodes M} SA(M) / SA(root)          (the root node counts 1)
//   c_tri = Σ_{leaves L} SA(L)·⌈N(L)/B⌉ / SA(root)      (B = leaf block width; 1 for instance BVHs)
// When SA(root) = 0 (every primitive is the same point) each SA ratio is taken as 1.
struct BvhStats {
  double c_box = 0;
  double c_tri = 0;
  double sah = 0;           // c_box + c_tri
  double branching = 0;     // filled lanes per inner node
  double leaf_fill = 0;     // primitives / (blocks·B)
  uint32_t max_depth = 0;   // inner nodes on the longest root-to-leaf path (0: the root is a leaf)
  uint64_t primitives = 0;  // triangles (mesh BVH) or instances (instance BVH)
  uint64_t nodes = 0;       // WideNode count
  uint64_t leaves = 0;      // leaf lanes
  uint64_t blocks = 0;      // LeafBlock count (instance BVH: entries of the instance-index array)
  uint64_t node_bytes = 0;
  uint64_t block_bytes = 0;
};

// An axis-aligned box in float, as the layout stores it. Empty: lo = +inf, hi = -inf.
struct Box3f {
  static constexpr float kInf = std::numeric_limits<float>::infinity();
  float lo[3] = {kInf, kInf, kInf};
  float hi[3] = {-kInf, -kInf, -kInf};
};

// One mesh's BVH in its local space. `root` is a ChildRef: node 0 when the root is an inner node, a
// leaf ref for a mesh of at most leaf_size triangles, kEmpty for a mesh without triangles.
// Nodes are in depth-first pre-order (lane order); blocks in the order their nodes are emitted.
template <int W, int B>
struct MeshBvh {
  std::vector<fmt::WideNode<W>> nodes;
  std::vector<fmt::LeafBlock<B>> blocks;
  uint32_t root = fmt::ChildRef::kEmpty;
  BvhStats stats;
  MeshBvhView<W, B> view() const { return {nodes.data(), blocks.data(), root}; }
};

// Builds the BVH of `mesh`; `label` names it in error messages (default: "mesh '<name>'").
template <int W, int B>
MeshBvh<W, B> build_mesh_bvh(const Mesh& mesh, const BuildOptions& options = {}, std::string_view label = {});

// A W-wide BVH over boxes (instances, objects). Leaf refs use the ChildRef leaf encoding with
// first_block = first entry of `items` and block_count = number of entries (1..16); `items` holds
// indices into the input boxes. Boxes must be finite with lo <= hi.
template <int W>
struct BoxBvh {
  std::vector<fmt::WideNode<W>> nodes;
  std::vector<uint32_t> items;
  uint32_t root = fmt::ChildRef::kEmpty;
  BvhStats stats;
};
template <int W>
BoxBvh<W> build_box_bvh(const std::vector<Box3f>& boxes, const BuildOptions& options = {},
                        std::string_view label = "instance BVH");

// Octant orders (Molenaar 2019 §4.1), as layout.cpp computes them and the tests check them: the filled
// lanes of a node sorted by the key below ascending, ties by lane index, then the empty lanes in
// ascending lane order. key = dot(lo + hi, d) with d = (±1, ±1, ±1), the component negative when the
// octant bit is set (bit 0: x, bit 1: y, bit 2: z); evaluated in double as
// ((lo.x + hi.x)·d.x + (lo.y + hi.y)·d.y) + (lo.z + hi.z)·d.z. (dot(centre, d) ordered the same way.)
double octant_key(const float lo[3], const float hi[3], int octant);

// ---- instances (instance_bvh.cpp) ---------------------------------------------------------------

// The 3x4 inverse of `m`, computed in double. False when m is singular (|det| tiny or not finite).
bool invert_affine(const Affine3x4& m, double inverse[12]);

// SPEC §2.4 record: the translation in double, the inverse of the 3x3 part taken in double then
// rounded to float (all zeros if singular), flags bit 0 = det of that stored inverse < 0.
fmt::InstanceRecord make_instance_record(const Instance& instance);
// make_instance_record of every instance into out[0 .. instances.size()), in parallel (the writer's
// records, computed once: batching points and culling proxies copy from them instead of recomputing).
void make_instance_records(const std::vector<Instance>& instances, fmt::InstanceRecord* out);
std::vector<fmt::InstanceRecord> make_instance_records(const std::vector<Instance>& instances);

// False when the record's inverse is all zeros (singular transform) or not finite: never hit.
bool record_invertible(const fmt::InstanceRecord& rec);

// A float box containing the image under `m` of every point of the `local` boxes (corners
// transformed in double, rounded outward, widened by one more float step).
Box3f transform_bounds(const Affine3x4& m, const Box3f* local, size_t count);

// ---- the two levels, in core (in_core_scene.cpp) -------------------------------------------------

// Every mesh's BVH in local space (built in parallel over meshes) and an instance BVH over the world
// bounds of the instances (Molenaar 2019 §4.1 two levels). Instances of meshes without triangles and
// instances with a singular transform are left out of the instance BVH (with a warning); the instance
// records still exist so indices match Scene::instances.
template <int W, int B>
class InCoreScene {
 public:
  static InCoreScene build(const Scene& scene, const BuildOptions& options = {});

  InCoreScene() = default;
  InCoreScene(InCoreScene&&) noexcept = default;  // views stay valid: vector buffers move with it
  InCoreScene& operator=(InCoreScene&&) noexcept = default;
  InCoreScene(const InCoreScene&) = delete;
  InCoreScene& operator=(const InCoreScene&) = delete;

  SceneView<W, B> view() const;
  size_t mesh_count() const { return meshes_.size(); }
  const MeshBvh<W, B>& mesh(size_t i) const { return meshes_.at(i); }
  const BvhStats& mesh_stats(size_t i) const { return meshes_.at(i).stats; }
  const BoxBvh<W>& top() const { return top_; }
  const BvhStats& top_stats() const { return top_.stats; }
  const std::vector<fmt::InstanceRecord>& instances() const { return records_; }
  const std::vector<std::string>& warnings() const { return warnings_; }
  // True when the instances were merged into one mesh BVH (BuildOptions::merge_instances):
  // mesh(mesh_count() - 1) is that BVH, the scene's own meshes have none, and instances() holds one
  // record more, the merged one (their shared transform).
  bool merged() const { return !part_first_.empty(); }
  // True when merged in world space (BuildOptions::flatten_instances): the merged record is the identity.
  bool flattened() const { return flattened_; }

 private:
  std::vector<MeshBvh<W, B>> meshes_;
  std::vector<MeshBvhView<W, B>> views_;
  BoxBvh<W> top_;  // items = instance indices
  std::vector<fmt::InstanceRecord> records_;
  std::vector<AxisMove> moves_;  // axis_moves(records_), for the view
  std::vector<std::string> warnings_;
  std::vector<uint32_t> part_first_, part_instance_;  // merged: SceneView::part_first / part_instance
  bool flattened_ = false;
  static InCoreScene build_merged(const Scene& scene, const BuildOptions& options, bool flatten);
};

// ---- statistics (stats_table.cpp) ---------------------------------------------------------------

// All instanced triangles of `scene` in world space (stored float transform applied in double, then
// rounded): one mesh, as Benthin 2008 Table 1 measures whole scenes.
Mesh flatten_scene(const Scene& scene);

struct BvhStatsRow {
  std::string model;
  int width = 0;  // W
  int block = 0;  // B
  BuildMethod method = BuildMethod::kCollapse;
  BvhStats stats;
  double build_seconds = 0;  // wall clock of build_mesh_bvh (not part of the table text)
};

// One row per W ∈ {4, 8, 16} (B = W) × {collapse, split}, `options.method` ignored.
std::vector<BvhStatsRow> bvh_stats_rows(const std::string& model, const Mesh& mesh, const BuildOptions& options = {});

// Benthin 2008 Table 1 style text table of the rows (no timings: the text is deterministic).
std::string bvh_stats_table(const std::vector<BvhStatsRow>& rows);

// Imports each glTF/GLB (rtp::import_gltf), flattens it, and tabulates bvh_stats_rows.
std::string bvh_stats_table(const std::vector<std::string>& gltf_paths, const BuildOptions& options = {});

}  // namespace rtp
