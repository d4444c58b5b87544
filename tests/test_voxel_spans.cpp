// A batching point's triangles are voxelized in spans on several threads, each into a grid of its
// own, then merged (lib/voxel/point_voxels.cpp): the merge is the union of the cells, and the point's
// proxy is the same for any number of threads and holds every cell its triangles touch.
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <bit>
#include <filesystem>
#include <string>
#include <vector>

#include "bvh/bvh.h"
#include "cluster/cluster.h"
#include "core/error.h"
#include "gltf_builder.h"
#include "mesh/prepare.h"
#include "scene/import.h"
#include "voxel/point_voxels.h"
#include "voxel_cells.h"
#include "voxel_rng.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;
using voxel::Grid;

TEST(VoxelGrid, MergeIsTheUnionOfTheCells) {
  Rng rng(77);
  const Vec3d origin{-1, -2, -3};
  const double cell = 0.125;
  const uint32_t res = 64;  // 2 x 2 x 2 bricks of 32^3 cells
  Grid all(origin, cell, res), first(origin, cell, res), second(origin, cell, res);
  const double lo = -1, hi = -1 + cell * res;
  for (int t = 0; t < 400; ++t) {
    Vec3d v[3];
    const Vec3d c{rng.range(lo, hi), rng.range(lo - 1, hi - 1), rng.range(lo - 2, hi - 2)};
    for (Vec3d& p : v) p = c + Vec3d{rng.range(-0.4, 0.4), rng.range(-0.4, 0.4), rng.range(-0.4, 0.4)};
    voxel::voxelize_triangle(all, v[0], v[1], v[2], 0.01);
    voxel::voxelize_triangle(t % 3 ? first : second, v[0], v[1], v[2], 0.01);
  }
  ASSERT_GT(first.count(), 0u);
  ASSERT_GT(second.count(), 0u);
  ASSERT_LT(first.count(), all.count());  // each half alone misses cells: the merge has work to do
  Grid merged(origin, cell, res);
  merged.merge(first);   // into a grid without bricks
  merged.merge(second);  // into allocated bricks, and new ones
  EXPECT_EQ(merged.dense(), all.dense());
  EXPECT_EQ(merged.count(), all.count());
  Grid other_res(origin, cell, 32);
  EXPECT_THROW(merged.merge(other_res), Error);
}

// The largest batching point of `path` (default plan), voxelized in arenas of 1 and 3 threads: the same
// proxy, holding every cell its pieces' triangles touch (their glTF transforms in double, no margin)
// and no cell more than one cell (the margin) from one. Returns the touched cells.
uint64_t check_largest_point(const std::string& path) {
  Scene scene = import_gltf(path);
  prepare_scene(scene, {});
  const Plan plan = plan_batching_points(scene, {});
  if (plan.points.empty()) {
    ADD_FAILURE() << path << ": no batching point";
    return 0;
  }
  const BatchingPoint& bp = *std::max_element(plan.points.begin(), plan.points.end(), [](const auto& a, const auto& b) {
    return a.unique_triangles < b.unique_triangles;
  });
  EXPECT_GT(bp.unique_triangles, 2u * 8192u) << path << ": the point must span several voxelization units";
  const voxel::MeshProxies proxies(scene, plan);
  const std::vector<fmt::InstanceRecord> records = make_instance_records(scene.instances);
  auto voxelize_in = [&](int threads) {
    tbb::task_arena arena(threads);
    return arena.execute([&] { return voxel::voxelize_point(scene, plan, proxies, records.data(), bp, {}); });
  };
  const voxel::PointProxy one = voxelize_in(1), three = voxelize_in(3);
  EXPECT_EQ(one.dag.words, three.dag.words) << path;
  EXPECT_EQ(one.dag.leaves, three.dag.leaves) << path;
  EXPECT_EQ(one.set_cells, three.set_cells) << path;
  EXPECT_EQ(one.grid.root, three.grid.root) << path;

  const voxel::DagView view{three.dag.words.data(), three.dag.words.size(), three.dag.leaves.data(), three.dag.leaves.size()};
  const Grid got = voxel::decode_dag(three.grid, view);
  const Vec3d origin{three.grid.origin[0], three.grid.origin[1], three.grid.origin[2]};
  Grid touched(origin, three.grid.cell, three.grid.resolution), near(origin, three.grid.cell, three.grid.resolution);
  for (const uint32_t k : bp.pieces) {
    const UniquePiece& piece = plan.pieces[k];
    const Instance& in = scene.instances[piece.instance];
    const Mesh& m = piece.mesh;
    const auto world = [&](size_t i) { return in.transform.apply(to_d(m.positions[m.indices[i]])); };
    for (size_t i = 0; i + 2 < m.indices.size(); i += 3)
      voxel::voxelize_triangle(touched, world(i), world(i + 1), world(i + 2), 0.0);
  }
  uint64_t missing = 0, far = 0, n_touched = 0;
  for_each_cell(touched, [&](uint32_t x, uint32_t y, uint32_t z) {
    ++n_touched;
    if (!got.get(x, y, z) && missing++ < 5)
      ADD_FAILURE() << path << ": touched cell (" << x << ", " << y << ", " << z << ") is not set";
    int f[3] = {int(x) - 1, int(y) - 1, int(z) - 1}, l[3] = {int(x) + 1, int(y) + 1, int(z) + 1};
    for (int k = 0; k < 3; ++k) f[k] = std::max(f[k], 0), l[k] = std::min(l[k], int(near.resolution) - 1);
    near.mark_cells(f, l);
  });
  for_each_cell(got, [&](uint32_t x, uint32_t y, uint32_t z) {
    if (!near.get(x, y, z) && far++ < 5)
      ADD_FAILURE() << path << ": cell (" << x << ", " << y << ", " << z << ") is set, far from every triangle";
  });
  EXPECT_EQ(missing, 0u) << path;
  EXPECT_EQ(far, 0u) << path;
  EXPECT_EQ(got.count(), three.set_cells) << path;
  return n_touched;
}

// FlightHelmet's larger batching point: about 65k triangles in 8 pieces, a dozen spans of 8192.
TEST(VoxelPoint, SpansGiveTheSameProxyForAnyThreadCountAndEveryTouchedCell) {
  EXPECT_GT(check_largest_point((source_dir() / "samples/khronos/FlightHelmet/glTF/FlightHelmet.gltf").string()), 10000u);
}

// 20000 small triangles, one at each point of a lattice whose spacing is more than two cells: each
// touches cells no other triangle does, so a triangle a span boundary dropped would leave them unset
// (on a dense mesh its neighbours' cells would hide it).
TEST(VoxelPoint, SpansDropNoTriangleOfSeparatedOnes) {
  constexpr int kSide = 28, kTriangles = 20000;
  std::vector<float> xyz;
  for (int i = 0; i < kTriangles; ++i) {
    const float x = float(i % kSide), y = float(i / kSide % kSide), z = float(i / (kSide * kSide));
    xyz.insert(xyz.end(), {x, y, z, x + 0.05f, y, z, x, y + 0.05f, z});
  }
  GltfBuilder b;
  b.add_mesh(b.add_positions(xyz));  // not indexed: vertices in triangle order
  b.set_scene({b.add_node({{"mesh", 0}})});
  const fs::path dir = temp_dir("voxel_spans");
  const uint64_t touched = check_largest_point(b.write_glb(dir / "lattice.glb"));
  EXPECT_GE(touched, uint64_t(kTriangles));  // each triangle touches at least its own cell
  fs::remove_all(dir);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
