#pragma once
// Internals shared by the lib/bvh builders (not part of the public API).
//
// Determinism rules every file here follows:
//  * boxes are unions by float min/max, which is exact, so any merge order gives the same bits
//    (-0.0 is turned into +0.0 when primitive boxes are made, so min/max never sees both zeros);
//  * SAH costs are computed from such boxes, never accumulated across threads;
//  * work is split by fixed sizes (chunks, thresholds on primitive counts), never by thread count;
//  * intermediate node indices may depend on scheduling (tbb::concurrent_vector), but nothing is
//    ever ordered or tie-broken by them: the layout walks the tree from the root in lane order.
#include <oneapi/tbb/concurrent_vector.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "bvh/bvh.h"

namespace rtp::bvh {

constexpr uint32_t kNone = 0xFFFFFFFFu;
constexpr uint32_t kMaxBins = 64;

// Leaf blocks of width b for n primitives.
inline uint32_t blocks(uint32_t n, uint32_t b) { return (n + b - 1) / b; }

// ---- boxes ---------------------------------------------------------------------------------------

inline void grow(Box3f& b, const float lo[3], const float hi[3]) {
  for (int a = 0; a < 3; ++a) {
    b.lo[a] = std::min(b.lo[a], lo[a]);
    b.hi[a] = std::max(b.hi[a], hi[a]);
  }
}
inline void grow(Box3f& b, const Box3f& o) { grow(b, o.lo, o.hi); }
inline void grow_point(Box3f& b, const float p[3]) { grow(b, p, p); }
inline Box3f join(Box3f a, const Box3f& b) {
  grow(a, b);
  return a;
}
inline bool is_empty(const Box3f& b) { return !(b.lo[0] <= b.hi[0] && b.lo[1] <= b.hi[1] && b.lo[2] <= b.hi[2]); }
// Half the surface area, in double (cannot overflow for float boxes); 0 for an empty box.
inline double half_area(const Box3f& b) {
  if (is_empty(b)) return 0;
  const double x = double(b.hi[0]) - b.lo[0], y = double(b.hi[1]) - b.lo[1], z = double(b.hi[2]) - b.lo[2];
  return x * y + y * z + z * x;
}
inline float no_negative_zero(float v) { return v + 0.0f; }  // -0 + 0 = +0 (round to nearest)

// ---- primitives ----------------------------------------------------------------------------------

// A primitive (triangle or instance bound) as the builders move it around: 32 bytes.
struct PrimRef {
  float lo[3];
  uint32_t id;  // triangle index in the mesh, or box index
  float hi[3];
  uint32_t unused;
  // The box centre, without overflow; + 0.0f turns a -0 into +0. binned_sah.cpp computes the same
  // value with SSE (same operations in the same order).
  float centroid(int axis) const { return (0.5f * lo[axis] + 0.5f * hi[axis]) + 0.0f; }
};
static_assert(sizeof(PrimRef) == 32);

// Resolved options for one tree.
struct BuildParams {
  uint32_t bins = 32;
  uint32_t max_depth = 64;
  uint32_t leaf_size = 4;  // a-priori leaf: ranges of <= leaf_size primitives are leaves
  uint32_t max_leaf = 64;  // no leaf may hold more (16 blocks of `block`, or 16 instances)
  uint32_t block = 4;      // leaf cost granularity B: cost ⌈N/B⌉
  uint32_t task_threshold = 4096;
  uint32_t parallel_threshold = 65536;
};

// Number of median halvings that bring n primitives to at most leaf_size: ⌈log2 ⌈n / leaf_size⌉⌉.
inline uint32_t median_levels(uint64_t n, uint32_t leaf_size) {
  uint64_t groups = (n + leaf_size - 1) / leaf_size;
  uint32_t levels = 0;
  while ((uint64_t(1) << levels) < groups) ++levels;
  return levels;
}

// A contiguous range of PrimRefs with its bounds and its depth in the binary split tree.
struct Range {
  uint32_t begin = 0, end = 0;
  Box3f box;   // union of the primitive boxes
  Box3f cbox;  // bounds of the centroids
  uint32_t depth = 0;
  uint32_t size() const { return end - begin; }
};

// How a range is split: a binned SAH plane (left = bins [0, bin) on `axis`) or a median split.
struct Split {
  bool median = true;
  int axis = 0;
  uint32_t bin = 0;
  // SAH estimate of the children (SAH splits only): half areas and counts.
  double left_area = 0, right_area = 0;
  uint32_t left_count = 0, right_count = 0;
};

// Binned SAH over one PrimRef array (Wald 2007 binning, as Benthin 2008 §4.1 builds its binary BVH).
// `scratch` has the same length as `prims`; ranges handled concurrently must be disjoint.
class Splitter {
 public:
  Splitter(PrimRef* prims, PrimRef* scratch, const BuildParams& params) : prims_(prims), scratch_(scratch), p_(params) {}
  const BuildParams& params() const { return p_; }
  PrimRef* prims() const { return prims_; }

  // Bounds of [begin, end) at the given depth.
  Range make_range(uint32_t begin, uint32_t end, uint32_t depth) const;
  // The best binned SAH plane; a median split when no plane separates the centroids or when the
  // depth budget (max_depth - depth) only leaves room for median halving. Requires size() >= 2.
  Split find(const Range& r) const;
  // Partitions r by s into left and right (both non-empty), with their bounds, at depth + 1.
  void apply(const Range& r, const Split& s, Range& left, Range& right) const;

 private:
  void partition_sah(const Range& r, const Split& s, Range& left, Range& right) const;
  void partition_median(const Range& r, Range& left, Range& right) const;
  PrimRef* prims_;
  PrimRef* scratch_;
  BuildParams p_;
};

// ---- the binary tree (binned_sah.cpp) -------------------------------------------------------------

// Node i's left child is node i + 1; the right child is `right` (kNone for a leaf). A node over
// prims [begin, begin + count) is stored at an index reserved for its range (a subtree over n
// primitives uses at most 2n - 1 consecutive slots), so tasks never share a counter: the array is
// the same for any thread count. Unused slots keep count = 0.
struct BinaryNode {
  Box3f box;
  uint32_t begin = 0, count = 0;
  uint32_t right = kNone;
  bool leaf() const { return right == kNone; }
};
struct BinaryTree {
  std::vector<BinaryNode> nodes;  // node 0 is the root (if any primitive)
};

// Binary binned SAH build over prims[0, n): leaves when a range holds <= leaf_size primitives.
BinaryTree build_binary(Splitter& splitter, uint32_t n);

// ---- the W-wide tree before layout (collapse.cpp, split.cpp) -------------------------------------

// A leaf is a list of prim ranges: part p covers prims [begin, begin + count), then part `next`.
struct LeafPart {
  uint32_t begin = 0, count = 0;
  uint32_t next = kNone;
};

enum class LaneKind : uint8_t { kLeaf, kNode, kBinary };  // kBinary: an uncollapsed binary node

struct WideLane {
  Box3f box;
  uint32_t ref = kNone;  // kLeaf: first LeafPart; kNode: multi-node index; kBinary: binary node
  uint32_t prims = 0;    // primitives below
  LaneKind kind = LaneKind::kLeaf;
};

template <int W>
struct MultiNode {
  uint32_t count = 0;  // filled lanes, [0, count)
  WideLane lane[W];
};

template <int W>
struct WideTree {
  tbb::concurrent_vector<MultiNode<W>> nodes;  // indices depend on scheduling; only the shape counts
  std::vector<LeafPart> parts;
  WideLane root;  // prims == 0: empty tree
};

// Benthin 2008 §4.2 SAH collapse of `binary` (built over splitter's prims).
template <int W>
WideTree<W> collapse_binary(const BinaryTree& binary, const BuildParams& params);

// Benthin 2008 §4.3 top-down W-way split over prims[0, n).
template <int W>
WideTree<W> split_build(Splitter& splitter, uint32_t n);

// ---- layout (layout.cpp) -------------------------------------------------------------------------

// Emits the formats/ layout of a mesh tree: nodes depth-first, leaf blocks pre-gathered from `mesh`.
template <int W, int B>
void emit_mesh(const WideTree<W>& tree, const PrimRef* prims, const Mesh& mesh, const std::string& label, MeshBvh<W, B>& out);

// Emits a box tree: leaf refs index out.items, which receives the PrimRef ids.
template <int W>
void emit_boxes(const WideTree<W>& tree, const PrimRef* prims, const std::string& label, BoxBvh<W>& out);

// Validates options shared by every tree (throws Error(kUsage)).
void check_options(const BuildOptions& options);

// Builds the W-wide tree over prims[0, n) with the chosen method (mesh_bvh.cpp).
template <int W>
WideTree<W> build_wide(std::vector<PrimRef>& prims, const BuildParams& params, BuildMethod method, const std::string& label);

}  // namespace rtp::bvh
