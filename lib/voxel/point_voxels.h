#pragma once
// A batching point's culling proxy: its geometry (pieces and instances, through the transforms the
// tracer uses) voxelized conservatively into the point's grid, then reduced to a DAG.
#include <cstdint>
#include <vector>

#include "cluster/cluster.h"
#include "formats/bvh_layout.h"
#include "voxel/voxel.h"

namespace rtp::voxel {

struct VoxelOptions {
  uint32_t resolution = 0;  // cells per axis; 0 = chosen per batching point (choose_resolution)
  bool thin = false;        // 6-separating, no margin: a test foil that must produce false culls
};

// "Model no more than a scene needs": R ≈ sqrt(T) / 2 cells per axis for T triangles (a surface of T
// triangles covers O(R^2) cells, so cells per triangle stay near 1/4 to 1), rounded to a power of two
// and clamped to [32, 512]. The bunny (69k triangles) gets 128^3, the seed's default. voxelize_point
// counts a point's unique triangles plus, per instance, at most 256 of its mesh's triangles; it halves
// any resolution (also a forced one) whose cells would be smaller than twice the point's margin.
uint32_t choose_resolution(uint64_t triangles);

// Coarse local occupancy of every instanced mesh (a pyramid 32^3 ... 1^3 of conservative voxels in
// its local bounds), built once per mesh in parallel: an instance is voxelized as the world boxes of
// the occupied local cells at the level that matches its size in the point's grid, so the cost per
// instance is bounded by the number of grid cells it covers, not by its triangles.
class MeshProxies {
 public:
  MeshProxies(const Scene& scene, const Plan& plan);
  struct Level {
    uint32_t r = 0;
    std::vector<uint32_t> cells;  // the occupied cells, x | y << 8 | z << 16, z, y, x ascending
  };
  struct Proxy {
    Aabb bounds;                // the mesh's local bounds (computed once, not per instance)
    Vec3d origin;               // local grid corner
    double cell = 0;            // finest local cell
    std::vector<Level> levels;  // r = 1, 2, 4, ..., 32
  };
  const Proxy& operator[](uint32_t mesh) const { return proxies_[mesh]; }

 private:
  std::vector<Proxy> proxies_;
};

struct PointProxy {
  fmt::DagGrid grid{};  // root is the LocalDag's until the pool remaps it
  LocalDag dag;
  uint64_t set_cells = 0;
  double work_seconds = 0;  // thread time spent (its triangle spans may run on several threads at once)
};

// The float-rounding bound (SPEC §4.5): with u = 2^-24 and an instance whose world->local map is
// M = [L^-1 | -L^-1·T] (SPEC §2.4: the tracer moves rays with it) and Minv its exact inverse, the world point the tracer
// reports for a hit lies within 16u·|Minv|·(|M_T| + 2|v|) + 16u·|Minv||M|·|org| of the instance's
// geometry Minv(v) (|·| infinity norms, M_T its translation, v the local vertices): the local ray is
// rounded to float (½u relative in origin and direction) and the watertight test decides within a
// few u of the larger of |org_local| and |v|; 16 leaves a factor of four. The first term is the
// grid's `margin`, the factor of |org| its `ray_rel`. `records`: make_instance_records of
// scene.instances, the records the tracer moves rays with (the points store them, SPEC §2.4).
PointProxy voxelize_point(const Scene& scene, const Plan& plan, const MeshProxies& meshes, const fmt::InstanceRecord* records,
                          const BatchingPoint& point, const VoxelOptions& options);

}  // namespace rtp::voxel
