// lib/trace on two-level scenes built by a tiny test builder (test_trace_util.h): every ISA × order ×
// (W, B) gives the scalar octant-stack answer bit for bit; that answer agrees with brute force in double
// ray by ray; invalid rays (TESTING.md case 4), interval ends (case 5), empty scenes, malformed deep trees.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "mesh/shapes.h"
#include "test_trace_paths.h"
#include "test_trace_util.h"
#include "test_widths.h"

namespace rtp {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using namespace trace_test;

using test::WB;
template <class T>
class TraceScene : public ::testing::Test {};
using test::AllWidths;
TYPED_TEST_SUITE(TraceScene, AllWidths);

// Rotation about a unit axis by `angle`, scaled by s (negative s mirrors), then moved by t.
Affine rotate_scale(std::array<double, 3> axis, double angle, double s, std::array<double, 3> t) {
  const double n = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
  const double x = axis[0] / n, y = axis[1] / n, z = axis[2] / n, c = std::cos(angle), q = std::sin(angle), C = 1 - c;
  const double r[9] = {c + x * x * C,     x * y * C - z * q, x * z * C + y * q, y * x * C + z * q, c + y * y * C,
                       y * z * C - x * q, z * x * C - y * q, z * y * C + x * q, c + z * z * C};
  Affine m{};
  for (int row = 0; row < 3; ++row) {
    for (int k = 0; k < 3; ++k) m[4 * row + k] = float(r[3 * row + k] * (k == 0 ? s : std::fabs(s)));
    m[4 * row + 3] = float(t[row]);
  }
  return m;
}

std::vector<Tri> random_soup(Rng& rng, int n) {
  std::vector<Tri> out;
  for (int i = 0; i < n; ++i) {
    Tri t;
    const float c[3] = {rng.range(-8, 8), rng.range(-8, 8), rng.range(-8, 8)};
    const float size = rng.range(0.1f, 3.0f);
    for (auto& v : t.v)
      for (int a = 0; a < 3; ++a) v[a] = c[a] + size * rng.range(-1, 1);
    if (i % 17 == 0) t.v[2] = t.v[1];                                     // zero area
    if (i % 23 == 0) t.v[2] = {t.v[0][0] + 1e-4f, t.v[0][1], t.v[0][2]};  // needle
    out.push_back(t);
  }
  for (int k = 0; k < 12; ++k) out.push_back(out[5]);  // identical overlapping triangles
  return out;
}

template <int W, int B>
TestScene<W, B> mixed_scene() {
  Rng rng(42);
  std::vector<std::vector<Tri>> meshes = {
      random_soup(rng, 300), soup(make_icosphere(2), 3.0, {0, 0, 0}), soup(make_cube(2.0), 1.0, {0, 0, 0}), {}};
  std::vector<TestInstance> inst = {
      {0, identity()},
      {1, translation(5, 0, 0)},
      {1, rotate_scale({1, 2, 3}, 0.7, 1.5, {-5, 3, 1})},
      {1, rotate_scale({0, 1, 0}, 0.3, -1.0, {0, -6, 0})},  // mirrored
      {2, rotate_scale({1, 1, 0}, 1.1, 0.8, {0, 0, 8})},
      {2, translation(3, 3, -7)},
      {3, identity()},                 // an instance of an empty mesh
      {1, translation(5, 0.5, 0.25)},  // overlaps instance 1
  };
  return build_scene<W, B>(std::move(meshes), std::move(inst));
}

// Random, inside, short and offset rays plus special direction components; every 41st ray invalid.
std::vector<fmt::Ray> mixed_rays(size_t n, uint64_t seed, size_t* invalid) {
  Rng rng(seed);
  std::vector<fmt::Ray> rays;
  *invalid = 0;
  const float centres[][3] = {{5, 0, 0}, {-5, 3, 1}, {0, -6, 0}, {0, 0, 8}, {3, 3, -7}};
  for (size_t i = 0; i < n; ++i) {
    fmt::Ray r{};
    const uint32_t kind = rng.below(4);
    float target[3];
    for (int a = 0; a < 3; ++a) target[a] = rng.range(-9, 9);
    if (kind == 1) {  // from inside a sphere or cube instance
      const float* c = centres[rng.below(5)];
      for (int a = 0; a < 3; ++a) r.org[a] = c[a] + rng.range(-0.5f, 0.5f), target[a] = r.org[a] + rng.range(-1, 1);
    } else {
      for (int a = 0; a < 3; ++a) r.org[a] = rng.range(-15, 15);
    }
    const float len = rng.range(0.25f, 4.0f);
    for (int a = 0; a < 3; ++a) r.dir[a] = (target[a] - r.org[a]) * len;
    if (rng.below(6) == 0) r.dir[rng.below(3)] = rng.below(2) ? 0.0f : -0.0f;
    if (rng.below(10) == 0) r.dir[rng.below(3)] = rng.below(2) ? 1e-40f : 1e-9f;
    r.tnear = kind == 2 ? rng.range(0, 0.3f) : 0.0f;
    r.tfar = kind == 3 ? rng.range(0.05f, 1.0f) : INFINITY;
    if (i % 41 == 40) {
      switch (rng.below(5)) {
        case 0: r.org[rng.below(3)] = NAN; break;
        case 1: r.dir[rng.below(3)] = -INFINITY; break;
        case 2: r.tnear = r.tfar + 1; break;
        case 3: r.tnear = INFINITY, r.tfar = INFINITY; break;
        default: r.tfar = NAN; break;
      }
      ++*invalid;
    }
    rays.push_back(r);
  }
  return rays;
}

TYPED_TEST(TraceScene, EveryPathEqualsScalarAndBruteForce) {
  constexpr int W = TypeParam::W, B = TypeParam::B;
  const TestScene<W, B> scene = mixed_scene<W, B>();
  size_t invalid = 0;
  const std::vector<fmt::Ray> rays = mixed_rays(6000, 7, &invalid);
  const PathResult ref = check_all_paths<W, B>(scene.view(), rays, "mixed scene");
  EXPECT_EQ(ref.closest_stats.invalid_rays, invalid);
  EXPECT_EQ(ref.any_stats.invalid_rays, invalid);
  int hits = 0, ties = 0, failures = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (!ray_is_valid_for_test(rays[i])) continue;
    const RefHit bf = brute_force(scene, rays[i]);
    hits += bf.instance != fmt::Hit::kNone;
    const int c = classify(scene, rays[i], ref.hits[i], bf);
    ties += c == 1;
    if (c == 2 && ++failures <= 5)
      ADD_FAILURE() << "ray " << i << ": t " << ref.hits[i].t << " instance " << ref.hits[i].instance << " prim "
                    << ref.hits[i].prim << " vs brute force t " << bf.t << " instance " << bf.instance << " prim " << bf.prim;
  }
  EXPECT_EQ(failures, 0);
  EXPECT_GT(hits, 1500);
  EXPECT_LE(ties, 6) << "classified edge ties";
}

// Row-major 3x3 part and translation as an Affine.
Affine affine(const std::array<float, 9>& l, std::array<float, 3> t) {
  return {l[0], l[1], l[2], t[0], l[3], l[4], l[5], t[1], l[6], l[7], l[8], t[2]};
}

// Issue 11: instances whose L^-1 is a signed permutation get their local ray from the world ray's
// (move_ray_by_axes) instead of the double products and a division. Every ISA and order must give what
// the general path (a view without AxisMoves) gives, bit for bit, also for rays with a zero component of
// org − T or dir (they fall back) and rays on which the instance's translation plane lies.
TYPED_TEST(TraceScene, AxisMovesEqualTheGeneralTransformBitForBit) {
  constexpr int W = TypeParam::W, B = TypeParam::B;
  Rng rng(5);
  std::vector<std::vector<Tri>> meshes = {random_soup(rng, 200), soup(make_icosphere(2), 2.0, {0.25, 0, 0})};
  const std::array<float, 3> t0{2, 0, -3}, t1{-6, 4, 1}, t2{0, -5, 6};
  std::vector<TestInstance> inst = {
      {0, affine({0, -1, 0, 1, 0, 0, 0, 0, 1}, t0)},        // quarter turn about z
      {1, affine({-1, 0, 0, 0, 1, 0, 0, 0, -1}, t1)},       // half turn about y (Lantern's root node)
      {1, affine({-1, 0, 0, 0, 1, 0, 0, 0, 1}, t2)},        // mirror
      {0, affine({0, 0, 1, 1, 0, 0, 0, 1, 0}, {7, 7, 7})},  // axis cycle
      {1, translation(-3, -3, 5)},
      {1, identity()},                                     // moves no ray
      {0, rotate_scale({1, 2, 3}, 0.7, 1.5, {-5, 3, 1})},  // general
      {1, affine({0, 0, -1, 0, -1, 0, -1, 0, 0}, {1e5f, -2e5f, 3e5f})},
  };
  const TestScene<W, B> scene = build_scene<W, B>(std::move(meshes), std::move(inst));
  const std::vector<AxisMove> moves = axis_moves(scene.instances.data(), scene.instances.size());
  const uint8_t kinds[] = {AxisMove::kAxes, AxisMove::kAxes, AxisMove::kAxes,    AxisMove::kAxes,
                           AxisMove::kAxes, AxisMove::kNone, AxisMove::kGeneral, AxisMove::kAxes};
  ASSERT_EQ(moves.size(), std::size(kinds));
  for (size_t i = 0; i < moves.size(); ++i) EXPECT_EQ(moves[i].kind, kinds[i]) << "instance " << i;

  size_t invalid = 0;
  std::vector<fmt::Ray> rays = mixed_rays(4000, 11, &invalid);
  // Aimed at each instance, some from an origin on its translation planes, some with zero components.
  const std::array<float, 3> targets[] = {t0, t1, t2, {7, 7, 7}, {-3, -3, 5}, {1e5f, -2e5f, 3e5f}};
  for (int i = 0; i < 3000; ++i) {
    const std::array<float, 3>& c = targets[rng.below(std::size(targets))];
    fmt::Ray r{};
    for (int a = 0; a < 3; ++a) r.org[a] = c[a] + rng.range(-12, 12);
    if (i % 3 == 0) {  // on one of the instance's translation planes: org − T has a zero
      const uint32_t a = rng.below(3);
      r.org[a] = c[a];
    }
    for (int a = 0; a < 3; ++a) r.dir[a] = c[a] + rng.range(-2, 2) - r.org[a];
    if (i % 7 == 0) r.dir[rng.below(3)] = rng.below(2) ? 0.0f : -0.0f;
    r.tfar = INFINITY;
    rays.push_back(r);
  }
  SceneView<W, B> fast = scene.view();
  fast.moves = moves.data();
  const PathResult general = run_path<W, B>(scene.view(), rays, {Isa::kScalar, TraversalOrder::kOctantStack, 0});
  const PathResult got = check_all_paths<W, B>(fast, rays, "axis moves");
  int bad = 0, hits = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    const uint32_t id = general.hits[i].instance;
    hits += id != fmt::Hit::kNone && kinds[id] == AxisMove::kAxes;
    if ((!same_hit(got.hits[i], general.hits[i]) || got.occluded[i] != general.occluded[i]) && ++bad <= 5)
      ADD_FAILURE() << "ray " << i << ": t " << got.hits[i].t << " vs " << general.hits[i].t << ", instance "
                    << got.hits[i].instance << " vs " << general.hits[i].instance << ", prim " << got.hits[i].prim << " vs "
                    << general.hits[i].prim;
  }
  EXPECT_EQ(bad, 0);
  EXPECT_GT(hits, 1500) << "rays whose closest hit is on an instance moved by its axes";
}

// TESTING.md case 5: a hit exactly at tnear or at tfar counts, one ulp outside does not, through the
// instance transform (an exact translation) and both levels.
TYPED_TEST(TraceScene, HitsExactlyAtTnearAndTfar) {
  constexpr int W = TypeParam::W, B = TypeParam::B;
  Tri quad1{{{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}}}}, quad2{{{{-1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}}};
  const TestScene<W, B> scene = build_scene<W, B>({{quad1, quad2}}, {{0, translation(4, -2, 5)}, {0, translation(4, -2, 9)}});
  std::vector<fmt::Ray> rays;
  for (float dz : {1.0f, 2.0f, 0.5f}) {
    const float t = 5.0f / dz;  // the first quad, at world z = 5
    const fmt::Ray base{{4.25f, -2.5f, 0}, 0, {0, 0, dz}, INFINITY};
    for (auto [tn, tf] :
         {std::pair{t, t}, {0.0f, t}, {t, INFINITY}, {std::nextafter(t, INFINITY), INFINITY}, {0.0f, std::nextafter(t, 0.0f)}}) {
      fmt::Ray r = base;
      r.tnear = tn, r.tfar = tf;
      rays.push_back(r);
    }
  }
  const PathResult ref = check_all_paths<W, B>(scene.view(), rays, "interval ends");
  for (size_t k = 0; k < rays.size(); k += 5) {
    const float t = rays[k].tfar;
    EXPECT_EQ(ref.hits[k].t, t);
    EXPECT_EQ(ref.hits[k].instance, 0u);
    EXPECT_EQ(ref.hits[k + 1].t, t);
    EXPECT_EQ(ref.hits[k + 2].t, t);
    EXPECT_EQ(ref.hits[k + 3].instance, 1u) << "one ulp past the first quad: the second";
    EXPECT_EQ(ref.hits[k + 4].instance, fmt::Hit::kNone);
  }
}

// TESTING.md case 4: NaN/Inf anywhere, tnear > tfar, tnear = inf: misses, counted, never a hang.
TYPED_TEST(TraceScene, InvalidRaysAreCountedMisses) {
  constexpr int W = TypeParam::W, B = TypeParam::B;
  const TestScene<W, B> scene = mixed_scene<W, B>();
  std::vector<fmt::Ray> rays;
  const fmt::Ray good{{0, 0, -20}, 0, {0.01f, 0.02f, 1}, INFINITY};
  for (int c : {0, 1, 2, 4, 5, 6})  // org, dir
    for (float x : {NAN, INFINITY, -INFINITY}) {
      fmt::Ray r = good;
      (c < 3 ? r.org[c] : r.dir[c - 4]) = x;
      rays.push_back(r);
    }
  for (auto [tn, tf] :
       {std::pair{2.0f, 1.0f}, {INFINITY, INFINITY}, {0.0f, -INFINITY}, {NAN, NAN}, {NAN, 1.0f}, {0.0f, NAN}, {-INFINITY, NAN}}) {
    fmt::Ray r = good;
    r.tnear = tn, r.tfar = tf;
    rays.push_back(r);
  }
  rays.push_back(good);
  const PathResult ref = check_all_paths<W, B>(scene.view(), rays, "invalid rays");
  EXPECT_EQ(ref.closest_stats.invalid_rays, rays.size() - 1);
  for (size_t i = 0; i + 1 < rays.size(); ++i) {
    EXPECT_EQ(ref.hits[i].instance, fmt::Hit::kNone);
    EXPECT_EQ(ref.occluded[i], 0);
  }
  EXPECT_NE(ref.hits.back().instance, fmt::Hit::kNone) << "the valid ray hits the soup";
}

TYPED_TEST(TraceScene, EmptyScenesMiss) {
  constexpr int W = TypeParam::W, B = TypeParam::B;
  const TestScene<W, B> none = build_scene<W, B>({}, {});
  const TestScene<W, B> empty_mesh = build_scene<W, B>({{}}, {{0, identity()}});
  const std::vector<fmt::Ray> rays = {{{0, 0, 0}, 0, {1, 0, 0}, INFINITY}, {{1, 2, 3}, 0, {0, 0, 0}, INFINITY}};
  for (const auto* s : {&none, &empty_mesh}) {
    const PathResult r = check_all_paths<W, B>(s->view(), rays, "empty");
    for (const fmt::Hit& h : r.hits) EXPECT_EQ(h.instance, fmt::Hit::kNone);
  }
  // A zero direction is a valid ray that hits nothing, even inside a closed mesh.
  const TestScene<W, B> sphere = build_scene<W, B>({soup(make_icosphere(1), 1.0, {0, 0, 0})}, {{0, identity()}});
  const PathResult r = check_all_paths<W, B>(sphere.view(), {{{0, 0, 0}, 0, {0, 0, 0}, INFINITY}}, "zero dir");
  EXPECT_EQ(r.hits[0].instance, fmt::Hit::kNone);
  EXPECT_EQ(r.closest_stats.invalid_rays, 0u);
}

// A chain of `depth` inner nodes, each with every lane's box equal: lane 0 the next node, the other
// lanes leaves holding one triangle each at a distinct distance along +z (the last node: all leaves).
template <int W, int B>
TestScene<W, B> chain_scene(int depth) {
  TestScene<W, B> s = build_scene<W, B>({{}}, {{0, identity()}});
  auto& bvh = s.bvhs[0];
  s.meshes[0].clear();
  for (int d = 0; d < depth; ++d) {
    fmt::WideNode<W> n;
    for (int lane = 0; lane < W; ++lane) {
      for (int a = 0; a < 3; ++a) n.lo[a][lane] = -1, n.hi[a][lane] = 1000;
      if (lane == 0 && d + 1 < depth) {
        n.child[lane] = fmt::ChildRef::inner(uint32_t(d + 1));
        continue;
      }
      const uint32_t prim = uint32_t(s.meshes[0].size());
      const float z = 10.0f + float(prim);
      s.meshes[0].push_back({{{{-1, -1, z}, {1, -1, z}, {0, 1, z}}}});
      fmt::LeafBlock<B> blk;
      for (int k = 0; k < B; ++k) {
        for (int a = 0; a < 3; ++a)
          blk.v0[a][k] = s.meshes[0].back().v[0][a], blk.v1[a][k] = s.meshes[0].back().v[1][a],
          blk.v2[a][k] = s.meshes[0].back().v[2][a];
        blk.prim[k] = prim;
      }
      n.child[lane] = fmt::ChildRef::leaf(uint32_t(bvh.blocks.size()), 1);
      bvh.blocks.push_back(blk);
    }
    for (int o = 0; o < 8; ++o)
      for (int i = 0; i < W; ++i) n.order[o][i] = uint8_t(i);
    bvh.nodes.push_back(n);
  }
  bvh.root = fmt::ChildRef::inner(0);
  s.mesh_views[0] = {bvh.nodes.data(), bvh.blocks.data(), bvh.root};
  // The top level: a single leaf whose box is never tested (root = leaf).
  return s;
}

TYPED_TEST(TraceScene, DeepTreesWithinTheLimitAreExactBeyondItSafe) {
  constexpr int W = TypeParam::W, B = TypeParam::B;
  const std::vector<fmt::Ray> rays = {{{0, 0, 0}, 0, {0, 0, 1}, INFINITY}, {{0, 0, 0}, 0, {0, 0, 1}, 10.5f}};
  {
    const TestScene<W, B> s = chain_scene<W, B>(64);
    const PathResult r = check_all_paths<W, B>(s.view(), rays, "depth 64");
    EXPECT_EQ(r.hits[0].t, 10.0f);
    EXPECT_EQ(r.hits[0].prim, 0u);
    EXPECT_EQ(r.occluded[1], 1);
  }
  const TestScene<W, B> s = chain_scene<W, B>(300);
  for (const TraceOptions& opt : all_paths()) {
    const PathResult r = run_path<W, B>(s.view(), rays, opt);
    uint64_t misses = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      // Either the exact answer, or a miss counted as an overflow: never a crash or a wrong hit.
      if (r.hits[i].instance != fmt::Hit::kNone)
        EXPECT_EQ(r.hits[i].t, 10.0f);
      else
        ++misses;
    }
    EXPECT_EQ(r.closest_stats.overflow_rays, misses) << trace_test::path_name(opt);
  }
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp
