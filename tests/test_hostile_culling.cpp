// Culling that cannot drop a hit (lib/reader/check_culling.h, formats/SPEC.md §4.5, §4.6): a batching
// point's culling grid that would cull rays its geometry is hit by is refused by every reader when it
// decodes it. Each case was an exit-0 wrong answer with --cull before (an empty root on a point of 968
// triangles: 0 hits instead of 978); now the tracer, rtpack-trace (with and without --cull),
// rtpack-inspect and --verify exit 3 naming the chunk and the field.
#include <gtest/gtest.h>

#include <algorithm>

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

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
