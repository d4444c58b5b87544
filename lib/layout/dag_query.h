#pragma once
// Reading a package's sparse voxel DAGs (formats/dag.h, SPEC §4.5): the structural check every DAG
// passes before a ray reads it, and the interval-clipped ray/DAG test of the culling step (Molenaar
// 2019 §3.2). Part of the reader library: no dependency beyond formats/. Building DAGs is lib/voxel.
#include <cstdint>
#include <string>

#include "formats/dag.h"
#include "formats/ray_file.h"

namespace rtp::voxel {

// A read-only view of a pool (from a package chunk or a DagPool).
struct DagView {
  const uint32_t* words = nullptr;
  uint64_t word_count = 0;
  const uint64_t* leaves = nullptr;
  uint64_t leaf_count = 0;
  // Version 7.0: the instance-box proxies' nodes (section kCullNodes), fmt::WideNode<cull_width>[].
  const void* cull = nullptr;
  uint64_t cull_count = 0;
  uint32_t cull_width = 0;  // the package's BVH width W
};

// Structural check of one grid's DAG: resolution, cell, every reference in range, node sizes, no
// empty node or leaf; for an instance-box grid (fmt::kDagBoxes): every inner child after its parent and
// in range, no node reached twice. Returns "" when sound, else what is wrong. Cost: O(nodes reachable).
std::string check_dag(const fmt::DagGrid& grid, const DagView& pool);
// The same for every grid of a pool at once (nodes shared by several grids are checked once):
// "" or "batching point N: <problem>".
std::string check_dags(const fmt::DagGrid* grids, uint64_t count, const DagView& pool);
// Bytes of the unique nodes and leaves reachable from the grid's root (the size of this DAG built
// alone, before sharing with other batching points).
uint64_t dag_reachable_bytes(const fmt::DagGrid& grid, const DagView& pool);

// Result of the ray/DAG test: culled, or a lower bound t_entry >= tnear on the entry distance of every
// set cell the ray meets within [tnear, tfar] (so every hit of the grid's geometry has t >= t_entry).
// The reference returns the exact smallest entry distance.
struct DagHit {
  bool culled = true;
  double t_entry = 0;
};
// The cell growth the ray test uses for this ray (SPEC §4.5).
double dag_ray_growth(const fmt::DagGrid& grid, const double org[3]);
// Front-to-back DFS over the DAG with the eight child boxes tested together, clipped to
// [tnear, tfar] (fixed stack, no allocation); for an instance-box grid, culled or t_entry = tnear.
// Requires check_dag() to have passed.
DagHit dag_first_entry(const fmt::DagGrid& grid, const DagView& pool, const double org[3], const double dir[3], double tnear,
                       double tfar);
// Molenaar 2019 §4.2, as both package tracers apply it before walking a batching point's BVH: false
// when the ray is culled; otherwise ray.tnear is raised to the entry distance rounded down to float
// (no hit of the point's geometry lies before it).
// An instance-box grid culls the ray when it meets no instance box within [tnear, tfar] (boxes grown
// by a relative 1e-5, so every box the float kernels may hit counts) and leaves tnear as it is.
bool dag_enter(const fmt::DagGrid& grid, const DagView& pool, fmt::Ray& ray);

}  // namespace rtp::voxel
