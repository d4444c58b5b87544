// Emission of the formats/ layout (SPEC §2) from a W-wide build tree: WideNode<W> with SoA child
// boxes, ChildRef encoding, per-octant child orders (Molenaar 2019 §4.1), pre-gathered SoA leaf blocks
// (Benthin 2008 §5.7), format limits, and the §4 cost statistics.
//
// Nodes are numbered in depth-first pre-order, lanes in order, node 0 = root; a node's leaf blocks
// are allocated when the node is emitted, so each node's leaves sit together. Block contents are
// filled afterwards in parallel (each leaf writes only its own blocks). Statistics are summed in
// emission order, so they too are identical for any thread count.
#include <oneapi/tbb/parallel_for.h>

#include <cmath>

#include "bvh/build_internal.h"
#include "core/error.h"

namespace rtp {

double octant_key(const float lo[3], const float hi[3], int octant) {
  const double dx = (octant & 1) ? -1.0 : 1.0, dy = (octant & 2) ? -1.0 : 1.0, dz = (octant & 4) ? -1.0 : 1.0;
  return ((double(lo[0]) + double(hi[0])) * dx + (double(lo[1]) + double(hi[1])) * dy) + (double(lo[2]) + double(hi[2])) * dz;
}

namespace bvh {
namespace {

using fmt::ChildRef;

// Molenaar 2019 §4.1: per ray octant, the filled lanes front to back along the octant's diagonal
// (key ascending, ties by lane), then the empty lanes. Insertion sort: at most 16 lanes.
// octant_key's value for every octant from three sums per lane: multiplying by -1 is exact, so its
// (±sx + ±sy) + ±sz is ±(sx + sy) or ±(sx - sy), then one addition — the same bits, without the
// eight calls and the per-octant float-to-double conversions per lane.
template <int W>
void write_octant_orders(fmt::WideNode<W>& node, uint32_t filled) {
  double plus[W], minus[W], sz[W];  // sx + sy, sx - sy, sz with s = double(lo) + double(hi)
  for (uint32_t i = 0; i < filled; ++i) {
    const double sx = double(node.lo[0][i]) + double(node.hi[0][i]), sy = double(node.lo[1][i]) + double(node.hi[1][i]);
    plus[i] = sx + sy;
    minus[i] = sx - sy;
    sz[i] = double(node.lo[2][i]) + double(node.hi[2][i]);
  }
  for (int o = 0; o < 8; ++o) {
    double key[W];
    uint8_t lanes[W];
    // Octant bits: 1 = -x, 2 = -y, 4 = -z. (+x,+y): sx + sy; (-x,+y): -(sx - sy); (+x,-y): sx - sy; (-x,-y): -(sx + sy).
    const bool nx = o & 1, ny = o & 2, nz = o & 4;
    const double* xy = nx == ny ? plus : minus;
    const double sign_xy = nx ? -1.0 : 1.0, sign_z = nz ? -1.0 : 1.0;
    for (uint32_t i = 0; i < filled; ++i) {
      key[i] = sign_xy * xy[i] + sign_z * sz[i];
      uint32_t k = i;
      while (k > 0 && key[lanes[k - 1]] > key[i]) {  // strict: equal keys keep lane order
        lanes[k] = lanes[k - 1];
        --k;
      }
      lanes[k] = uint8_t(i);
    }
    for (uint32_t i = filled; i < uint32_t(W); ++i) lanes[i] = uint8_t(i);
    for (int i = 0; i < W; ++i) node.order[o][i] = lanes[i];
  }
}

// Walks the tree from the root and writes nodes; `leaf(lane)` returns the ChildRef of a leaf lane.
// `cost_block` is the B of the ⌈N/B⌉ leaf cost.
template <int W, class LeafFn>
void emit_nodes(const WideTree<W>& tree, uint32_t cost_block, uint64_t block_size, const std::string& label,
                std::vector<fmt::WideNode<W>>& nodes, uint32_t& root, BvhStats& st, LeafFn&& leaf) {
  st = BvhStats{};
  nodes.clear();
  root = ChildRef::kEmpty;
  if (tree.root.prims == 0) return;
  // Benthin 2008 §4 cost estimate: C_box = Σ SA(M), C_tri = Σ SA(L)·⌈N/B⌉, relative to SA(root).
  const double root_area = half_area(tree.root.box);
  auto ratio = [root_area](const Box3f& b) { return root_area > 0 ? half_area(b) / root_area : 1.0; };
  auto leaf_ref = [&](const WideLane& lane) {
    st.c_tri += ratio(lane.box) * blocks(lane.prims, cost_block);
    st.leaves += 1;
    st.blocks += blocks(lane.prims, cost_block);
    st.primitives += lane.prims;
    return leaf(lane);
  };

  uint64_t filled_lanes = 0;
  if (tree.root.kind == LaneKind::kLeaf) {
    root = leaf_ref(tree.root);
  } else {
    struct Pending {
      uint32_t node;    // multi-node in the build tree
      uint32_t parent;  // output node to patch, kNone for the root
      uint32_t lane;
      uint32_t depth;
    };
    std::vector<Pending> stack{{tree.root.ref, kNone, 0, 1}};
    nodes.reserve(tree.nodes.size());
    while (!stack.empty()) {
      const Pending p = stack.back();
      stack.pop_back();
      if (nodes.size() >= ChildRef::kMaxNodes)
        throw Error(ExitCode::kInputInvalid, label + ": more than " + std::to_string(ChildRef::kMaxNodes) + " BVH nodes");
      const uint32_t index = uint32_t(nodes.size());
      if (p.parent == kNone) {
        root = ChildRef::inner(index);
      } else {
        nodes[p.parent].child[p.lane] = ChildRef::inner(index);
      }
      const MultiNode<W>& m = tree.nodes[p.node];
      if (m.count < 2 || m.count > uint32_t(W))
        throw Error(ExitCode::kInternal, label + ": multi-node with " + std::to_string(m.count) + " lanes");
      fmt::WideNode<W> node;
      Box3f box;
      for (uint32_t i = 0; i < uint32_t(W); ++i) {
        const bool filled = i < m.count;
        const Box3f b = filled ? m.lane[i].box : Box3f{};
        for (int a = 0; a < 3; ++a) {
          node.lo[a][i] = b.lo[a];
          node.hi[a][i] = b.hi[a];
        }
        node.child[i] = ChildRef::kEmpty;
        if (!filled) continue;
        grow(box, b);
        if (m.lane[i].kind == LaneKind::kLeaf) node.child[i] = leaf_ref(m.lane[i]);
      }
      write_octant_orders(node, m.count);
      nodes.push_back(node);
      st.c_box += ratio(box);
      st.max_depth = std::max(st.max_depth, p.depth);
      filled_lanes += m.count;
      for (uint32_t i = m.count; i-- > 0;)  // reversed: lane 0 is emitted next (pre-order)
        if (m.lane[i].kind == LaneKind::kNode) stack.push_back({m.lane[i].ref, index, i, p.depth + 1});
    }
  }
  st.nodes = nodes.size();
  st.sah = st.c_box + st.c_tri;
  st.branching = st.nodes ? double(filled_lanes) / double(st.nodes) : 0;
  st.leaf_fill = st.blocks ? double(st.primitives) / (double(st.blocks) * cost_block) : 0;
  st.node_bytes = st.nodes * sizeof(fmt::WideNode<W>);
  st.block_bytes = st.blocks * block_size;
}

}  // namespace

template <int W, int B>
void emit_mesh(const WideTree<W>& tree, const PrimRef* prims, const Mesh& mesh, const std::string& label, MeshBvh<W, B>& out) {
  struct Job {
    uint32_t part, count, first_block;
  };
  std::vector<Job> jobs;
  uint64_t next_block = 0;
  emit_nodes(tree, B, sizeof(fmt::LeafBlock<B>), label, out.nodes, out.root, out.stats, [&](const WideLane& lane) {
    const uint32_t n = blocks(lane.prims, B);
    if (n == 0 || n > ChildRef::kMaxBlocksPerLeaf)
      throw Error(ExitCode::kInternal, label + ": leaf of " + std::to_string(lane.prims) + " triangles");
    if (next_block + n - 1 > ChildRef::kMaxBlockIndex)
      throw Error(ExitCode::kInputInvalid,
                  label + ": more than " + std::to_string(ChildRef::kMaxBlockIndex + 1) + " leaf blocks (split the mesh)");
    jobs.push_back({lane.ref, lane.prims, uint32_t(next_block)});
    const uint32_t ref = ChildRef::leaf(uint32_t(next_block), n);
    next_block += n;
    return ref;
  });

  // Benthin 2008 §5.7 pre-gathering: each leaf's triangles in SoA blocks of B, the last block padded
  // by repeating its last triangle.
  out.blocks.assign(next_block, fmt::LeafBlock<B>{});
  const Vec3f* pos = mesh.positions.data();
  const uint32_t* idx = mesh.indices.data();
  tbb::parallel_for(size_t(0), jobs.size(), [&](size_t j) {
    const Job& job = jobs[j];
    fmt::LeafBlock<B>* blk = out.blocks.data() + job.first_block;
    uint32_t t = 0;
    auto put = [&](uint32_t lane_index, uint32_t tri) {
      fmt::LeafBlock<B>& b = blk[lane_index / B];
      const uint32_t l = lane_index % B;
      const Vec3f& a = pos[idx[3 * size_t(tri)]];
      const Vec3f& c = pos[idx[3 * size_t(tri) + 1]];
      const Vec3f& d = pos[idx[3 * size_t(tri) + 2]];
      for (int k = 0; k < 3; ++k) {
        b.v0[k][l] = a[k];
        b.v1[k][l] = c[k];
        b.v2[k][l] = d[k];
      }
      b.prim[l] = tri;
    };
    uint32_t last = 0;
    for (uint32_t part = job.part; part != kNone; part = tree.parts[part].next) {
      const LeafPart& lp = tree.parts[part];
      for (uint32_t k = lp.begin; k < lp.begin + lp.count; ++k) {
        last = prims[k].id;
        put(t++, last);
      }
    }
    for (; t % B != 0; ++t) put(t, last);
  });
}

template <int W>
void emit_boxes(const WideTree<W>& tree, const PrimRef* prims, const std::string& label, BoxBvh<W>& out) {
  out.items.clear();
  emit_nodes(tree, 1, sizeof(uint32_t), label, out.nodes, out.root, out.stats, [&](const WideLane& lane) {
    if (lane.prims == 0 || lane.prims > ChildRef::kMaxBlocksPerLeaf)
      throw Error(ExitCode::kInternal, label + ": leaf of " + std::to_string(lane.prims) + " items");
    const uint64_t first = out.items.size();
    if (first + lane.prims - 1 > ChildRef::kMaxBlockIndex)
      throw Error(ExitCode::kInputInvalid, label + ": more than " + std::to_string(ChildRef::kMaxBlockIndex + 1) + " items");
    for (uint32_t part = lane.ref; part != kNone; part = tree.parts[part].next) {
      const LeafPart& lp = tree.parts[part];
      for (uint32_t k = lp.begin; k < lp.begin + lp.count; ++k) out.items.push_back(prims[k].id);
    }
    return ChildRef::leaf(uint32_t(first), lane.prims);
  });
}

#define RTP_EMIT_MESH(W, B) \
  template void emit_mesh<W, B>(const WideTree<W>&, const PrimRef*, const Mesh&, const std::string&, MeshBvh<W, B>&);
RTP_EMIT_MESH(4, 4)
RTP_EMIT_MESH(8, 8)
RTP_EMIT_MESH(16, 16)
RTP_EMIT_MESH(8, 4)
RTP_EMIT_MESH(16, 8)
#undef RTP_EMIT_MESH
template void emit_boxes<4>(const WideTree<4>&, const PrimRef*, const std::string&, BoxBvh<4>&);
template void emit_boxes<8>(const WideTree<8>&, const PrimRef*, const std::string&, BoxBvh<8>&);
template void emit_boxes<16>(const WideTree<16>&, const PrimRef*, const std::string&, BoxBvh<16>&);

}  // namespace bvh
}  // namespace rtp
