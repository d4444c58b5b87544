#pragma once
// Culling that cannot drop a hit (formats/SPEC.md §4.5, §4.6): the cheap checks of a batching point's
// culling grid against what it culls, run by every reader at decode. The structural checks of the DAGs
// themselves are voxel::check_dags (lib/layout/dag_query.h).
#include <cstdint>
#include <string>

#include "formats/bvh_layout.h"
#include "formats/chunk.h"
#include "formats/dag.h"
#include "layout/dag_query.h"

namespace rtp {

// A grid against its point's descriptor: a voxel grid's box contains the point's bounds, and a root that
// culls every ray (kDagEmpty) belongs to a point without triangles. "" or what is wrong.
std::string grid_cover_problem(const fmt::DagGrid& grid, const fmt::BatchingPointDesc& desc);
// The same for every point, O(points); throws Error(kInputInvalid) "LABEL: batching point P: ...".
void check_grids_cover_points(const fmt::DagGrid* grids, const fmt::BatchingPointDesc* descs, uint64_t count,
                              const std::string& label);

// An instance-box grid (resolution kDagBoxes) against its point's instance BVH (sections 15-16), node for
// node: the same children, and every filled lane's decoded box containing the BVH lane's box, so the
// proxy never culls a ray the instance walk could hit. O(nodes); throws naming node and lane.
template <int W>
void check_instance_boxes(const fmt::DagGrid& grid, const voxel::DagView& pool, const fmt::WideNode<W>* nodes, uint64_t n_nodes,
                          const std::string& label);

}  // namespace rtp
