// TESTING.md item 8 at the unit level, for instances (Molenaar 2019 §4.2): a batching point's culling
// grid holds every cell its instances' triangles touch — through the glTF's own double transforms,
// with no margin — and no cell farther from them than the coarse occupancy it is built from can
// explain. Scenes: the committed instanced samples (far.glb places instances far from the origin) and
// the shared forest when it is there; several batching points each.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "bvh/bvh.h"
#include "cluster/cluster.h"
#include "gltf_builder.h"
#include "mesh/prepare.h"
#include "scene/import.h"
#include "voxel/point_voxels.h"
#include "voxel_cells.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;
using voxel::Grid;

// Every cell a mesh's triangles touch through an instance's double transform, with no margin.
void touch_mesh(Grid& g, const Instance& in, const Mesh& m) {
  const auto world = [&](size_t k) { return in.transform.apply(to_d(m.positions[m.indices[k]])); };
  for (size_t k = 0; k + 2 < m.indices.size(); k += 3) voxel::voxelize_triangle(g, world(k), world(k + 1), world(k + 2), 0.0);
}

// Marks in `out` every cell within `reach` cells (Chebyshev) of one set in `src`.
void dilate_into(Grid& out, const Grid& src, int reach) {
  const int last = int(src.resolution) - 1;
  for_each_cell(src, [&](uint32_t x, uint32_t y, uint32_t z) {
    const int c[3] = {int(x), int(y), int(z)};
    int f[3], l[3];
    for (int k = 0; k < 3; ++k) f[k] = std::max(c[k] - reach, 0), l[k] = std::min(c[k] + reach, last);
    out.mark_cells(f, l);
  });
}

struct Totals {
  uint64_t points = 0, instances = 0, touched = 0, set = 0, missing = 0, far_out = 0;
};

// Dilation (Chebyshev) of the touched cells by `reach` cells: where a cell set by an instance's coarse
// occupancy may lie. An occupied local cell holds a triangle (within its margin), and the level is
// chosen so that its cells span about two grid cells (rotated: up to sqrt(3) times that), so no set cell
// is farther than 4 cells from a touched one; 5 leaves one for the margins.
constexpr int kReach = 5;

Totals check_scene(const std::string& path, uint64_t points_wanted) {
  Scene scene = import_gltf(path);
  prepare_scene(scene, {});
  ClusterOptions co;
  co.chunk_target = std::max<uint64_t>(64, scene.instanced_triangles() / points_wanted);
  const Plan plan = plan_batching_points(scene, co);
  const voxel::MeshProxies proxies(scene, plan);
  const std::vector<fmt::InstanceRecord> records = make_instance_records(scene.instances);
  Totals t;
  for (size_t p = 0; p < plan.points.size(); ++p) {
    const BatchingPoint& bp = plan.points[p];
    if (bp.instances.empty()) continue;
    // Pieces voxelize triangle by triangle (VoxelVoxelize.*): a point of instances only isolates the
    // instance path; a mixed point is judged on its instances' cells only (the pieces' add cells).
    const voxel::PointProxy px = voxel::voxelize_point(scene, plan, proxies, records.data(), bp, {});
    const voxel::DagView view{px.dag.words.data(), px.dag.words.size(), px.dag.leaves.data(), px.dag.leaves.size()};
    const Grid got = voxel::decode_dag(px.grid, view);
    const Vec3d origin{px.grid.origin[0], px.grid.origin[1], px.grid.origin[2]};
    Grid touched(origin, px.grid.cell, px.grid.resolution), near(origin, px.grid.cell, px.grid.resolution);
    for (const uint32_t i : bp.instances) touch_mesh(touched, scene.instances[i], scene.meshes[scene.instances[i].mesh]);
    Grid pieces(origin, px.grid.cell, px.grid.resolution);  // a piece's cells are set where its triangles are
    for (const uint32_t k : bp.pieces) touch_mesh(pieces, scene.instances[plan.pieces[k].instance], plan.pieces[k].mesh);
    for_each_cell(touched, [&](uint32_t x, uint32_t y, uint32_t z) {
      ++t.touched;
      if (!got.get(x, y, z)) {
        if (t.missing < 5)
          ADD_FAILURE() << path << " point " << p << ": cell (" << x << ", " << y << ", " << z
                        << ") touched by an instance's triangle is not set";
        ++t.missing;
      }
    });
    dilate_into(near, touched, kReach);
    dilate_into(near, pieces, 1);  // pieces: within their margin, one cell
    for_each_cell(got, [&](uint32_t x, uint32_t y, uint32_t z) {
      ++t.set;
      if (!near.get(x, y, z)) {
        if (t.far_out < 5)
          ADD_FAILURE() << path << " point " << p << ": cell (" << x << ", " << y << ", " << z << ") is set, more than " << kReach
                        << " cells from any triangle of the point";
        ++t.far_out;
      }
    });
    ++t.points;
    t.instances += bp.instances.size();
  }
  std::printf("[ instances ] %-16s %3llu points, %6llu instances: %8llu cells touched, %8llu set, %llu missing, %llu too far\n",
              fs::path(path).filename().string().c_str(), (unsigned long long)t.points, (unsigned long long)t.instances,
              (unsigned long long)t.touched, (unsigned long long)t.set, (unsigned long long)t.missing,
              (unsigned long long)t.far_out);
  return t;
}

TEST(VoxelInstances, PointGridsHoldEveryCellTheirInstancesTouch) {
  const fs::path s = source_dir() / "samples/generated";
  std::vector<std::pair<std::string, uint64_t>> scenes = {
      {(s / "forest-small.glb").string(), 12}, {(s / "gallery.glb").string(), 12}, {(s / "far.glb").string(), 8}};
  const fs::path forest = source_dir() / "../shared/assets/scenes/forest-2k.glb";
  // ~4 s of the test's 6 at -O2: not under the sanitizers (RTP_SANITIZED, scripts/test).
  if (!fs::exists(forest) && shared_assets_required()) ADD_FAILURE() << forest << " is absent, and RTP_REQUIRE_SHARED is set";
  if (fs::exists(forest) && std::getenv("RTP_SANITIZED") == nullptr) scenes.emplace_back(forest.string(), 64);
  for (const auto& [path, points] : scenes) {
    const Totals t = check_scene(path, points);
    EXPECT_GT(t.points, 0u) << path << ": no batching point holds instances";
    EXPECT_GT(t.touched, 0u) << path;
    EXPECT_EQ(t.missing, 0u) << path;
    EXPECT_EQ(t.far_out, 0u) << path;
    // The coarse occupancy costs cells (a box per occupied local cell: 2.0-2.2x the touched cells on the
    // forests and the gallery, 4.8x on far.glb's few), but it is not "set everything".
    EXPECT_LT(t.set, 8 * t.touched) << path;
  }
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
