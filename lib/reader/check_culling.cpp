#include "reader/check_culling.h"

#include "core/error.h"

namespace rtp {
namespace {

bool point_without_bounds(const fmt::BatchingPointDesc& d) {
  return !(d.lo[0] <= d.hi[0] && d.lo[1] <= d.hi[1] && d.lo[2] <= d.hi[2]);
}

}  // namespace

std::string grid_cover_problem(const fmt::DagGrid& g, const fmt::BatchingPointDesc& d) {
  if (g.root == fmt::kDagEmpty && d.unique_triangles + d.instanced_triangles > 0)
    return "culling grid is empty (it culls every ray) but the point has " +
           std::to_string(d.unique_triangles + d.instanced_triangles) + " triangles";
  if (g.resolution == fmt::kDagBoxes || point_without_bounds(d)) return {};
  // Descriptor bounds and the grid are float: the comparison in double is exact.
  for (int a = 0; a < 3; ++a) {
    const double lo = g.origin[a], hi = double(g.origin[a]) + double(g.cell) * g.resolution;
    if (!(lo <= d.lo[a] && d.hi[a] <= hi))
      return "culling grid [" + std::to_string(lo) + ", " + std::to_string(hi) + "] on axis " + std::to_string(uint64_t(a)) +
             " does not contain the point's bounds [" + std::to_string(d.lo[a]) + ", " + std::to_string(d.hi[a]) + "]";
  }
  return {};
}

void check_grids_cover_points(const fmt::DagGrid* grids, const fmt::BatchingPointDesc* descs, uint64_t count,
                              const std::string& label) {
  for (uint64_t p = 0; p < count; ++p) {
    const std::string e = grid_cover_problem(grids[p], descs[p]);
    if (!e.empty()) fail_invalid(label + ": batching point " + std::to_string(p) + ": " + e);
  }
}

template <int W>
void check_instance_boxes(const fmt::DagGrid& grid, const voxel::DagView& pool, const fmt::WideNode<W>* nodes, uint64_t n_nodes,
                          const std::string& label) {
  if (grid.resolution != fmt::kDagBoxes) return;
  // check_dags has put the grid's nodes inside the section; these must mirror the instance BVH.
  if (pool.cull_width != uint32_t(W) || grid.root > pool.cull_count || n_nodes > pool.cull_count - grid.root)
    fail_invalid(label + ": instance boxes: " + std::to_string(n_nodes) + " instance BVH nodes, the culling grid holds " +
                 std::to_string(grid.root <= pool.cull_count ? pool.cull_count - grid.root : 0) + " from node " +
                 std::to_string(grid.root));
  const auto* cull = static_cast<const fmt::CullNode<W>*>(pool.cull) + grid.root;
  for (uint64_t i = 0; i < n_nodes; ++i)
    for (int l = 0; l < W; ++l) {
      auto where = [&] { return label + ": instance boxes: node " + std::to_string(i) + " lane " + std::to_string(uint64_t(l)); };
      if (cull[i].child[l] != nodes[i].child[l])
        fail_invalid(where() + ": child " + std::to_string(cull[i].child[l]) + ", the instance BVH's is " +
                     std::to_string(nodes[i].child[l]));
      if (fmt::ChildRef::is_empty(nodes[i].child[l])) continue;
      for (int a = 0; a < 3; ++a) {
        const double lo = fmt::cull_plane(cull[i].origin[a], cull[i].scale[a], cull[i].lo[a][l]);
        const double hi = fmt::cull_plane(cull[i].origin[a], cull[i].scale[a], cull[i].hi[a][l]);
        if (!(lo <= nodes[i].lo[a][l] && nodes[i].hi[a][l] <= hi))
          fail_invalid(where() + ": box [" + std::to_string(lo) + ", " + std::to_string(hi) + "] on axis " +
                       std::to_string(uint64_t(a)) + " does not contain the instance BVH's [" +
                       std::to_string(nodes[i].lo[a][l]) + ", " + std::to_string(nodes[i].hi[a][l]) + "]");
      }
    }
}

template void check_instance_boxes<4>(const fmt::DagGrid&, const voxel::DagView&, const fmt::WideNode<4>*, uint64_t,
                                      const std::string&);
template void check_instance_boxes<8>(const fmt::DagGrid&, const voxel::DagView&, const fmt::WideNode<8>*, uint64_t,
                                      const std::string&);
template void check_instance_boxes<16>(const fmt::DagGrid&, const voxel::DagView&, const fmt::WideNode<16>*, uint64_t,
                                       const std::string&);

}  // namespace rtp
