#pragma once
// rtpack-inspect --verify: culling cannot drop a hit (formats/SPEC.md §4.5). Every triangle a batching
// point traces, placed in world space by its instance record, must lie in set cells of the point's voxel
// grid: an independent check of the converter's conservative voxelization, read straight from the DAG.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "formats/bvh_layout.h"
#include "formats/chunk.h"
#include "formats/dag.h"
#include "layout/dag_query.h"

namespace rtp {

// Whether every cell of the voxel grid (resolution != kDagBoxes) that the triangle (world space, double)
// overlaps is set, each cell shrunk by a quarter of the grid's margin (the converter set every cell within
// `margin` of the triangle, so rounding here cannot refuse a sound grid). A triangle reaching outside the
// grid is not covered. Requires voxel::check_dag to have passed. Cost: O(cells overlapped × levels).
bool dag_covers_triangle(const fmt::DagGrid& grid, const voxel::DagView& pool, const double tri[3][3]);

// The leaf triangles of one mesh as its chunk stores them (padding lanes included), 9 floats each.
struct MeshTriangles {
  std::vector<float> xyz;      // v0, v1, v2 per triangle
  std::vector<uint32_t> prim;  // its index in the mesh
  static constexpr size_t kGroup = 64;
  std::vector<float> group_box;  // lo[3], hi[3] of each kGroup triangles (their finite coordinates)
};
template <int B>
void append_triangles(const fmt::LeafBlock<B>* blocks, uint64_t count, MeshTriangles& out);

// One batching point's geometry against its voxel grid: every triangle of every piece (`pieces[entry]`)
// and of every instanced mesh (`meshes`, by scene mesh id; a mesh whose segment was not read is skipped),
// placed in world space by the record of each local instance. "" or the first triangle not covered, named
// by local instance, mesh and prim.
std::string point_coverage_problem(const fmt::DagGrid& grid, const voxel::DagView& pool, const fmt::InstanceRecord* records,
                                   uint64_t n_records, const uint32_t* slots, uint64_t n_slots,
                                   const std::vector<MeshTriangles>& pieces, const std::map<uint32_t, MeshTriangles>& meshes);

}  // namespace rtp
