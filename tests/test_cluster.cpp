// Batching points: every object in exactly one point, targets respected, segments, the 4-wide top
// level with consistent parent pointers and containing boxes.
#include <gtest/gtest.h>

#include <tbb/task_arena.h>

#include <cstring>
#include <set>

#include "cluster/cluster.h"
#include "gltf_builder.h"
#include "scene/import.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

void check_plan(const Scene& s, const Plan& p) {
  // Instances of instanced meshes: exactly once over all points.
  std::vector<int> seen(s.instances.size(), 0);
  for (const auto& bp : p.points)
    for (uint32_t i : bp.instances) {
      ASSERT_TRUE(p.mesh_instanced[s.instances[i].mesh]);
      ++seen[i];
    }
  for (size_t i = 0; i < s.instances.size(); ++i)
    EXPECT_EQ(seen[i], p.mesh_instanced[s.instances[i].mesh] ? 1 : 0) << "instance " << i;
  // Pieces: exactly once over all points, and together exactly the triangles of their instance,
  // in the mesh's local space.
  std::vector<int> piece_seen(p.pieces.size(), 0);
  for (const auto& bp : p.points)
    for (uint32_t k : bp.pieces) ++piece_seen[k];
  for (int c : piece_seen) EXPECT_EQ(c, 1);
  std::map<uint32_t, std::vector<int>> covered;
  for (const auto& piece : p.pieces) {
    const Mesh& src = s.meshes[s.instances[piece.instance].mesh];
    auto& cov = covered[piece.instance];
    cov.resize(src.triangle_count());
    for (size_t t = 0; t < piece.mesh.triangle_count(); ++t) {
      const uint32_t orig = piece.prim[t];
      ++cov[orig];
      for (int k = 0; k < 3; ++k)
        EXPECT_EQ(piece.mesh.positions[piece.mesh.indices[3 * t + size_t(k)]], src.positions[src.indices[3 * orig + size_t(k)]]);
      EXPECT_EQ(piece.mesh.source[t].triangle, src.source[orig].triangle);
    }
  }
  for (size_t i = 0; i < s.instances.size(); ++i) {
    if (p.mesh_instanced[s.instances[i].mesh]) continue;
    ASSERT_TRUE(covered.count(uint32_t(i)));
    for (int c : covered[uint32_t(i)]) EXPECT_EQ(c, 1);
  }
  // Targets: a point over the target holds a single object.
  for (const auto& bp : p.points) {
    const uint64_t w = p.chunk_by == ChunkBy::kInstanced ? bp.unique_triangles + bp.instanced_triangles
                                                         : bp.unique_triangles + bp.instances.size();
    if (w > p.chunk_target) {
      EXPECT_EQ(bp.pieces.size() + bp.instances.size(), 1u);
    }
  }
  // Segments: every instanced mesh in exactly one.
  for (size_t m = 0; m < s.meshes.size(); ++m) {
    if (!p.mesh_instanced[m]) continue;
    ASSERT_NE(p.mesh_segment[m], kNoIndex);
    const auto& seg = p.segments[p.mesh_segment[m]].meshes;
    EXPECT_EQ(std::count(seg.begin(), seg.end(), uint32_t(m)), 1);
  }
  // Top level: each point referenced once; parents consistent; boxes contain the points' bounds.
  std::vector<int> ref(p.points.size(), 0);
  for (size_t n = 0; n < p.top.size(); ++n) {
    const fmt::TopNode& node = p.top[n];
    if (n == 0) {
      EXPECT_EQ(node.parent, fmt::TopNode::kEmpty);
    } else {
      EXPECT_EQ(p.top[node.parent].child[node.slot], uint32_t(n));
    }
    for (int l = 0; l < 4; ++l) {
      const uint32_t c = node.child[l];
      if (c == fmt::TopNode::kEmpty) continue;
      if (c & fmt::TopNode::kLeafBit) {
        const auto& bp = p.points[c & ~fmt::TopNode::kLeafBit];
        ++ref[c & ~fmt::TopNode::kLeafBit];
        for (int a = 0; a < 3; ++a) {
          EXPECT_LE(double(node.lo[a][l]), bp.bounds.lo[a]);
          EXPECT_GE(double(node.hi[a][l]), bp.bounds.hi[a]);
        }
      } else {
        EXPECT_EQ(p.top[c].parent, uint32_t(n));
        EXPECT_EQ(p.top[c].depth, node.depth + 1);
      }
    }
  }
  for (int r : ref) EXPECT_EQ(r, 1);
}

TEST(Cluster, GallerySmallTargetManyPoints) {
  const Scene s = import_gltf((source_dir() / "samples/generated/gallery.glb").string());
  ClusterOptions o;
  o.chunk_target = 2000;
  const Plan p = plan_batching_points(s, o);
  EXPECT_GT(p.points.size(), 4u);
  EXPECT_TRUE(p.pieces.empty());     // every gallery mesh is used at least twice: all instanced
  EXPECT_EQ(p.segments.size(), 5u);  // 15k triangles in segments of at most 2000 (one mesh each here)
  check_plan(s, p);
}

// The default segment target comes from the instanced meshes' own triangles, not from the instanced
// total that sizes batching points: forest-2k's trees (205k unique triangles, 10^8 instanced) go in
// several segments of at most 2^16 triangles (unless one mesh is larger), not in one of 1.6M.
TEST(Cluster, SegmentTargetFollowsTheSegmentsOwnTriangles) {
  const std::filesystem::path path = shared_assets() / "scenes/forest-2k.glb";
  RTP_NEED_SHARED(path);
  const Scene s = import_gltf(path.string());
  const Plan p = plan_batching_points(s, {});
  EXPECT_GT(p.chunk_target, uint64_t(1) << 20);
  uint64_t in_segments = 0;
  for (const auto& seg : p.segments) {
    in_segments += seg.triangles;
    if (seg.meshes.size() > 1) {
      EXPECT_LE(seg.triangles, uint64_t(1) << 16);
    }
  }
  EXPECT_GE(p.segments.size(), in_segments >> 16) << in_segments << " triangles in segments";
  EXPECT_GT(p.segments.size(), 1u);
  check_plan(s, p);
  ClusterOptions o;  // an explicit target still wins
  o.segment_target = uint64_t(1) << 30;
  EXPECT_EQ(plan_batching_points(s, o).segments.size(), 1u);
}

TEST(Cluster, LanternPiecesSplitAtFractionOfTarget) {
  const Scene s = import_gltf((source_dir() / "samples/khronos/Lantern/glTF/Lantern.gltf").string());
  ClusterOptions o;
  o.chunk_target = 1000;  // pieces of at most 250 triangles
  const Plan p = plan_batching_points(s, o);
  for (const auto& piece : p.pieces) EXPECT_LE(piece.mesh.triangle_count(), 250u);
  EXPECT_GE(p.pieces.size(), 5394u / 250u);
  EXPECT_TRUE(p.segments.empty());
  check_plan(s, p);
}

TEST(Cluster, ForestByInstancedVsUnique) {
  const Scene s = import_gltf((source_dir() / "samples/generated/forest-small.glb").string());
  ClusterOptions o;
  o.chunk_target = 200000;
  const Plan inst = plan_batching_points(s, o);
  o.chunk_by = ChunkBy::kUnique;
  o.chunk_target = 500;  // instances per point in unique mode
  const Plan uniq = plan_batching_points(s, o);
  check_plan(s, inst);
  check_plan(s, uniq);
  EXPECT_GT(inst.points.size(), 1u);
  EXPECT_GT(uniq.points.size(), 1u);
  EXPECT_FALSE(inst.segments.empty());
}

TEST(Cluster, DeterministicAndDerivedTarget) {
  const Scene s = import_gltf((source_dir() / "samples/generated/forest-small.glb").string());
  const Plan a = plan_batching_points(s, {}), b = plan_batching_points(s, {});
  EXPECT_EQ(a.chunk_target, default_chunk_target(s, ChunkBy::kInstanced));
  ASSERT_EQ(a.points.size(), b.points.size());
  for (size_t i = 0; i < a.points.size(); ++i) EXPECT_EQ(a.points[i].instances, b.points[i].instances);
  ASSERT_EQ(a.top.size(), b.top.size());
  EXPECT_EQ(std::memcmp(a.top.data(), b.top.data(), a.top.size() * sizeof(fmt::TopNode)), 0);
}

TEST(Cluster, DegenerateAllObjectsAtOnePoint) {
  GltfBuilder gb = one_triangle();
  std::vector<int> roots;
  roots.reserve(300);
  for (int i = 0; i < 300; ++i) roots.push_back(gb.add_node({{"mesh", 0}}));
  gb.set_scene(roots);
  const auto dir = temp_dir("cluster_degenerate");
  const Scene s = import_gltf(gb.write_glb(dir / "d.glb"));
  ClusterOptions o;
  o.chunk_target = 7;
  const Plan p = plan_batching_points(s, o);
  EXPECT_GE(p.points.size(), 300u / 7u + 1u);
  for (const auto& bp : p.points) EXPECT_LE(bp.instances.size(), 7u);
  check_plan(s, p);
  std::filesystem::remove_all(dir);
}

// 10^5 instances: the first levels of the cut are binned and partitioned in parallel and the subtrees
// cut by several tasks; the plan is complete and the same in an arena of 1 thread as of 2.
TEST(Cluster, ParallelCutIsCompleteAndTheSameForAnyThreadCount) {
  GltfBuilder gb = one_triangle();
  constexpr size_t kInstances = 100000;
  std::vector<float> t(3 * kInstances);
  uint64_t x = 12345;
  for (float& v : t) {
    x = x * 6364136223846793005ull + 1442695040888963407ull;
    v = float(double(x >> 11) / double(uint64_t(1) << 53) * 1000.0);
  }
  t[3 * 777] = t[3 * 778];  // two instances at the same place
  t[3 * 777 + 1] = t[3 * 778 + 1];
  t[3 * 777 + 2] = t[3 * 778 + 2];
  const int acc = gb.add_accessor(gb.add_view(t), 5126, "VEC3", kInstances);
  gb.j["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {{"TRANSLATION", acc}};
  const auto dir = temp_dir("cluster_parallel");
  const Scene s = import_gltf(gb.write_glb(dir / "many.glb"));
  ASSERT_EQ(s.instances.size(), kInstances);
  ClusterOptions o;
  o.chunk_target = 64;
  auto plan_with = [&](int threads) {
    tbb::task_arena arena(threads);
    return arena.execute([&] { return plan_batching_points(s, o); });
  };
  const Plan one = plan_with(1), two = plan_with(2);
  EXPECT_GT(one.points.size(), kInstances / 64);
  check_plan(s, one);
  ASSERT_EQ(one.points.size(), two.points.size());
  for (size_t i = 0; i < one.points.size(); ++i) {
    ASSERT_EQ(one.points[i].instances, two.points[i].instances) << "point " << i;
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(one.points[i].bounds.lo[a], two.points[i].bounds.lo[a]);
      EXPECT_EQ(one.points[i].bounds.hi[a], two.points[i].bounds.hi[a]);
    }
  }
  ASSERT_EQ(one.top.size(), two.top.size());
  EXPECT_EQ(std::memcmp(one.top.data(), two.top.data(), one.top.size() * sizeof(fmt::TopNode)), 0);
  std::filesystem::remove_all(dir);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
