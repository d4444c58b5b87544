// Culling that cannot drop a hit (lib/reader/check_culling.h, formats/SPEC.md §4.5, §4.6): a batching
// point's culling grid that would cull rays its geometry is hit by is refused by every reader when it
// decodes it. Each case was an exit-0 wrong answer with --cull before (an empty root on a point of 968
// triangles: 0 hits instead of 978); now the tracer, rtpack-trace (with and without --cull),
// rtpack-inspect and --verify exit 3 naming the chunk and the field.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <functional>
#include <limits>

#include "formats/bvh_layout.h"
#include "formats/chunk.h"
#include "formats/dag.h"
#include "hostile_package.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using fmt::SectionType;

// The first point that culls by instance boxes: its grid and the index of its chunk.
struct BoxPoint {
  uint64_t point = 0;
  fmt::DagGrid grid{};
};
BoxPoint box_point(const std::string& path) {
  PackageReader r(path);
  const AlignedBytes b = r.read(size_t(r.find(fmt::ChunkKind::kBatchingPoints, 0)));
  uint64_t n = 0;
  const fmt::DagGrid* g = section<fmt::DagGrid>(const_cast<uint8_t*>(b.data()), SectionType::kPointGrids, &n);
  for (uint64_t p = 0; p < n; ++p)
    if (g[p].resolution == fmt::kDagBoxes) return {p, g[p]};
  throw std::runtime_error("no batching point culls by instance boxes");
}

// The instance BVH root node of point `p` (its first node: the cull nodes mirror it node for node).
fmt::WideNode<kW> instance_root(const std::string& path, uint64_t p) {
  PackageReader r(path);
  AlignedBytes b = r.read(size_t(r.find(fmt::ChunkKind::kBatchingPoint, p)));
  return section<fmt::WideNode<kW>>(b.data(), SectionType::kInstanceNodes)[0];
}

class HostileCulling : public Hostile {
 protected:
  // Every reader refuses it, and so does rtpack-trace --cull (no hit file either).
  void expect_refused_with_culling(const std::string& p, const std::vector<std::string>& needles) {
    expect_everywhere(p, needles);
    const ToolResult r =
        run_tool("rtpack-trace", {p, "--rays", (dir / "tools.rays").string(), "--hits", (dir / "cull.hits").string(), "--cull"},
                 dir, {}, 20);
    EXPECT_EQ(r.code, 3) << r.err;
    EXPECT_TRUE(contains_all(r.err, needles)) << r.err;
    EXPECT_FALSE(fs::exists(dir / "cull.hits"));
  }
  // Edits the root cull node of the first instance-box point of forest_boxes: `edit(node, bvh_root)`
  // returns the field text.
  void box_case(const std::function<std::string(fmt::CullNode<kW>&, const fmt::WideNode<kW>&)>& edit) {
    const std::string p = copy(bases().forest_boxes);
    const BoxPoint bp = box_point(p);
    const fmt::WideNode<kW> bvh = instance_root(p, bp.point);
    const std::string label = chunk_of(p, fmt::ChunkKind::kBatchingPoint, bp.point).second;
    std::string field;
    patch_chunk(p, chunk_of(p, fmt::ChunkKind::kDagPool, 0).first, [&](uint8_t* chunk, size_t) {
      field = edit(section<fmt::CullNode<kW>>(chunk, SectionType::kCullNodes)[bp.grid.root], bvh);
    });
    expect_refused_with_culling(p, {label, field});
  }
  // Patches the grids section of the descriptors chunk: `edit(grids, count)` returns the field text.
  void grid_case(const std::string& base, const std::function<std::string(fmt::DagGrid*, uint64_t)>& edit) {
    const std::string p = copy(base);
    const auto [index, label] = chunk_of(p, fmt::ChunkKind::kBatchingPoints, 0);
    std::string field;
    patch_chunk(p, index, [&](uint8_t* chunk, size_t) {
      uint64_t n = 0;
      fmt::DagGrid* grids = section<fmt::DagGrid>(chunk, SectionType::kPointGrids, &n);
      ASSERT_NE(grids, nullptr) << "no culling grids";
      field = edit(grids, n);
    });
    expect_refused_with_culling(p, {label, field});
  }
};

TEST_F(HostileCulling, EmptyRootOnAPointWithTriangles) {
  grid_case(bases().forest, [](fmt::DagGrid* g, uint64_t) {
    g[0].root = fmt::kDagEmpty;
    return std::string("batching point 0: culling grid is empty (it culls every ray) but the point has");
  });
}

TEST_F(HostileCulling, VoxelGridMovedOffItsPoint) {
  grid_case(bases().forest, [](fmt::DagGrid* g, uint64_t) {
    g[0].origin[1] += g[0].cell * float(g[0].resolution) * 0.5f;  // the lower half of the point is outside
    return std::string("batching point 0: culling grid [");
  });
}

// The lane of the root with the widest box on axis 0.
int widest_lane(const fmt::WideNode<kW>& n) {
  int best = -1;
  for (int l = 0; l < kW; ++l)
    if (!fmt::ChildRef::is_empty(n.child[l]) && (best < 0 || n.hi[0][l] - n.lo[0][l] > n.hi[0][best] - n.lo[0][best])) best = l;
  return best;
}

// Boxes shrunk instead of emptied would drop hits: culling dropped from 54 % to 8 % with them emptied.
TEST_F(HostileCulling, InstanceBoxShrunkBelowItsBvhBox) {
  box_case([](fmt::CullNode<kW>& c, const fmt::WideNode<kW>& bvh) {
    const int l = widest_lane(bvh);
    c.hi[0][l] = c.lo[0][l];
    return "instance boxes: node 0 lane " + std::to_string(l) + ": box [";
  });
}

TEST_F(HostileCulling, InstanceBoxLaneEmptiedUnderAFilledBvhLane) {
  box_case([](fmt::CullNode<kW>& c, const fmt::WideNode<kW>& bvh) {
    const int l = widest_lane(bvh);
    c.child[l] = fmt::ChildRef::kEmpty;
    return "instance boxes: node 0 lane " + std::to_string(l) + ": child 4294967295, the instance BVH's is " +
           std::to_string(bvh.child[l]);
  });
}

// A voxel grid whose cells no longer cover its triangles (every pooled leaf cut to its lowest cell: each
// stays a well-formed leaf, so every structural and cheap check passes) would cull rays that hit. The
// tracers check the cheap invariants only (the grid's box, its structure); --verify re-voxelizes.
TEST_F(HostileCulling, VoxelGridThatNoLongerCoversItsTriangles) {
  const std::string p = copy(bases().forest);
  {
    const PackageReader r(p);
    EXPECT_EQ(inspect_package(r, {.verify = true}).listed, std::vector<std::string>{}) << "the intact package is sound";
  }
  uint64_t leaves = 0;
  patch_chunk(p, chunk_of(p, fmt::ChunkKind::kDagPool, 0).first, [&](uint8_t* chunk, size_t) {
    uint64_t* mask = section<uint64_t>(chunk, SectionType::kDagLeaves, &leaves);
    for (uint64_t k = 0; k < leaves; ++k) mask[k] &= ~mask[k] + 1;
  });
  ASSERT_GT(leaves, 0u) << "the forest package has no pooled leaves";
  const std::vector<std::string> needles = {"batching point", "meets cells its voxel grid does not set"};
  expect_inspect_problem(p, needles, true);
  const ToolResult v = run_tool("rtpack-inspect", {"--verify", p}, dir, {}, 20);
  EXPECT_EQ(v.code, 3) << v.err;
  EXPECT_TRUE(contains_all(v.out, needles)) << v.out;
}

// One case per invariant voxel::check_dags enforces (SPEC §4.5), each in a valid-CRC package: every reader
// refuses it at decode (the tracers name the DAG pool, inspect the descriptors; both name the point).
struct DagCase {
  const char* name;
  bool boxes;  // forest_boxes (an instance-box grid) instead of forest (a voxel grid of R >= 16)
  bool pool;   // edits the pool (nodes may be shared), not the grid
  // Edits the chosen grid `g` (its index `p`), the pool's words, leaves and cull nodes; returns the message.
  std::function<std::string(fmt::DagGrid* grids, uint64_t p, uint32_t* words, uint64_t* leaves, uint8_t* cull)> edit;
};

TEST_F(HostileCulling, EveryDagPoolInvariantIsCheckedAtDecode) {
  constexpr uint32_t nb = uint32_t(fmt::cull_node_bytes(kW));
  const std::vector<DagCase> cases = {
      {"cell", false, false,
       [](fmt::DagGrid* g, uint64_t p, uint32_t*, uint64_t*, uint8_t*) {
         g[p].cell = -1;
         return std::string("cell size is not a positive finite number");
       }},
      {"origin", false, false,
       [](fmt::DagGrid* g, uint64_t p, uint32_t*, uint64_t*, uint8_t*) {
         g[p].origin[2] = std::numeric_limits<float>::quiet_NaN();
         return std::string("origin is not finite");
       }},
      {"extent", false, false,
       [](fmt::DagGrid* g, uint64_t p, uint32_t*, uint64_t*, uint8_t*) {
         g[p].cell = 3e38f;
         return std::string("grid extent is not finite (in float)");
       }},
      {"margin", false, false,
       [](fmt::DagGrid* g, uint64_t p, uint32_t*, uint64_t*, uint8_t*) {
         g[p].margin = -1;
         return std::string("margin or ray_rel is negative or not finite");
       }},
      {"root", false, false,
       [](fmt::DagGrid* g, uint64_t p, uint32_t*, uint64_t*, uint8_t*) {
         g[p].root = 0x7FFFFFF0u;
         return std::string("node at word 2147483632");
       }},
      {"masks", false, true,
       [](fmt::DagGrid* g, uint64_t p, uint32_t* w, uint64_t*, uint8_t*) {
         w[g[p].root] |= 1u << 24;
         return std::string(": malformed masks");
       }},
      {"inline above level 1", false, true,
       [](fmt::DagGrid* g, uint64_t p, uint32_t* w, uint64_t*, uint8_t*) {
         const uint32_t word = w[g[p].root],
                        c = uint32_t(std::countr_zero(fmt::dag_child_mask(word) & ~fmt::dag_full_mask(word)));
         w[g[p].root] |= 1u << (16 + c);
         return std::string(": inline leaves above level 1");
       }},
      {"leaf", false, true,
       [](fmt::DagGrid*, uint64_t, uint32_t*, uint64_t* leaves, uint8_t*) {
         leaves[0] = 0;
         return std::string("leaf 0 is empty or full");
       }},
      {"box grid fields", true, false,
       [](fmt::DagGrid* g, uint64_t p, uint32_t*, uint64_t*, uint8_t*) {
         g[p].cell = 1;
         return std::string("instance boxes: origin, cell, margin and ray_rel must be 0");
       }},
      {"box root", true, false,
       [](fmt::DagGrid* g, uint64_t p, uint32_t*, uint64_t*, uint8_t*) {
         g[p].root = 0xFFFFFFu;
         return std::string("instance boxes: first node 16777215 out of range");
       }},
      {"box node reached twice", true, true,
       [](fmt::DagGrid* g, uint64_t p, uint32_t*, uint64_t*, uint8_t*) {
         for (uint64_t q = p + 1;; ++q)
           if (g[q].resolution == fmt::kDagBoxes) {
             g[q].root = g[p].root;
             return "instance boxes: node " + std::to_string(g[p].root) + " reached twice";
           }
       }},
      {"box scale", true, true,
       [](fmt::DagGrid* g, uint64_t p, uint32_t*, uint64_t*, uint8_t* cull) {
         reinterpret_cast<fmt::CullNode<kW>*>(cull + uint64_t(g[p].root) * nb)->scale[0] = -1;
         return "instance boxes: node " + std::to_string(g[p].root) +
                " has a non-finite origin or a negative or non-finite scale";
       }},
      {"box child before its parent", true, true,
       [](fmt::DagGrid* g, uint64_t p, uint32_t*, uint64_t*, uint8_t* cull) {
         auto* n = reinterpret_cast<fmt::CullNode<kW>*>(cull + uint64_t(g[p].root) * nb);
         for (int l = 0; l < kW; ++l)
           if (!fmt::ChildRef::is_empty(n->child[l]) && !fmt::ChildRef::is_leaf(n->child[l])) {
             n->child[l] = 0;
             return "instance boxes: node " + std::to_string(g[p].root) + " lane " + std::to_string(l) + " references node " +
                    std::to_string(g[p].root);
           }
         return std::string("no inner lane");
       }},
  };
  for (const DagCase& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string p = copy(c.boxes ? bases().forest_boxes : bases().forest);
    const size_t descs = chunk_of(p, fmt::ChunkKind::kBatchingPoints, 0).first,
                 pool = chunk_of(p, fmt::ChunkKind::kDagPool, 0).first;
    std::vector<uint8_t> grid_bytes;  // the descriptors chunk is patched after the pool, from a copy
    uint64_t point = 0, n = 0;
    {
      PackageReader r(p);
      AlignedBytes b = r.read(descs);
      const fmt::DagGrid* g = section<fmt::DagGrid>(b.data(), SectionType::kPointGrids, &n);
      while (point < n &&
             !(c.boxes ? g[point].resolution == fmt::kDagBoxes : g[point].resolution >= 16 && g[point].root < fmt::kDagEmpty))
        ++point;
      ASSERT_LT(point, n) << "no grid for this case";
      grid_bytes.assign(reinterpret_cast<const uint8_t*>(g), reinterpret_cast<const uint8_t*>(g + n));
    }
    auto* grids = reinterpret_cast<fmt::DagGrid*>(grid_bytes.data());
    std::string message;
    patch_chunk(p, pool, [&](uint8_t* chunk, size_t) {
      message = c.edit(grids, point, section<uint32_t>(chunk, SectionType::kDagNodes),
                       section<uint64_t>(chunk, SectionType::kDagLeaves), section<uint8_t>(chunk, SectionType::kCullNodes));
    });
    patch_chunk(p, descs, [&](uint8_t* chunk, size_t) {
      std::memcpy(section<fmt::DagGrid>(chunk, SectionType::kPointGrids), grid_bytes.data(), grid_bytes.size());
    });
    // A grid field names its point; a pool edit names the first point that reaches the edited node or leaf.
    const std::string which = "batching point " + (c.pool ? std::string() : std::to_string(point));
    expect_everywhere(p, {which, message});
  }
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
