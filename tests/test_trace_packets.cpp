// Issue 11 packets (Wu 2016): runs of P in {4, 8, 16} consecutive rays traced as packets give the
// single-ray answers bit for bit — camera tiles on a real sample and through rotated, mirrored and scaled
// instances, shadow rays as any hit, packets whose rays split over octants or carry invalid and
// degenerate rays — and the packet path is really taken (its counters), with its SIMD utilization.
// (test_trace_paths.h runs every packet size on every check_all_paths scene as well.)
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "bvh/bvh.h"
#include "core/error.h"
#include "mesh/shapes.h"
#include "oracle/rays.h"
#include "scene/import.h"
#include "trace/trace.h"
#include "test_trace_util.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using trace_test::simd_isas;

bool same(const fmt::Hit& a, const fmt::Hit& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// A sphere and a grid placed rotated, mirrored, scaled and translated, several times each.
Scene instanced_scene() {
  Scene s;
  s.meshes.push_back(make_icosphere(3));
  s.meshes.push_back(make_grid(12, 12));
  for (int k = 0; k < 9; ++k) {
    Instance in;
    in.mesh = k % 3 == 2 ? 1u : 0u;
    const double a = 0.7 * k, c = std::cos(a), sn = std::sin(a), scale = 0.5 + 0.25 * (k % 4);
    const double mirror = k % 4 == 1 ? -1.0 : 1.0;
    in.transform(0, 0) = scale * c * mirror, in.transform(0, 1) = -scale * sn;
    in.transform(1, 0) = scale * sn * mirror, in.transform(1, 1) = scale * c;
    in.transform(2, 2) = scale * (k % 3 == 2 ? 0.2 : 1.0);
    in.transform(0, 3) = 2.5 * (k % 3), in.transform(1, 3) = 2.5 * (k / 3), in.transform(2, 3) = 0.3 * k;
    in.mirrored = mirror < 0;
    s.instances.push_back(in);
  }
  s.bounds = Aabb{};
  for (const Instance& in : s.instances)
    for (uint32_t v : s.meshes[in.mesh].indices) s.bounds.grow(in.transform.apply(to_d(s.meshes[in.mesh].positions[v])));
  return s;
}

struct Answers {
  std::vector<fmt::Hit> hits;
  std::vector<uint8_t> occluded;
  TraceStats closest, any;
};

template <int W, int B>
Answers run(const SceneView<W, B>& view, const std::vector<fmt::Ray>& rays, const TraceOptions& o) {
  Answers a;
  a.hits.resize(rays.size());
  a.occluded.assign(rays.size(), 7);
  a.closest = trace_closest<W, B>(view, rays.data(), a.hits.data(), rays.size(), o);
  a.any = trace_any<W, B>(view, rays.data(), a.occluded.data(), rays.size(), o);
  return a;
}

// Every SIMD ISA and packet size against that ISA's single rays, ray by ray; at least `min_packet_share`
// of the rays went in packets, and their SIMD utilization (active rays per packet node test / P) is at
// least `above_floor` beyond the floor 3/P that the rule of kPacketMinActive (3) alone guarantees;
// with `packet_leaves`, closest-hit leaves were also tested by whole packets (triangle_packet.h).
template <int W, int B>
void expect_packets_equal_single(const SceneView<W, B>& view, const std::vector<fmt::Ray>& rays, const std::string& what,
                                 double above_floor, double min_packet_share, bool packet_leaves = false) {
  for (Isa isa : simd_isas()) {
    const Answers single = run<W, B>(view, rays, {isa, TraversalOrder::kOctantStack, 0});
    EXPECT_EQ(single.closest.packets, 0u);
    for (uint32_t p : {4u, 8u, 16u}) {
      const std::string path =
          what + " W=" + std::to_string(W) + " B=" + std::to_string(B) + " " + isa_name(isa) + " packets of " + std::to_string(p);
      const Answers got = run<W, B>(view, rays, {isa, TraversalOrder::kOctantStack, p});
      int bad = 0;
      for (size_t i = 0; i < rays.size() && bad < 5; ++i) {
        if (!same(got.hits[i], single.hits[i]))
          ++bad, ADD_FAILURE() << path << " ray " << i << ": t " << got.hits[i].t << " vs " << single.hits[i].t << ", instance "
                               << got.hits[i].instance << " vs " << single.hits[i].instance << ", prim " << got.hits[i].prim
                               << " vs " << single.hits[i].prim;
        if (got.occluded[i] != single.occluded[i])
          ++bad,
              ADD_FAILURE() << path << " ray " << i << ": occluded " << int(got.occluded[i]) << " vs " << int(single.occluded[i]);
      }
      EXPECT_EQ(got.closest.rays, rays.size()) << path;
      EXPECT_EQ(got.closest.invalid_rays, single.closest.invalid_rays) << path;
      EXPECT_EQ(got.closest.overflow_rays, 0u) << path;
      // The packet path was taken, by most rays, and its node tests kept lanes busy.
      EXPECT_GT(got.closest.packets, 0u) << path;
      EXPECT_GE(double(got.closest.packet_rays), min_packet_share * double(rays.size())) << path;
      EXPECT_LE(got.closest.packet_rays, got.closest.packets * p) << path;
      ASSERT_GT(got.closest.packet_node_tests, 0u) << path;
      const double utilization = double(got.closest.packet_active_lanes) / (double(got.closest.packet_node_tests) * p);
      EXPECT_LE(utilization, 1.0) << path;
      EXPECT_GE(utilization, std::min(1.0, 3.0 / p + above_floor)) << path;
      std::printf("%s: SIMD utilization %.1f%%, %.1f%% of the rays in packets\n", path.c_str(), 100 * utilization,
                  100.0 * double(got.closest.packet_rays) / double(rays.size()));
      EXPECT_GT(got.any.packets, 0u) << path;
      if (packet_leaves) {
        EXPECT_GT(got.closest.packet_triangle_tests, 0u) << path << ": no leaf tested by a packet";
      }
    }
  }
}

TEST(TracePackets, CameraTilesOnARealSampleEqualSingleRays) {
  if (simd_isas().empty()) GTEST_SKIP() << "no AVX2 on this CPU: packets are SIMD only";
  const Scene scene = import_gltf(RTP_SOURCE_DIR "/samples/khronos/FlightHelmet/glTF/FlightHelmet.gltf");
  const InCoreScene<8, 8> base = InCoreScene<8, 8>::build(scene);
  RayGenOptions gen;
  gen.seed = 9;
  gen.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { trace_closest<8, 8>(base.view(), r, h, n, {}); };
  // Primary rays come in 4x4 pixel tiles (oracle/rays.h): packets of 4, 8, 16 are 2x2-ish, 4x2, 4x4 tiles.
  const std::vector<fmt::Ray> primary = generate_rays(scene, RayKind::kPrimary, 4096, gen);
  const std::vector<fmt::Ray> shadow = generate_rays(scene, RayKind::kShadow, 2048, gen);
  size_t hits = 0;
  {
    std::vector<fmt::Hit> h(primary.size());
    trace_closest<8, 8>(base.view(), primary.data(), h.data(), primary.size(), {});
    for (const fmt::Hit& x : h) hits += x.instance != fmt::Hit::kNone;
  }
  EXPECT_GT(hits, primary.size() / 8) << "the camera must see the helmet";
  const InCoreScene<4, 4> w4 = InCoreScene<4, 4>::build(scene);
  const InCoreScene<16, 8> w16 = InCoreScene<16, 8>::build(scene);
  // Shadow rays toward one light from scattered hits are less coherent: fewer go in packets.
  expect_packets_equal_single<8, 8>(base.view(), primary, "FlightHelmet primary", 0.1, 0.9, true);
  expect_packets_equal_single<8, 8>(base.view(), shadow, "FlightHelmet shadow", 0.0, 0.1);
  expect_packets_equal_single<4, 4>(w4.view(), primary, "FlightHelmet primary", 0.1, 0.9, true);
  expect_packets_equal_single<16, 8>(w16.view(), primary, "FlightHelmet primary", 0.1, 0.9, true);
  expect_packets_equal_single<16, 8>(w16.view(), shadow, "FlightHelmet shadow", 0.0, 0.1);
}

TEST(TracePackets, PacketsThroughRotatedMirroredScaledInstancesEqualSingleRays) {
  if (simd_isas().empty()) GTEST_SKIP() << "no AVX2 on this CPU: packets are SIMD only";
  const Scene scene = instanced_scene();
  const InCoreScene<8, 8> bvh = InCoreScene<8, 8>::build(scene);
  RayGenOptions gen;
  gen.seed = 4;
  gen.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { trace_closest<8, 8>(bvh.view(), r, h, n, {}); };
  const std::vector<fmt::Ray> rays = generate_rays(scene, RayKind::kPrimary, 4096, gen);
  const std::vector<fmt::Ray> shadow = generate_rays(scene, RayKind::kShadow, 2048, gen);
  size_t hits = 0;
  {
    std::vector<fmt::Hit> h(rays.size());
    trace_closest<8, 8>(bvh.view(), rays.data(), h.data(), rays.size(), {});
    for (const fmt::Hit& x : h) hits += x.instance != fmt::Hit::kNone;
  }
  EXPECT_GT(hits, rays.size() / 8) << "the camera must see the instances";
  expect_packets_equal_single<8, 8>(bvh.view(), rays, "instances primary", 0.1, 0.9);
  expect_packets_equal_single<8, 8>(bvh.view(), shadow, "instances shadow", 0.0, 0.1);
  const InCoreScene<16, 16> w16 = InCoreScene<16, 16>::build(scene);
  expect_packets_equal_single<16, 16>(w16.view(), rays, "instances primary", 0.1, 0.9);
}

// A scene of one moved instance (a glTF root node with a transform, as BoomBox has) and one of an
// unmoved and a moved instance: the top level is one leaf, which packets enter without a world packet
// (trace_packet.h), making one only for the unmoved instance.
TEST(TracePackets, TopLevelOfOneLeafEqualsSingleRays) {
  if (simd_isas().empty()) GTEST_SKIP() << "no AVX2 on this CPU: packets are SIMD only";
  for (const bool with_unmoved : {false, true}) {
    Scene s;
    s.meshes.push_back(make_icosphere(3));
    Instance moved;
    const double c = std::cos(0.9), sn = std::sin(0.9);
    moved.transform(0, 0) = -0.8 * c, moved.transform(0, 1) = -0.8 * sn;  // mirrored, rotated, scaled
    moved.transform(1, 0) = -0.8 * sn, moved.transform(1, 1) = 0.8 * c;
    moved.transform(2, 2) = 0.5;
    moved.transform(0, 3) = 1.5, moved.transform(1, 3) = -0.25, moved.transform(2, 3) = 0.75;
    moved.mirrored = true;
    s.instances.push_back(moved);
    if (with_unmoved) s.instances.push_back(Instance{});
    s.bounds = Aabb{};
    for (const Instance& in : s.instances)
      for (uint32_t v : s.meshes[in.mesh].indices) s.bounds.grow(in.transform.apply(to_d(s.meshes[in.mesh].positions[v])));
    BuildOptions bo;
    bo.top_leaf_size = 2;  // both instances of the second scene in the one leaf
    const InCoreScene<8, 8> bvh = InCoreScene<8, 8>::build(s, bo);
    ASSERT_EQ(bvh.view().direct, kNoDirectInstance);
    ASSERT_TRUE(fmt::ChildRef::is_leaf(bvh.view().top_root));
    RayGenOptions gen;
    gen.seed = 6;
    gen.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { trace_closest<8, 8>(bvh.view(), r, h, n, {}); };
    const std::vector<fmt::Ray> rays = generate_rays(s, RayKind::kPrimary, 4096, gen);
    std::vector<fmt::Hit> h(rays.size());
    trace_closest<8, 8>(bvh.view(), rays.data(), h.data(), rays.size(), {});
    std::vector<size_t> per_instance(s.instances.size(), 0);
    for (const fmt::Hit& x : h)
      if (x.instance != fmt::Hit::kNone) ++per_instance.at(x.instance);
    for (size_t i = 0; i < per_instance.size(); ++i) EXPECT_GT(per_instance[i], rays.size() / 20) << "instance " << i;
    expect_packets_equal_single<8, 8>(bvh.view(), rays, with_unmoved ? "unmoved + moved primary" : "one moved primary", 0.1, 0.9);
  }
}

// Instances whose L^-1 is a signed permutation (a half turn about y as BoomBox's and Lantern's nodes, a
// quarter turn, a mirror, an axis cycle, a translation) move a packet's rays by permuting the world rays
// (move_ray_by_axes), lane by lane falling back to the double transform where a component of org - T or
// dir is zero. Packets must give the single rays' answers and the general transform's (a view without
// AxisMoves) bit for bit, as one instance under a one-leaf top level and as several under a tree.
TEST(TracePackets, SignedPermutationInstancesMovePacketsByTheirAxes) {
  if (simd_isas().empty()) GTEST_SKIP() << "no AVX2 on this CPU: packets are SIMD only";
  const double turns[][9] = {{-1, 0, 0, 0, 1, 0, 0, 0, -1},  // half turn about y
                             {0, -1, 0, 1, 0, 0, 0, 0, 1},   // quarter turn about z
                             {-1, 0, 0, 0, 1, 0, 0, 0, 1},   // mirror
                             {0, 0, 1, 1, 0, 0, 0, 1, 0},    // axis cycle
                             {1, 0, 0, 0, 1, 0, 0, 0, 1}};   // translation only
  for (const bool one : {true, false}) {
    Scene s;
    s.meshes.push_back(make_icosphere(3));
    s.meshes.push_back(make_grid(8, 8));
    for (int k = 0; k < (one ? 1 : 10); ++k) {
      Instance in;
      in.mesh = uint32_t(k % 2);
      const double* m = turns[k % 5];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) in.transform(r, c) = m[3 * r + c] * (k == 9 ? 0.25 : 1.0);
      // Instance 9's scale 0.25 makes L^-1 = 4 x a signed permutation: not one, the general path.
      in.transform(0, 3) = 2.5 * (k % 4), in.transform(1, 3) = 2.5 * (k / 4), in.transform(2, 3) = -0.5 * (k % 3);
      in.mirrored = k % 5 == 2;
      s.instances.push_back(in);
    }
    s.bounds = Aabb{};
    for (const Instance& in : s.instances)
      for (uint32_t v : s.meshes[in.mesh].indices) s.bounds.grow(in.transform.apply(to_d(s.meshes[in.mesh].positions[v])));
    const InCoreScene<8, 8> bvh = InCoreScene<8, 8>::build(s);
    const SceneView<8, 8> view = bvh.view();
    ASSERT_NE(view.moves, nullptr);
    ASSERT_EQ(view.moves[0].kind, AxisMove::kAxes);
    ASSERT_EQ(fmt::ChildRef::is_leaf(view.top_root), one);
    RayGenOptions gen;
    gen.seed = 12;
    gen.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { trace_closest<8, 8>(view, r, h, n, {}); };
    std::vector<fmt::Ray> rays = generate_rays(s, RayKind::kPrimary, 4096, gen);
    // Every 5th ray's origin on a translation plane of instance 0 (org - T has a zero: that lane alone
    // takes the general transform inside its packet).
    for (size_t i = 0; i < rays.size(); i += 5) rays[i].org[i % 3] = float(s.instances[0].transform(int(i % 3), 3));
    SceneView<8, 8> general = view;
    general.moves = nullptr;
    const Answers reference = run<8, 8>(general, rays, {Isa::kScalar, TraversalOrder::kOctantStack, 0});
    size_t on_axes = 0;
    for (const fmt::Hit& h : reference.hits)
      on_axes += h.instance != fmt::Hit::kNone && view.moves[h.instance].kind == AxisMove::kAxes;
    EXPECT_GT(on_axes, rays.size() / 8) << "closest hits on instances moved by their axes";
    for (Isa isa : simd_isas())
      for (uint32_t p : {4u, 8u, 16u}) {
        const std::string path =
            std::string(one ? "one instance" : "ten instances") + " " + isa_name(isa) + " packets of " + std::to_string(p);
        const Answers got = run<8, 8>(view, rays, {isa, TraversalOrder::kOctantStack, p});
        int bad = 0;
        for (size_t i = 0; i < rays.size(); ++i)
          if ((!same(got.hits[i], reference.hits[i]) || got.occluded[i] != reference.occluded[i]) && ++bad <= 5)
            ADD_FAILURE() << path << " ray " << i << ": t " << got.hits[i].t << " vs " << reference.hits[i].t << ", instance "
                          << got.hits[i].instance << " vs " << reference.hits[i].instance;
        EXPECT_EQ(bad, 0) << path;
        EXPECT_GE(double(got.closest.packet_rays), 0.9 * double(rays.size())) << path;
      }
    expect_packets_equal_single<8, 8>(view, rays, one ? "one axis-moved instance" : "axis-moved instances", 0.1, 0.9);
  }
}

// A packet through one instance scaled by 2^-100 (L^-1 = 2^100): lanes whose local direction or origin
// leaves float range are misses for single rays (transform_ray refuses them) and must be for the
// packet's four-lanes-at-once move too (InstanceMove4, ray_prep.h), beside lanes in range that hit.
// A lane moved with an infinite direction would hit at t = 0 (den = inf): the range test is what keeps
// the answers equal.
TEST(TracePackets, MovedLanesOutOfFloatRangeAreMissesAsForSingleRays) {
  if (simd_isas().empty()) GTEST_SKIP() << "no AVX2 on this CPU: packets are SIMD only";
  Scene s;
  s.meshes.push_back(make_icosphere(3));
  Instance tiny;
  const double scale = std::ldexp(1.0, -100);
  for (int a = 0; a < 3; ++a) tiny.transform(a, a) = scale;
  tiny.transform(0, 3) = 3 * scale;  // moved too: not the identity, not a signed permutation
  s.instances.push_back(tiny);
  s.bounds = Aabb{};
  for (uint32_t v : s.meshes[0].indices) s.bounds.grow(tiny.transform.apply(to_d(s.meshes[0].positions[v])));
  const InCoreScene<8, 8> bvh = InCoreScene<8, 8>::build(s);
  const SceneView<8, 8> view = bvh.view();
  ASSERT_TRUE(fmt::ChildRef::is_leaf(view.top_root));
  ASSERT_NE(view.moves, nullptr);
  ASSERT_EQ(view.moves[0].kind, AxisMove::kGeneral);
  // Runs of 16 rays towards +z at the sphere: lane k aims at (3 + 0.05 (k % 4 - 1.5), 0.05 (k / 4 - 1.5)) in
  // local units; every third lane has a direction of length 2^40 (local 2^140: beyond FLT_MAX), every
  // fifth an origin 2^40 away along -z (local 2^140), the rest are in range.
  std::vector<fmt::Ray> rays;
  for (int run = 0; run < 64; ++run)
    for (int k = 0; k < 16; ++k) {
      const int i = run * 16 + k;
      const float x = float((3 + 0.05 * (k % 4 - 1.5) + 0.001 * run) * scale), y = float(0.05 * (k / 4 - 1.5) * scale);
      const bool long_dir = i % 3 == 0, far_org = i % 5 == 0;
      const float z = far_org ? -float(std::ldexp(1.0, 40)) : float(-4 * scale);
      const float len = long_dir ? float(std::ldexp(1.0, 40)) : 1.0f;
      rays.push_back({{x, y, z}, 0.0f, {0.0f, 0.0f, len}, INFINITY});
    }
  for (Isa isa : simd_isas()) {
    const Answers single = run<8, 8>(view, rays, {isa, TraversalOrder::kOctantStack, 0});
    size_t hits = 0, out_of_range_hits = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      const bool hit = single.hits[i].instance != fmt::Hit::kNone;
      hits += hit;
      out_of_range_hits += hit && (i % 3 == 0 || i % 5 == 0);
    }
    EXPECT_GT(hits, rays.size() / 3) << "the in-range lanes hit the sphere";
    EXPECT_EQ(out_of_range_hits, 0u) << "transform_ray refuses local rays beyond float range";
    for (uint32_t p : {4u, 8u, 16u}) {
      const std::string path = std::string(isa_name(isa)) + " packets of " + std::to_string(p);
      const Answers got = run<8, 8>(view, rays, {isa, TraversalOrder::kOctantStack, p});
      EXPECT_GT(got.closest.packets, 0u) << path;
      int bad = 0;
      for (size_t i = 0; i < rays.size(); ++i)
        if ((!same(got.hits[i], single.hits[i]) || got.occluded[i] != single.occluded[i]) && ++bad <= 5)
          ADD_FAILURE() << path << " ray " << i << ": t " << got.hits[i].t << " vs " << single.hits[i].t << ", occluded "
                        << int(got.occluded[i]) << " vs " << int(single.occluded[i]);
      EXPECT_EQ(bad, 0) << path;
    }
  }
}

// Packets of 16 whose rays point into different octants, or carry NaN, tnear > tfar, zero and
// axis-parallel directions: the first valid ray's octant forms the packet, the others go alone.
TEST(TracePackets, SplitOctantsAndDegenerateRaysGoAlone) {
  if (simd_isas().empty()) GTEST_SKIP() << "no AVX2 on this CPU: packets are SIMD only";
  const Scene scene = instanced_scene();
  const InCoreScene<8, 8> bvh = InCoreScene<8, 8>::build(scene);
  const Aabb b = scene.bounds;
  const float cx = float(0.5 * (b.lo.x + b.hi.x)), cy = float(0.5 * (b.lo.y + b.hi.y));
  std::vector<fmt::Ray> rays;
  size_t expect_invalid = 0;
  for (int tile = 0; tile < 64; ++tile) {
    for (int i = 0; i < 16; ++i) {
      fmt::Ray r{};
      r.org[0] = cx + 0.01f * float(i % 4) + 0.2f * float(tile % 8) - 0.8f;
      r.org[1] = cy + 0.01f * float(i / 4) + 0.2f * float(tile / 8) - 0.8f;
      r.org[2] = float(b.hi.z) + 3.0f;
      // Down, with x and y signs that flip every other lane (tiles 0..31) or in one lane only.
      const float sx = tile < 32 ? (i % 2 ? 1.0f : -1.0f) : (i == 5 ? -1.0f : 1.0f);
      r.dir[0] = sx * 0.05f * float(1 + i % 3), r.dir[1] = 0.04f, r.dir[2] = -1.0f;
      r.tfar = INFINITY;
      if (tile % 5 == 1 && i == 3) r.dir[0] = 0.0f;                   // infinite reciprocal: alone
      if (tile % 5 == 2 && i == 0) r.org[0] = NAN, ++expect_invalid;  // the first lane is invalid
      if (tile % 5 == 3 && i == 7) r.tnear = 5.0f, r.tfar = 1.0f, ++expect_invalid;
      if (tile % 5 == 4 && i == 9) r.dir[0] = r.dir[1] = r.dir[2] = 0.0f;  // zero direction: a miss
      rays.push_back(r);
    }
  }
  rays.resize(rays.size() - 5);  // a last, short packet
  // ... ending in an invalid ray, which its lanes past the end repeat: counted once.
  rays.back().org[1] = NAN, ++expect_invalid;
  for (Isa isa : simd_isas()) {
    const Answers single = run<8, 8>(bvh.view(), rays, {isa, TraversalOrder::kOctantStack, 0});
    size_t hit = 0;
    for (const fmt::Hit& h : single.hits) hit += h.instance != fmt::Hit::kNone;
    EXPECT_GT(hit, rays.size() / 4);
    for (uint32_t p : {4u, 8u, 16u}) {
      const Answers got = run<8, 8>(bvh.view(), rays, {isa, TraversalOrder::kOctantStack, p});
      for (size_t i = 0; i < rays.size(); ++i) {
        ASSERT_TRUE(same(got.hits[i], single.hits[i])) << isa_name(isa) << " packets of " << p << " ray " << i;
        ASSERT_EQ(got.occluded[i], single.occluded[i]) << isa_name(isa) << " packets of " << p << " ray " << i;
      }
      EXPECT_EQ(got.closest.invalid_rays, expect_invalid);
      EXPECT_GT(got.closest.packets, 0u);
      EXPECT_LT(got.closest.packet_rays, rays.size() - expect_invalid) << "split octants must leave rays out";
    }
  }
}

// An axis-aligned orthographic camera: every ray of a tile has the same ±inf reciprocals on two axes
// (issue 11: gallery's such rays all went alone). Those tiles go as packets and answer as single rays
// bit for bit, also from origins on the scene's bounding planes (0·inf there); a tile with one ray that
// is not axis-aligned, or with +0 and -0 mixed, still sends that ray alone.
TEST(TracePackets, OrthographicAxisAlignedTilesGoAsPacketsAndEqualSingleRays) {
  if (simd_isas().empty()) GTEST_SKIP() << "no AVX2 on this CPU: packets are SIMD only";
  // Unit cubes at even integer places: every box plane is a multiple of 0.5, and so is every 2nd origin.
  Scene scene;
  scene.meshes.push_back(make_cube(0.5));
  for (int k = 0; k < 16; ++k) {
    Instance in;
    in.transform(0, 3) = 2.0 * (k % 4), in.transform(1, 3) = 2.0 * (k / 4), in.transform(2, 3) = 0.5 * (k % 3);
    scene.instances.push_back(in);
  }
  scene.bounds = Aabb{};
  for (const Instance& in : scene.instances)
    for (const auto& p : scene.meshes[0].positions) scene.bounds.grow(in.transform.apply(to_d(p)));
  const InCoreScene<8, 8> bvh = InCoreScene<8, 8>::build(scene);
  std::vector<fmt::Ray> rays;
  size_t pure = 0;
  for (int tile = 0; tile < 256; ++tile) {
    const int tx = tile % 16, ty = tile / 16;
    const bool mixed = tile % 9 == 4, signed_zero = tile % 9 == 7;
    for (int i = 0; i < 16; ++i) {
      fmt::Ray r{};
      // A tile spans 0.5: its first and last columns and rows lie on box planes (x = -0.5, 0.5, 1.5, ...).
      const float step[4] = {0.0f, 1.0f / 6.0f, 1.0f / 3.0f, 0.5f};
      r.org[0] = -1.0f + 0.5f * float(tx) + step[i % 4];
      r.org[1] = -1.0f + 0.5f * float(ty) + step[i / 4];
      r.org[2] = 4.0f;
      r.dir[0] = 0.0f, r.dir[1] = 0.0f, r.dir[2] = -1.0f;
      if (tile % 2) r.dir[0] = -0.0f, r.dir[2] = -2.0f;  // the other x octant, a longer direction
      if (mixed && i == 6) r.dir[0] = 1e-3f;             // not axis-aligned: alone
      if (signed_zero && i == 9) r.dir[1] = -0.0f;       // another octant: alone
      r.tfar = INFINITY;
      rays.push_back(r);
    }
    pure += mixed || signed_zero ? 0 : 16;
  }
  for (Isa isa : simd_isas()) {
    const Answers single = run<8, 8>(bvh.view(), rays, {isa, TraversalOrder::kOctantStack, 0});
    size_t hit = 0;
    for (const fmt::Hit& h : single.hits) hit += h.instance != fmt::Hit::kNone;
    EXPECT_GT(hit, rays.size() / 8) << "the camera must see the instances";
    for (uint32_t p : {4u, 8u, 16u}) {
      const Answers got = run<8, 8>(bvh.view(), rays, {isa, TraversalOrder::kOctantStack, p});
      for (size_t i = 0; i < rays.size(); ++i) {
        ASSERT_TRUE(same(got.hits[i], single.hits[i])) << isa_name(isa) << " packets of " << p << " ray " << i;
        ASSERT_EQ(got.occluded[i], single.occluded[i]) << isa_name(isa) << " packets of " << p << " ray " << i;
      }
      EXPECT_GE(got.closest.packet_rays, pure) << isa_name(isa) << " packets of " << p;
      EXPECT_LT(got.closest.packet_rays, rays.size()) << "the mixed tiles' odd rays go alone";
    }
  }
}

TEST(TracePackets, OtherPacketSizesAreRefused) {
  Scene scene;
  scene.meshes.push_back(make_cube());
  scene.instances.push_back(Instance{});
  scene.bounds = Aabb{};
  for (const auto& p : scene.meshes[0].positions) scene.bounds.grow(to_d(p));
  const InCoreScene<8, 8> bvh = InCoreScene<8, 8>::build(scene);
  const fmt::Ray ray{{0, 0, 5}, 0, {0, 0, -1}, INFINITY};
  fmt::Hit h{};
  uint8_t occ = 0;
  for (uint32_t bad : {1u, 2u, 3u, 12u, 32u}) {
    TraceOptions o{detect_isa(), TraversalOrder::kOctantStack, bad};
    try {
      trace_closest<8, 8>(bvh.view(), &ray, &h, 1, o);
      ADD_FAILURE() << "packet size " << bad << " accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ExitCode::kUsage);
      EXPECT_NE(std::string(e.what()).find("packet size " + std::to_string(bad)), std::string::npos) << e.what();
    }
    EXPECT_THROW((trace_any<8, 8>(bvh.view(), &ray, &occ, 1, o)), Error);
  }
  // The scalar ISA takes a valid size and traces single rays.
  const TraceStats st = trace_closest<8, 8>(bvh.view(), &ray, &h, 1, {Isa::kScalar, TraversalOrder::kOctantStack, 8});
  EXPECT_EQ(st.packets, 0u);
  EXPECT_EQ(h.t, 4.0f);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
