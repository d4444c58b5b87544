// lib/bvh mesh BVHs on procedural and degenerate meshes: layout validity (test_bvh_check.h), depth
// limits, determinism across thread counts, option and input errors.
#include <gtest/gtest.h>
#include <oneapi/tbb/global_control.h>

#include <cmath>
#include <cstring>
#include <random>

#include "bvh/bvh.h"
#include "core/error.h"
#include "mesh/shapes.h"
#include "test_bvh_check.h"
#include "test_widths.h"

namespace rtp {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using bvhtest::check_mesh_bvh;

using test::for_each_config;

constexpr BuildMethod kMethods[] = {BuildMethod::kCollapse, BuildMethod::kSplit};

std::string config_name(int w, int b, BuildMethod m) {
  return "W=" + std::to_string(w) + " B=" + std::to_string(b) + " " + method_name(m);
}

// Builds and checks `mesh` for every (W, B) and both methods.
void check_all(const Mesh& mesh, BuildOptions options = {}) {
  for (BuildMethod m : kMethods) {
    options.method = m;
    for_each_config([&]<int W, int B>() {
      const MeshBvh<W, B> bvh = build_mesh_bvh<W, B>(mesh, options);
      check_mesh_bvh<W, B>(mesh, bvh, options.max_depth, mesh.name + " " + config_name(W, B, m));
    });
  }
}

Mesh from_triangles(const std::string& name, const std::vector<std::array<Vec3f, 3>>& tris) {
  Mesh m;
  m.name = name;
  for (const auto& t : tris) {
    for (const Vec3f& v : t) {
      m.indices.push_back(uint32_t(m.positions.size()));
      m.positions.push_back(v);
    }
  }
  return m;
}

TEST(BvhBuild, ProceduralMeshes) {
  Mesh tet = make_tetrahedron();
  tet.name = "tetrahedron";
  check_all(tet);
  Mesh cube = make_cube();
  cube.name = "cube";
  check_all(cube);
  Mesh sphere = make_icosphere(4);  // 5120 triangles
  sphere.name = "icosphere4";
  check_all(sphere);
  Mesh grid = make_grid(60, 40);  // 4800 triangles, flat (zero-thickness boxes)
  grid.name = "grid";
  check_all(grid);
}

TEST(BvhBuild, EmptyAndSingleTriangle) {
  Mesh empty;
  empty.name = "empty";
  check_all(empty);
  const MeshBvh<8, 8> e = build_mesh_bvh<8, 8>(empty);
  EXPECT_EQ(e.root, fmt::ChildRef::kEmpty);
  EXPECT_EQ(e.stats.sah, 0.0);

  const Mesh one = from_triangles("one", {{Vec3f{0, 0, 0}, Vec3f{1, 0, 0}, Vec3f{0, 1, 0}}});
  check_all(one);
  const MeshBvh<8, 8> o = build_mesh_bvh<8, 8>(one);
  ASSERT_TRUE(fmt::ChildRef::is_leaf(o.root));  // a root leaf, no nodes
  EXPECT_EQ(fmt::ChildRef::block_count(o.root), 1u);
  EXPECT_TRUE(o.nodes.empty());
  EXPECT_EQ(o.stats.c_box, 0.0);
  EXPECT_EQ(o.stats.c_tri, 1.0);
}

TEST(BvhBuild, AllCentroidsEqual) {
  // Every triangle box is centred on the origin (lo = -hi), with different extents: no SAH plane
  // separates the centroids, so every split is a median on object index.
  std::vector<std::array<Vec3f, 3>> tris;
  for (int i = 0; i < 5000; ++i) {
    const float a = 1 + float(i % 97) * 0.25f, b = 0.5f + float(i % 31) * 0.125f, c = float(i % 7) * 0.5f;
    tris.push_back({Vec3f{-a, -b, 0}, Vec3f{a, 0, c}, Vec3f{0, b, -c}});
  }
  const Mesh m = from_triangles("same-centroid", tris);
  check_all(m);
  // Median splits halve exactly: the depth is the minimum for the leaf size.
  const MeshBvh<4, 4> bvh = build_mesh_bvh<4, 4>(m, {});
  EXPECT_LE(bvh.stats.max_depth, 11u);  // ⌈log2 ⌈5000/4⌉⌉ = 11 binary levels
}

TEST(BvhBuild, TenThousandIdenticalTriangles) {
  std::vector<std::array<Vec3f, 3>> tris(10000, {Vec3f{0.25f, 1, 2}, Vec3f{3, 1.5f, 2}, Vec3f{1, 4, -2}});
  const Mesh m = from_triangles("identical", tris);
  check_all(m);
  BuildOptions o;
  o.max_depth = 16;  // ⌈log2(10000 / leaf_size)⌉ <= 12 fits
  check_all(m, o);
}

TEST(BvhBuild, ZeroAreaAndNeedleTriangles) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-100, 100);
  std::vector<std::array<Vec3f, 3>> tris;
  for (int i = 0; i < 3000; ++i) {
    const Vec3f p{u(rng), u(rng), u(rng)};
    switch (i % 4) {
      case 0: tris.push_back({p, p, p}); break;                                                // a point
      case 1: tris.push_back({p, Vec3f{p.x + 1, p.y, p.z}, Vec3f{p.x + 2, p.y, p.z}}); break;  // collinear
      case 2: {                                                                                // needle
        const Vec3f q{u(rng) * 100, u(rng) * 100, u(rng) * 100};
        tris.push_back({p, q, Vec3f{q.x, std::nextafter(q.y, 1e9f), q.z}});
        break;
      }
      default: tris.push_back({p, Vec3f{p.x + 1, p.y, p.z}, Vec3f{p.x, p.y + 1, p.z + 1}});  // normal
    }
  }
  check_all(from_triangles("degenerate-mix", tris));
  // Every triangle the same point: SA(root) = 0.
  check_all(
      from_triangles("one-point", std::vector<std::array<Vec3f, 3>>(500, {Vec3f{1, 2, 3}, Vec3f{1, 2, 3}, Vec3f{1, 2, 3}})));
}

TEST(BvhBuild, HugeAndSignedZeroCoordinates) {
  std::vector<std::array<Vec3f, 3>> tris;
  const float big = 3e38f;
  for (int i = 0; i < 400; ++i) {
    const float s = (i % 2) ? -1.0f : 1.0f, f = float(i) / 400;
    tris.push_back({Vec3f{s * big * f, -big, 0}, Vec3f{big * f, big, -0.0f}, Vec3f{-0.0f, s * big, big * f}});
  }
  check_all(from_triangles("huge", tris));
}

TEST(BvhBuild, DepthLimitHoldsOnGeometricSpacing) {
  // Triangles at x = 1.5^i: binned SAH peels off the far ones a few at a time, which would make a
  // deep tree; the depth budget switches to median splits in time.
  std::vector<std::array<Vec3f, 3>> tris;
  for (int i = 0; i < 200; ++i) {
    const float x = std::pow(1.5f, float(i));
    tris.push_back({Vec3f{x, 0, 0}, Vec3f{x * 1.01f, 1, 0}, Vec3f{x, 0, 1}});
  }
  const Mesh m = from_triangles("geometric", tris);
  for (uint32_t depth : {6u, 8u, 12u, 64u}) {
    BuildOptions o;
    o.max_depth = depth;
    check_all(m, o);
  }
  // With the default limit the SAH tree is deeper than the median tree would be: the limit bites.
  BuildOptions deep;
  deep.leaf_size = 1;
  const MeshBvh<4, 4> unconstrained = build_mesh_bvh<4, 4>(m, deep);
  deep.max_depth = 8;
  const MeshBvh<4, 4> limited = build_mesh_bvh<4, 4>(m, deep);
  EXPECT_GT(unconstrained.stats.max_depth, 8u);
  EXPECT_LE(limited.stats.max_depth, 8u);
  check_mesh_bvh<4, 4>(m, limited, 8, "geometric leaf_size=1 max_depth=8");
}

// Node and block arrays are byte-identical whatever the number of threads.
template <int W, int B>
void expect_same_for_any_thread_count(const Mesh& mesh, BuildOptions o) {
  MeshBvh<W, B> one, two;
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
    one = build_mesh_bvh<W, B>(mesh, o);
  }
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
    two = build_mesh_bvh<W, B>(mesh, o);
  }
  const std::string what = config_name(W, B, o.method);
  EXPECT_EQ(one.root, two.root) << what;
  ASSERT_EQ(one.nodes.size(), two.nodes.size()) << what;
  ASSERT_EQ(one.blocks.size(), two.blocks.size()) << what;
  EXPECT_EQ(std::memcmp(one.nodes.data(), two.nodes.data(), one.nodes.size() * sizeof(one.nodes[0])), 0) << what;
  EXPECT_EQ(std::memcmp(one.blocks.data(), two.blocks.data(), one.blocks.size() * sizeof(one.blocks[0])), 0) << what;
  EXPECT_EQ(std::memcmp(&one.stats, &two.stats, sizeof one.stats), 0) << what;
  check_mesh_bvh<W, B>(mesh, two, o.max_depth, what);
}

TEST(BvhBuild, DeterministicForAnyThreadCount) {
  Mesh sphere = make_icosphere(6);  // 81920 triangles
  sphere.name = "icosphere6";
  // Low thresholds so that this mesh exercises the parallel binning, the chunked partition and the
  // task recursion of every builder.
  BuildOptions o;
  o.task_threshold = 256;
  o.parallel_threshold = 2048;
  for (BuildMethod m : kMethods) {
    o.method = m;
    expect_same_for_any_thread_count<4, 4>(sphere, o);
    expect_same_for_any_thread_count<8, 4>(sphere, o);
    expect_same_for_any_thread_count<16, 16>(sphere, o);
  }
  // And with identical centroids (median path under parallelism).
  std::vector<std::array<Vec3f, 3>> tris(20000, {Vec3f{0, 0, 0}, Vec3f{1, 0, 0}, Vec3f{0, 1, 0}});
  const Mesh same = from_triangles("identical", tris);
  o.method = BuildMethod::kCollapse;
  expect_same_for_any_thread_count<8, 8>(same, o);
}

TEST(BvhBuild, StatsAreSane) {
  Mesh sphere = make_icosphere(5);  // 20480 triangles
  for (BuildMethod m : kMethods) {
    BuildOptions o;
    o.method = m;
    const MeshBvh<16, 16> a = build_mesh_bvh<16, 16>(sphere, o);
    const MeshBvh<4, 4> b = build_mesh_bvh<4, 4>(sphere, o);
    // Wider nodes: fewer, shallower, and a lower box cost.
    EXPECT_LT(a.stats.nodes, b.stats.nodes);
    EXPECT_LT(a.stats.max_depth, b.stats.max_depth);
    EXPECT_LT(a.stats.c_box, b.stats.c_box);
    EXPECT_GT(a.stats.branching, 4.0) << method_name(m);
    // Benthin 2008 §4.4: with a-priori collapse the leaves are well filled.
    EXPECT_GT(a.stats.leaf_fill, 0.5) << method_name(m);
  }
  // A larger leaf_size trades C_tri for fewer nodes.
  BuildOptions small, large;
  small.leaf_size = 4;
  large.leaf_size = 32;
  const MeshBvh<8, 8> s = build_mesh_bvh<8, 8>(sphere, small), l = build_mesh_bvh<8, 8>(sphere, large);
  EXPECT_LT(l.stats.nodes, s.stats.nodes);
  check_mesh_bvh<8, 8>(sphere, l, 64, "leaf_size 32");
}

TEST(BvhBuild, RejectsBadInputNamingTheMesh) {
  Mesh m = make_cube();
  m.name = "broken-cube";
  m.positions[3].y = std::numeric_limits<float>::quiet_NaN();
  try {
    (void)build_mesh_bvh<8, 8>(m);
    FAIL() << "NaN vertex accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ExitCode::kInputInvalid);
    EXPECT_NE(std::string(e.what()).find("broken-cube"), std::string::npos) << e.what();
  }
  m = make_cube();
  m.name = "bad-index";
  m.indices[7] = 99;
  try {
    (void)build_mesh_bvh<4, 4>(m);
    FAIL() << "index out of range accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ExitCode::kInputInvalid);
    EXPECT_NE(std::string(e.what()).find("bad-index"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("triangle 2"), std::string::npos) << e.what();
  }
  // A depth limit the mesh cannot meet even with median splits.
  Mesh sphere = make_icosphere(3);
  sphere.name = "tight-sphere";
  BuildOptions o;
  o.max_depth = 3;
  try {
    (void)build_mesh_bvh<4, 4>(sphere, o);
    FAIL() << "impossible depth limit accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ExitCode::kInputInvalid);
    EXPECT_NE(std::string(e.what()).find("tight-sphere"), std::string::npos) << e.what();
  }
}

TEST(BvhBuild, RejectsBadOptions) {
  const Mesh cube = make_cube();
  auto code_of = [&](BuildOptions o) {
    try {
      (void)build_mesh_bvh<8, 4>(cube, o);
    } catch (const Error& e) {
      return e.code();
    }
    return ExitCode::kOk;
  };
  BuildOptions o;
  o.leaf_size = 65;  // > 16 blocks of 4
  EXPECT_EQ(code_of(o), ExitCode::kUsage);
  o.leaf_size = 64;
  EXPECT_EQ(code_of(o), ExitCode::kOk);
  o = {};
  o.bins = 1;
  EXPECT_EQ(code_of(o), ExitCode::kUsage);
  o.bins = 65;
  EXPECT_EQ(code_of(o), ExitCode::kUsage);
  o = {};
  o.max_depth = 0;
  EXPECT_EQ(code_of(o), ExitCode::kUsage);
}

TEST(BvhBuild, LargestLeavesFitSixteenBlocks) {
  // leaf_size = 16·B: every leaf uses at most 16 blocks and the refs encode it.
  Mesh sphere = make_icosphere(4);
  sphere.name = "icosphere4";
  BuildOptions o;
  o.leaf_size = 16 * 4;
  for (BuildMethod m : kMethods) {
    o.method = m;
    const MeshBvh<8, 4> bvh = build_mesh_bvh<8, 4>(sphere, o);
    check_mesh_bvh<8, 4>(sphere, bvh, 64, std::string("leaf 64 ") + method_name(m));
    uint32_t most = 0;
    for (const auto& n : bvh.nodes)
      for (uint32_t c : n.child)
        if (fmt::ChildRef::is_leaf(c)) most = std::max(most, fmt::ChildRef::block_count(c));
    EXPECT_LE(most, 16u);
    EXPECT_GE(most, 9u);  // leaves of more than 8 blocks do occur
  }
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp
