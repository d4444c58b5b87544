// lib/bvh two-level in-core scenes: instance records, the instance BVH (every instance exactly once,
// boxes containing the transformed meshes), the SceneView wiring, determinism, degenerate instances.
#include <gtest/gtest.h>
#include <oneapi/tbb/global_control.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <vector>

#include "bvh/bvh.h"
#include "mesh/shapes.h"
#include "oracle/rays.h"
#include "scene/import.h"
#include "test_bvh_check.h"
#include "trace/trace.h"
#include "test_widths.h"

namespace rtp {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;
using bvhtest::DBox;
using fmt::ChildRef;
const fs::path kSamples = fs::path(RTP_SOURCE_DIR) / "samples";

// Exact world bounds of an instance: every vertex of its mesh through the stored float transform,
// evaluated in double.
DBox world_bounds(const Scene& s, const Instance& inst) {
  DBox b;
  const Mesh& m = s.meshes[inst.mesh];
  for (uint32_t v : m.indices) {
    const Vec3d w = inst.transform.apply(to_d(m.positions[v]));
    b.grow(w.x, w.y, w.z);
  }
  return b;
}

// Everything about an InCoreScene that must hold for `scene`. Returns the instances in the BVH.
template <int W, int B>
size_t check_scene(const Scene& scene, const InCoreScene<W, B>& ics, const BuildOptions& o, const std::string& what) {
  SCOPED_TRACE(what);
  const size_t ni = scene.instances.size();
  // Mesh BVHs and the view wiring.
  EXPECT_EQ(ics.mesh_count(), scene.meshes.size());
  const SceneView<W, B> v = ics.view();
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    bvhtest::check_mesh_bvh<W, B>(scene.meshes[m], ics.mesh(m), o.max_depth, what + " mesh " + std::to_string(m));
    EXPECT_EQ(v.meshes[m].nodes, ics.mesh(m).nodes.data());
    EXPECT_EQ(v.meshes[m].blocks, ics.mesh(m).blocks.data());
    EXPECT_EQ(v.meshes[m].root, ics.mesh(m).root);
    EXPECT_EQ(&ics.mesh_stats(m), &ics.mesh(m).stats);
  }
  EXPECT_EQ(v.top_nodes, ics.top().nodes.data());
  EXPECT_EQ(v.top_root, ics.top().root);
  EXPECT_EQ(v.top_instances, ics.top().items.data());
  EXPECT_EQ(v.instances, ics.instances().data());

  // Instance records (SPEC §2.4).
  EXPECT_EQ(ics.instances().size(), ni);
  std::vector<char> eligible(ni, 0);
  for (size_t i = 0; i < ni && i < ics.instances().size(); ++i) {
    const Instance& inst = scene.instances[i];
    const fmt::InstanceRecord& r = ics.instances()[i];
    for (int row = 0; row < 3; ++row) {
      EXPECT_EQ(r.translation[row], inst.transform(row, 3)) << "instance " << i;
    }
    EXPECT_EQ(r.mesh, inst.mesh);
    EXPECT_EQ(r.flags & 1u, inst.transform.det3() < 0 ? 1u : 0u) << "instance " << i;
    EXPECT_EQ((r.flags & 1u) != 0, inst.mirrored) << "instance " << i;
    EXPECT_EQ(r.flags & ~1u, 0u);
    EXPECT_EQ(r.reserved, 0u);
    const bool singular = std::abs(inst.transform.det3()) == 0;
    if (!singular) {
      // inverse_linear · L ≈ identity (the inverse was taken in double and rounded to float once).
      for (int row = 0; row < 3; ++row)
        for (int col = 0; col < 3; ++col) {
          double s = 0;
          for (int k = 0; k < 3; ++k) s += double(r.inverse_linear[row * 3 + k]) * inst.transform(k, col);
          const double expect = row == col ? 1 : 0;
          EXPECT_NEAR(s, expect, 1e-5) << "instance " << i << " (" << row << "," << col << ")";
        }
    }
    eligible[i] = !singular && scene.meshes[inst.mesh].triangle_count() > 0;
  }

  // The instance BVH: every eligible instance exactly once, boxes containing the transformed meshes.
  const BoxBvh<W>& top = ics.top();
  std::vector<char> seen(ni, 0), item_used(top.items.size(), 0);
  auto leaf = [&](uint32_t ref, uint64_t& count) -> DBox {
    DBox b;
    const uint32_t first = ChildRef::first_block(ref), n = ChildRef::block_count(ref);
    EXPECT_LE(n, 16u);
    EXPECT_LE(uint64_t(first) + n, top.items.size());
    if (uint64_t(first) + n > top.items.size()) return b;
    for (uint32_t k = first; k < first + n; ++k) {
      EXPECT_FALSE(item_used[k]) << "item " << k << " in two leaves";
      item_used[k] = 1;
      const uint32_t id = top.items[k];
      EXPECT_LT(id, ni);
      if (id >= ni) continue;
      EXPECT_TRUE(eligible[id]) << "instance " << id << " should not be in the instance BVH";
      EXPECT_FALSE(seen[id]) << "instance " << id << " twice";
      seen[id] = 1;
      b.grow(world_bounds(scene, scene.instances[id]));
    }
    count = n;
    return b;
  };
  const bvhtest::WalkResult w = bvhtest::walk_tree<W>(top.nodes, top.root, /*tight=*/false, 1, leaf);
  size_t in_bvh = 0;
  for (size_t i = 0; i < ni; ++i) {
    EXPECT_EQ(bool(seen[i]), bool(eligible[i])) << "instance " << i;
    in_bvh += seen[i] != 0;
  }
  for (size_t k = 0; k < item_used.size(); ++k) EXPECT_TRUE(item_used[k]) << "item " << k << " unreferenced";
  EXPECT_LE(w.max_depth, o.max_depth);
  const BvhStats& st = ics.top_stats();
  EXPECT_EQ(st.primitives, in_bvh);
  EXPECT_EQ(st.blocks, top.items.size());
  EXPECT_EQ(st.nodes, top.nodes.size());
  EXPECT_EQ(st.leaves, w.leaves);
  if (in_bvh) {
    EXPECT_DOUBLE_EQ(st.leaf_fill, 1.0);
    const double ra = w.root_area;
    EXPECT_NEAR(st.c_box, ra > 0 ? w.box_area_sum / ra : double(w.nodes), 1e-9 * std::max(1.0, st.c_box));
    EXPECT_NEAR(st.c_tri, ra > 0 ? w.leaf_cost_sum / ra : double(w.blocks), 1e-9 * std::max(1.0, st.c_tri));
  } else {
    EXPECT_EQ(top.root, ChildRef::kEmpty);
  }
  return in_bvh;
}

using test::for_each_config;

TEST(BvhScene, GalleryAllConfigs) {
  const Scene scene = import_gltf((kSamples / "generated/gallery.glb").string());
  ASSERT_GT(scene.instances.size(), 1u);
  for (BuildMethod m : {BuildMethod::kCollapse, BuildMethod::kSplit}) {
    BuildOptions o;
    o.method = m;
    for_each_config([&]<int W, int B>() {
      const InCoreScene<W, B> ics = InCoreScene<W, B>::build(scene, o);
      const size_t n =
          check_scene<W, B>(scene, ics, o, "gallery W=" + std::to_string(W) + " B=" + std::to_string(B) + " " + method_name(m));
      EXPECT_EQ(n, scene.instances.size());
      EXPECT_TRUE(ics.warnings().empty());
    });
  }
}

TEST(BvhScene, ForestSmallManyInstances) {
  const Scene scene = import_gltf((kSamples / "generated/forest-small.glb").string());
  ASSERT_GE(scene.instances.size(), 1000u);
  for (BuildMethod m : {BuildMethod::kCollapse, BuildMethod::kSplit}) {
    BuildOptions o;
    o.method = m;
    const InCoreScene<8, 8> ics = InCoreScene<8, 8>::build(scene, o);
    EXPECT_EQ((check_scene<8, 8>(scene, ics, o, std::string("forest ") + method_name(m))), scene.instances.size());
    EXPECT_GT(ics.top_stats().branching, 2.0);
  }
  BuildOptions four;
  four.top_leaf_size = 4;  // up to 4 instances per leaf
  const InCoreScene<16, 8> ics = InCoreScene<16, 8>::build(scene, four);
  check_scene<16, 8>(scene, ics, four, "forest top_leaf_size 4");
}

TEST(BvhScene, DegenerateInstances) {
  Scene s;
  s.meshes.push_back(make_cube());
  s.meshes.push_back(make_icosphere(2));
  s.meshes.push_back(Mesh{});  // no triangles
  s.meshes[2].name = "empty";
  auto add = [&](uint32_t mesh, const Mat4d& m) {
    Instance i;
    i.mesh = mesh;
    i.transform = Affine3x4::from(m);
    i.mirrored = m.det3() < 0;
    i.node = uint32_t(s.instances.size());
    s.instances.push_back(i);
  };
  const double t0[3] = {0, 0, 0}, q0[4] = {0, 0, 0, 1}, one[3] = {1, 1, 1};
  add(0, Mat4d::identity());
  const double t1[3] = {148376, 1234, -223423}, q1[4] = {0.2, -0.4, 0.1, 0.8888194417}, s1[3] = {3, 0.5, 2};
  add(1, Mat4d::from_trs(t1, q1, s1));  // far away, rotated, scaled
  const double mirror[3] = {-1, 1, 1};
  add(1, Mat4d::from_trs(t0, q0, mirror));  // mirrored
  const double flat[3] = {1, 1, 0};
  add(0, Mat4d::from_trs(t0, q0, flat));                              // singular: left out
  add(2, Mat4d::identity());                                          // empty mesh: left out
  for (int k = 0; k < 40; ++k) add(0, Mat4d::from_trs(t1, q0, one));  // 40 identical boxes
  for (BuildMethod m : {BuildMethod::kCollapse, BuildMethod::kSplit}) {
    BuildOptions o;
    o.method = m;
    const InCoreScene<4, 4> ics = InCoreScene<4, 4>::build(s, o);
    EXPECT_EQ((check_scene<4, 4>(s, ics, o, std::string("degenerate ") + method_name(m))), s.instances.size() - 2);
    ASSERT_EQ(ics.warnings().size(), 2u);
    EXPECT_NE(ics.warnings()[0].find("instance 3"), std::string::npos) << ics.warnings()[0];
    EXPECT_NE(ics.warnings()[1].find("instance 4"), std::string::npos) << ics.warnings()[1];
    EXPECT_EQ(ics.instances()[2].flags & 1u, 1u);
  }
}

TEST(BvhScene, MovedSceneKeepsValidViews) {
  const Scene scene = import_gltf((kSamples / "khronos/Lantern/glTF/Lantern.gltf").string());
  BuildOptions two_level;  // Lantern's parts would be merged in world space (test_trace_merged.cpp)
  two_level.merge_instances = false;
  InCoreScene<8, 8> a = InCoreScene<8, 8>::build(scene, two_level);
  const SceneView<8, 8> before = a.view();
  InCoreScene<8, 8> b = std::move(a);
  const SceneView<8, 8> after = b.view();
  EXPECT_EQ(before.top_nodes, after.top_nodes);
  EXPECT_EQ(before.meshes[0].nodes, after.meshes[0].nodes);
  check_scene<8, 8>(scene, b, two_level, "moved");
  // The merged build too: its parts table and merged mesh move with it.
  InCoreScene<8, 8> c = InCoreScene<8, 8>::build(scene);
  ASSERT_TRUE(c.flattened());
  const SceneView<8, 8> c_before = c.view();
  InCoreScene<8, 8> d = std::move(c);
  const SceneView<8, 8> c_after = d.view();
  EXPECT_EQ(c_before.meshes[3].nodes, c_after.meshes[3].nodes);
  EXPECT_EQ(c_before.part_first, c_after.part_first);
  EXPECT_EQ(c_before.direct, c_after.direct);
}

TEST(BvhScene, DeterministicForAnyThreadCount) {
  const Scene scene = import_gltf((kSamples / "generated/gallery.glb").string());
  BuildOptions o;
  o.task_threshold = 128;
  o.parallel_threshold = 1024;
  for (BuildMethod m : {BuildMethod::kCollapse, BuildMethod::kSplit}) {
    o.method = m;
    InCoreScene<16, 8> one, two;
    {
      tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
      one = InCoreScene<16, 8>::build(scene, o);
    }
    {
      tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
      two = InCoreScene<16, 8>::build(scene, o);
    }
    auto same = [](const auto& x, const auto& y) {
      return x.size() == y.size() && (x.empty() || std::memcmp(x.data(), y.data(), x.size() * sizeof(x[0])) == 0);
    };
    EXPECT_TRUE(same(one.top().nodes, two.top().nodes));
    EXPECT_TRUE(same(one.top().items, two.top().items));
    EXPECT_EQ(one.top().root, two.top().root);
    EXPECT_TRUE(same(one.instances(), two.instances()));
    for (size_t i = 0; i < one.mesh_count(); ++i) {
      EXPECT_TRUE(same(one.mesh(i).nodes, two.mesh(i).nodes)) << "mesh " << i;
      EXPECT_TRUE(same(one.mesh(i).blocks, two.mesh(i).blocks)) << "mesh " << i;
    }
  }
}

TEST(BvhScene, TransformBoundsContainCorners) {
  Box3f local;
  local.lo[0] = -1;
  local.lo[1] = -2;
  local.lo[2] = -0.5f;
  local.hi[0] = 1;
  local.hi[1] = 2;
  local.hi[2] = 0.5f;
  const double t[3] = {1e5, -3e6, 7}, q[4] = {0.5, 0.5, 0.5, 0.5}, sc[3] = {1e-3, 7, -2};
  const Affine3x4 m = Affine3x4::from(Mat4d::from_trs(t, q, sc));
  const Box3f w = transform_bounds(m, &local, 1);
  for (int c = 0; c < 8; ++c) {
    const Vec3d p{(c & 1) ? local.hi[0] : local.lo[0], (c & 2) ? local.hi[1] : local.lo[1], (c & 4) ? local.hi[2] : local.lo[2]};
    const Vec3d q2 = m.apply(p);
    for (int a = 0; a < 3; ++a) {
      EXPECT_LT(double(w.lo[a]), q2[a]);  // strictly: one extra float step outward
      EXPECT_GT(double(w.hi[a]), q2[a]);
    }
  }
}

// float_down / float_up are std::nextafter towards -inf / +inf, bit for bit: the special values and
// random bit patterns of every class (denormals, zeros of both signs, the largest finite, NaN).
TEST(BvhScene, FloatStepsAreNextafter) {
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<float> v = {0.0f,
                          -0.0f,
                          inf,
                          -inf,
                          std::numeric_limits<float>::max(),
                          -std::numeric_limits<float>::max(),
                          std::numeric_limits<float>::min(),
                          -std::numeric_limits<float>::min(),
                          std::numeric_limits<float>::denorm_min(),
                          -std::numeric_limits<float>::denorm_min(),
                          1.0f,
                          -1.0f,
                          3000000.25f,
                          -2000000.75f};
  std::mt19937 rng(11);
  for (int i = 0; i < 100000; ++i) v.push_back(std::bit_cast<float>(uint32_t(rng())));
  for (float x : v) {
    if (std::isnan(x)) {
      EXPECT_TRUE(std::isnan(float_down(x)) && std::isnan(float_up(x)));
      continue;
    }
    EXPECT_EQ(std::bit_cast<uint32_t>(float_down(x)), std::bit_cast<uint32_t>(std::nextafter(x, -inf))) << x;
    EXPECT_EQ(std::bit_cast<uint32_t>(float_up(x)), std::bit_cast<uint32_t>(std::nextafter(x, inf))) << x;
  }
}

// Issue 11: a scene whose only instance is the identity skips the instance level (SceneView::direct).
// The answers must be those of the two-level walk, bit for bit, for every query, ISA and order; any
// other transform, or a second instance, keeps the two levels.
TEST(InCoreSceneDirect, OneIdentityInstanceSkipsTheInstanceLevelWithTheSameAnswers) {
  Scene scene = import_gltf(RTP_SOURCE_DIR "/samples/khronos/Suzanne/glTF/Suzanne.gltf");
  ASSERT_EQ(scene.instances.size(), 1u);
  scene.instances[0].transform = Affine3x4{};
  const InCoreScene<8, 8> bvh = InCoreScene<8, 8>::build(scene);
  const SceneView<8, 8> direct = bvh.view();
  ASSERT_EQ(direct.direct, 0u);
  SceneView<8, 8> two_level = direct;
  two_level.direct = kNoDirectInstance;
  RayGenOptions g;
  g.seed = 4;
  g.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { trace_closest<8, 8>(two_level, r, h, n, TraceOptions{}); };
  std::vector<fmt::Ray> rays;
  for (RayKind k : kAllRayKinds) {
    const auto v = generate_rays(scene, k, 800, g);
    rays.insert(rays.end(), v.begin(), v.end());
  }
  const size_t n = rays.size();
  for (Isa isa : {Isa::kScalar, Isa::kAvx2, Isa::kAvx512}) {
    if (int(isa) > int(detect_isa())) continue;
    for (TraversalOrder order : {TraversalOrder::kOctantStack, TraversalOrder::kActiveList}) {
      const TraceOptions o{isa, order};
      std::vector<fmt::Hit> a(n), b(n), ma(8 * n), mb(8 * n);
      std::vector<uint8_t> oa(n), ob(n);
      std::vector<uint32_t> ca(n), cb(n);
      trace_closest<8, 8>(direct, rays.data(), a.data(), n, o);
      trace_closest<8, 8>(two_level, rays.data(), b.data(), n, o);
      trace_any<8, 8>(direct, rays.data(), oa.data(), n, o);
      trace_any<8, 8>(two_level, rays.data(), ob.data(), n, o);
      trace_multi<8, 8>(direct, rays.data(), n, 8, ma.data(), ca.data(), o);
      trace_multi<8, 8>(two_level, rays.data(), n, 8, mb.data(), cb.data(), o);
      const std::string what = std::string(isa_name(isa)) + " " + order_name(order);
      EXPECT_EQ(std::memcmp(a.data(), b.data(), n * sizeof(fmt::Hit)), 0) << what;
      EXPECT_EQ(oa, ob) << what;
      EXPECT_EQ(ca, cb) << what;
      EXPECT_EQ(std::memcmp(ma.data(), mb.data(), ma.size() * sizeof(fmt::Hit)), 0) << what;
      size_t hits = 0;
      for (const fmt::Hit& h : a) hits += h.t < INFINITY;
      EXPECT_GT(hits, n / 4) << what;
    }
  }
  // Not the identity, or not the only instance: two levels.
  Scene moved = scene;
  moved.instances[0].transform(0, 3) = 1e-3;
  EXPECT_EQ((InCoreScene<8, 8>::build(moved).view().direct), kNoDirectInstance);
  Scene scaled = scene;
  scaled.instances[0].transform(1, 1) = 2;
  EXPECT_EQ((InCoreScene<8, 8>::build(scaled).view().direct), kNoDirectInstance);
  Scene two = scene;
  two.instances.push_back(scene.instances[0]);
  EXPECT_EQ((InCoreScene<8, 8>::build(two).view().direct), kNoDirectInstance);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp
