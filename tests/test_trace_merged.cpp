// Issue 11, "identity scenes skip the instance level": InCoreScene merges a scene whose instances share
// one transform (all the identity, or one root transform), each of its own mesh, into one mesh BVH
// (BuildOptions::merge_instances). Every answer must be the unmerged scene's bit for bit (closest t,
// instance, prim, u, v; any-hit; the N closest), on every ISA, order and packet size, and only such
// scenes may be merged.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "bvh/bvh.h"
#include "oracle/rays.h"
#include "scene/import.h"
#include "test_trace_paths.h"

namespace rtp {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using trace_test::check_all_paths;
using trace_test::PathResult;
using trace_test::same_hit;

size_t rays_per_kind() { return std::getenv("RTP_SANITIZED") ? 300 : 2000; }

Scene flight_helmet() {
  const std::string path = RTP_SOURCE_DIR "/samples/khronos/FlightHelmet/glTF/FlightHelmet.gltf";
  EXPECT_TRUE(std::filesystem::exists(path)) << "committed sample missing: " << path;
  return import_gltf(path);
}

// Rays of every kind, aimed with the unmerged scene's own answers.
std::vector<fmt::Ray> rays_for(const Scene& scene, const SceneView<8, 8>& view) {
  RayGenOptions gen;
  gen.seed = 11;
  gen.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { trace_closest<8, 8>(view, r, h, n, {}); };
  std::vector<fmt::Ray> rays;
  for (RayKind kind : kAllRayKinds) {
    const std::vector<fmt::Ray> k = generate_rays(scene, kind, rays_per_kind(), gen);
    rays.insert(rays.end(), k.begin(), k.end());
  }
  return rays;
}

// The merged build answers every ray as the unmerged one; returns the instances its hits name.
std::set<uint32_t> expect_same_answers(const Scene& scene, const std::string& what) {
  BuildOptions apart;
  apart.merge_instances = false;
  const InCoreScene<8, 8> merged = InCoreScene<8, 8>::build(scene);
  const InCoreScene<8, 8> unmerged = InCoreScene<8, 8>::build(scene, apart);
  EXPECT_TRUE(merged.merged()) << what;
  EXPECT_FALSE(unmerged.merged()) << what;
  EXPECT_EQ(merged.instances().size(), scene.instances.size() + 1) << what << ": the merged instance's record is last";
  EXPECT_EQ(merged.warnings(), unmerged.warnings()) << what;
  const std::vector<fmt::Ray> rays = rays_for(scene, unmerged.view());
  // Every ISA x order x packet size of each build agrees with its scalar octant-stack answer ...
  const PathResult a = check_all_paths<8, 8>(merged.view(), rays, what + " (merged)");
  const PathResult b = check_all_paths<8, 8>(unmerged.view(), rays, what + " (one BVH per mesh)");
  // ... and the two builds agree ray by ray.
  std::set<uint32_t> named;
  int bad = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (a.hits[i].instance != fmt::Hit::kNone) named.insert(a.hits[i].instance);
    if (same_hit(a.hits[i], b.hits[i]) && a.occluded[i] == b.occluded[i]) continue;
    if (++bad <= 5)
      ADD_FAILURE() << what << " ray " << i << ": merged t " << a.hits[i].t << " instance " << a.hits[i].instance << " prim "
                    << a.hits[i].prim << ", unmerged t " << b.hits[i].t << " instance " << b.hits[i].instance << " prim "
                    << b.hits[i].prim;
  }
  EXPECT_EQ(bad, 0) << what;
  // The N closest (Gribble's node culling), every ISA.
  for (Isa isa : {Isa::kScalar, Isa::kAvx2, Isa::kAvx512}) {
    if (static_cast<int>(isa) > static_cast<int>(detect_isa())) continue;
    constexpr uint32_t kN = 8;
    std::vector<fmt::Hit> ma(rays.size() * kN), mb(rays.size() * kN);
    std::vector<uint32_t> ca(rays.size()), cb(rays.size());
    TraceOptions o;
    o.isa = isa;
    trace_multi<8, 8>(merged.view(), rays.data(), rays.size(), kN, ma.data(), ca.data(), o);
    trace_multi<8, 8>(unmerged.view(), rays.data(), rays.size(), kN, mb.data(), cb.data(), o);
    EXPECT_EQ(ca, cb) << what << " multi-hit counts, " << isa_name(isa);
    size_t differ = 0;
    for (size_t k = 0; k < ma.size(); ++k) differ += !same_hit(ma[k], mb[k]);
    EXPECT_EQ(differ, 0u) << what << " multi-hit, " << isa_name(isa);
  }
  return named;
}

TEST(MergedIdentityInstances, FlightHelmetAnswersAsItsSixInstances) {
  const Scene scene = flight_helmet();
  ASSERT_EQ(scene.instances.size(), 6u);
  const std::set<uint32_t> named = expect_same_answers(scene, "FlightHelmet");
  EXPECT_GE(named.size(), 5u) << "the hits name the helmet's parts, not one merged instance";
  for (uint32_t i : named) EXPECT_LT(i, scene.instances.size());
}

// Instances in another order than their meshes, and one of a mesh without triangles: hits are named
// by instance order (the order ties are broken in), and the empty mesh's warning is the unmerged one.
TEST(MergedIdentityInstances, InstanceOrderAndEmptyMeshes) {
  Scene scene = flight_helmet();
  std::reverse(scene.instances.begin(), scene.instances.end());
  Mesh empty;
  empty.name = "empty";
  scene.meshes.push_back(empty);
  Instance none;
  none.mesh = uint32_t(scene.meshes.size() - 1);
  scene.instances.insert(scene.instances.begin() + 2, none);
  const std::set<uint32_t> named = expect_same_answers(scene, "FlightHelmet reversed, with an empty mesh");
  EXPECT_EQ(named.count(2), 0u) << "instance 2 has no triangles";
  EXPECT_GE(named.size(), 5u);
}

// One transform over every mesh node (a glTF root node rotated, scaled, moved): merged under that one
// transform, walked through the instance level once instead of once per part.
TEST(MergedIdentityInstances, OneSharedTransform) {
  Scene scene = flight_helmet();
  const double c = 0.8, s = 0.6;  // a turn about y, a scale of 2.5 and a move
  Affine3x4 m;
  const double rows[3][4] = {{2.5 * c, 0, 2.5 * s, 10.25}, {0, 2.5, 0, -3.5}, {-2.5 * s, 0, 2.5 * c, 7.0}};
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 4; ++k) m(r, k) = rows[r][k];
  for (Instance& in : scene.instances) in.transform = m;
  const std::set<uint32_t> named = expect_same_answers(scene, "FlightHelmet under one transform");
  EXPECT_GE(named.size(), 5u);
  const InCoreScene<8, 8> merged = InCoreScene<8, 8>::build(scene);
  EXPECT_EQ(merged.view().direct, kNoDirectInstance) << "a moved merged instance is walked as an instance";
}

// Only scenes whose instances share one transform, each of its own mesh, are merged.
TEST(MergedIdentityInstances, OnlyIdentityInstancesOfTheirOwnMeshes) {
  const Scene base = flight_helmet();
  EXPECT_TRUE((InCoreScene<8, 8>::build(base).merged()));
  EXPECT_TRUE((InCoreScene<4, 4>::build(base).merged()));
  Scene moved = base;
  moved.instances[3].transform(0, 3) = 0.25;  // one instance translated: merged only in world space
  BuildOptions local_only;
  local_only.flatten_instances = false;
  EXPECT_FALSE((InCoreScene<8, 8>::build(moved, local_only).merged()));
  EXPECT_TRUE((InCoreScene<8, 8>::build(moved).flattened()));
  EXPECT_FALSE((InCoreScene<8, 8>::build(base).flattened())) << "shared transforms merge in local space, exactly";
  Scene singular = base;
  for (Instance& in : singular.instances) in.transform(1, 1) = 0;  // shared, but no ray can enter it
  EXPECT_FALSE((InCoreScene<8, 8>::build(singular).merged()));
  Scene one_singular = moved;
  one_singular.instances[2].transform(1, 1) = 0;  // left out with a warning by the two-level build
  EXPECT_FALSE((InCoreScene<8, 8>::build(one_singular).merged()));
  Scene shared = base;
  shared.instances[4].mesh = shared.instances[1].mesh;  // two instances of one mesh
  EXPECT_FALSE((InCoreScene<8, 8>::build(shared).merged()));
  Scene one = base;
  one.instances.resize(1);  // one identity instance: SceneView::direct already walks it without the level
  EXPECT_FALSE((InCoreScene<8, 8>::build(one).merged()));
  Scene bad = base;
  bad.meshes[bad.instances[0].mesh].indices[0] = 0xFFFFFFF0u;  // the per-mesh build names the bad mesh
  try {
    (void)InCoreScene<8, 8>::build(bad);
    ADD_FAILURE() << "a vertex index out of range must be refused";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("mesh " + std::to_string(bad.instances[0].mesh)), std::string::npos) << e.what();
  }
}

// Issue 11, instances each of its own mesh under different transforms (Lantern: three parts, each
// translated, under a turned root) are merged in world space (BuildOptions::flatten_instances): the
// vertices rounded once in world space, so answers are the two-level walk's up to that rounding. Every
// ray must name the same instance and triangle at the same t (to 1e-5 of the scene's size), or be a
// tie the rounding can move: two triangles at the same t, or a hit within 1e-4 of its triangle's edge.
Scene lantern() {
  const std::string path = RTP_SOURCE_DIR "/samples/khronos/Lantern/glTF/Lantern.gltf";
  EXPECT_TRUE(std::filesystem::exists(path)) << "committed sample missing: " << path;
  return import_gltf(path);
}

bool near_edge(const fmt::Hit& h) {
  constexpr float kEps = 1e-4f;
  return h.u <= kEps || h.v <= kEps || h.u + h.v >= 1.0f - kEps;
}

TEST(FlattenedInstances, LanternAnswersAsItsThreeParts) {
  const Scene scene = lantern();
  ASSERT_EQ(scene.instances.size(), 3u);
  BuildOptions apart;
  apart.merge_instances = false;
  const InCoreScene<8, 8> flat = InCoreScene<8, 8>::build(scene);
  const InCoreScene<8, 8> two_level = InCoreScene<8, 8>::build(scene, apart);
  ASSERT_TRUE(flat.merged() && flat.flattened());
  EXPECT_NE(flat.view().direct, kNoDirectInstance) << "the world-space merge is walked without the instance level";
  EXPECT_EQ(flat.warnings(), two_level.warnings());
  const std::vector<fmt::Ray> rays = rays_for(scene, two_level.view());
  const PathResult a = check_all_paths<8, 8>(flat.view(), rays, "Lantern (flattened)");
  const PathResult b = check_all_paths<8, 8>(two_level.view(), rays, "Lantern (two levels)");
  const Aabb& w = scene.bounds;
  const double size = std::max({w.hi.x - w.lo.x, w.hi.y - w.lo.y, w.hi.z - w.lo.z});
  ASSERT_GT(size, 0);
  std::set<uint32_t> named;
  size_t same = 0, misses = 0, ties = 0, bad = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    const fmt::Hit &x = a.hits[i], &y = b.hits[i];
    const bool hx = x.instance != fmt::Hit::kNone, hy = y.instance != fmt::Hit::kNone;
    if (hx) named.insert(x.instance);
    const double dt = hx && hy ? std::fabs(double(x.t) - y.t) *
                                     std::sqrt(double(rays[i].dir[0]) * rays[i].dir[0] + double(rays[i].dir[1]) * rays[i].dir[1] +
                                               double(rays[i].dir[2]) * rays[i].dir[2])
                               : 0;
    bool ok;
    if (!hx && !hy) {
      ok = true;
      ++misses;
    } else if (hx && hy && x.instance == y.instance && x.prim == y.prim) {
      ok = dt <= 1e-5 * size;
      same += ok;
    } else {
      // A different triangle at the same distance, or a hit against a miss, only at an edge.
      ok = hx && hy ? dt <= 1e-5 * size && (near_edge(x) || near_edge(y)) : (hx ? near_edge(x) : near_edge(y));
      ties += ok;
    }
    if (!ok && ++bad <= 5)
      ADD_FAILURE() << "ray " << i << ": flattened t " << x.t << " instance " << x.instance << " prim " << x.prim << " (u " << x.u
                    << ", v " << x.v << "), two-level t " << y.t << " instance " << y.instance << " prim " << y.prim << " (u "
                    << y.u << ", v " << y.v << ")";
    // Any-hit: the same answer, or a tie at an edge (the closest-hit answers of the ray show it).
    if (a.occluded[i] != b.occluded[i] && !(hx && near_edge(x)) && !(hy && near_edge(y)) && ++bad <= 5)
      ADD_FAILURE() << "ray " << i << ": occluded " << int(a.occluded[i]) << " vs " << int(b.occluded[i]);
  }
  EXPECT_EQ(bad, 0u);
  EXPECT_EQ(same + misses + ties, rays.size());
  EXPECT_GE(same, rays.size() / 10) << "rays hit the lantern and agree in name";
  EXPECT_LE(ties, rays.size() / 1000 + 1) << "ties are rare";
  EXPECT_EQ(named, (std::set<uint32_t>{0, 1, 2})) << "hits name the lantern's three parts";
}

// A part far from the origin relative to its size (geospatial coordinates, as issue 11's accuracy
// scene) would lose its shape in world-space floats: such scenes keep their two levels.
TEST(FlattenedInstances, FarAndSmallPartsStayTwoLevel) {
  const Scene base = lantern();
  ASSERT_TRUE((InCoreScene<8, 8>::build(base).flattened()));
  Scene far = base;
  Affine3x4& t = far.instances[1].transform;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) t(r, c) *= 1e-3;
  t(0, 3) = 3000000.3, t(1, 3) = -2000000.7, t(2, 3) = 1000000.1;
  EXPECT_FALSE((InCoreScene<8, 8>::build(far).merged()));
  Scene small = base;  // the part scaled to 1e-3 in place: now small for where it is
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) small.instances[1].transform(r, c) *= 1e-3;
  EXPECT_FALSE((InCoreScene<8, 8>::build(small).merged()));
  Scene near = base;  // scaled to 1e-3 about the origin, its place with it: as flattenable as before
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) near.instances[1].transform(r, c) *= 1e-3;
  EXPECT_TRUE((InCoreScene<8, 8>::build(near).flattened()));
  Scene shared = base;
  shared.instances[2].mesh = shared.instances[0].mesh;  // a mesh placed twice is instanced, not copied
  EXPECT_FALSE((InCoreScene<8, 8>::build(shared).merged()));
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp
