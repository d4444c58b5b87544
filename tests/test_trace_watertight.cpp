// TESTING.md stability cases 1-2: rays aimed exactly at the shared vertices and edge midpoints of a
// closed mesh, from inside and from outside, never leak (0 allowed), also with the mesh far from the
// origin, moved there either in its vertices or by the instance transform; every ISA × order × (W, B).
#include <gtest/gtest.h>

#include <cstdlib>

#include <cmath>
#include <string>
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
class TraceWatertight : public ::testing::Test {};
using test::AllWidths;
TYPED_TEST_SUITE(TraceWatertight, AllWidths);

std::array<float, 3> to_float(const std::array<double, 3>& p) { return {float(p[0]), float(p[1]), float(p[2])}; }

// The closed convex mesh `m` (scaled by `scale`) placed at `centre`: in its vertices (in_vertices) or by
// a translation instance. Rays from 3 interior points and from outside (along the line from the centre
// through the target, 3x farther) aimed at every vertex and every edge midpoint: all must hit, at t ~ 1
// (the mesh is convex, so the first surface point on the way is the target).
template <int W, int B>
void check_no_leaks(const Mesh& m, double scale, std::array<double, 3> centre, bool in_vertices, const std::string& what) {
  std::vector<std::array<float, 3>> verts;
  std::vector<std::array<uint32_t, 2>> edges;
  const std::array<double, 3> local_centre = in_vertices ? centre : std::array<double, 3>{0, 0, 0};
  std::vector<Tri> tris = soup(m, scale, local_centre, &verts, &edges);
  const Affine place = in_vertices ? identity() : translation(centre[0], centre[1], centre[2]);
  const TestScene<W, B> scene = build_scene<W, B>({tris}, {{0, place}});

  // Targets in world space (double), rounded once.
  std::vector<std::array<double, 3>> targets;
  targets.reserve(verts.size() + edges.size());
  auto world = [&](const std::array<double, 3>& p) { return apply(place, p); };
  for (const auto& v : verts) targets.push_back(world({v[0], v[1], v[2]}));
  for (const auto& e : edges) {
    std::array<double, 3> mid;
    for (int a = 0; a < 3; ++a) mid[a] = double(float(0.5 * (double(verts[e[0]][a]) + double(verts[e[1]][a]))));
    targets.push_back(world(mid));
  }
  std::vector<fmt::Ray> rays;
  const double r = 0.3 * scale;
  const std::array<double, 3> inside[] = {
      centre, {centre[0] + r, centre[1], centre[2]}, {centre[0] - 0.5 * r, centre[1] + r, centre[2] - 0.25 * r}};
  for (const auto& t : targets) {
    const std::array<float, 3> tf = to_float(t);
    for (const auto& o : inside) {
      const std::array<float, 3> of = to_float(o);
      rays.push_back({{of[0], of[1], of[2]}, 0, {tf[0] - of[0], tf[1] - of[1], tf[2] - of[2]}, INFINITY});
    }
    std::array<double, 3> far;
    for (int a = 0; a < 3; ++a) far[a] = centre[a] + 3.0 * (t[a] - centre[a]);
    const std::array<float, 3> of = to_float(far);
    rays.push_back({{of[0], of[1], of[2]}, 0, {tf[0] - of[0], tf[1] - of[1], tf[2] - of[2]}, INFINITY});
  }
  const PathResult res = check_all_paths<W, B>(scene.view(), rays, what);
  const size_t bf_stride = std::getenv("RTP_SANITIZED") ? 8 : 1;
  int leaks = 0, far_off = 0, failures = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (res.hits[i].instance == fmt::Hit::kNone) {
      if (++leaks <= 5) ADD_FAILURE() << what << ": leak, ray " << i << " (" << (i % 4 == 3 ? "outside" : "inside") << ")";
      continue;
    }
    // t = 1 at the target, up to the rounding of the target to the float grid (far from the origin).
    const double len = std::sqrt(double(rays[i].dir[0]) * rays[i].dir[0] + double(rays[i].dir[1]) * rays[i].dir[1] +
                                 double(rays[i].dir[2]) * rays[i].dir[2]);
    const double grid =
        std::ldexp(1.0, std::ilogb(std::max({std::fabs(centre[0]), std::fabs(centre[1]), std::fabs(centre[2]), 1.0})) - 23);
    if (std::fabs(res.hits[i].t - 1.0) > 1e-4 + 4 * grid / len) ++far_off;
    // Under ASan+UBSan (scripts/test's second run) every 8th ray is also checked against the double brute
    // force: it reads no library memory, and all of it runs in the Release run.
    if (i % bf_stride != 0) continue;
    const RefHit bf = brute_force(scene, rays[i]);
    const int c = classify(scene, rays[i], res.hits[i], bf);
    if (c == 2 && ++failures <= 5)
      ADD_FAILURE() << what << ": ray " << i << " t " << res.hits[i].t << " prim " << res.hits[i].prim << " u " << res.hits[i].u
                    << " v " << res.hits[i].v << " vs brute force t " << bf.t << " prim " << bf.prim << " edge " << bf.edge;
  }
  EXPECT_EQ(leaks, 0) << what << " (" << rays.size() << " rays)";
  EXPECT_EQ(far_off, 0) << what << ": hits not at the aimed point";
  EXPECT_EQ(failures, 0) << what << ": disagreements with brute force";
}

const std::array<double, 3> kCentres[] = {{0, 0, 0}, {148376, 1234, -223423}, {3e6, -3e6, 3e6}};

TYPED_TEST(TraceWatertight, IcosphereVerticesAndEdges) {
  const Mesh sphere = make_icosphere(3);
  for (const auto& c : kCentres)
    for (bool in_vertices : {true, false})
      check_no_leaks<TypeParam::W, TypeParam::B>(
          sphere, 100.0, c, in_vertices, "icosphere at " + std::to_string(c[0]) + (in_vertices ? " (vertices)" : " (instance)"));
}

TYPED_TEST(TraceWatertight, CubeCornersEdgesAndDiagonals) {
  const Mesh cube = make_cube(1.0);
  for (const auto& c : kCentres)
    for (bool in_vertices : {true, false})
      check_no_leaks<TypeParam::W, TypeParam::B>(
          cube, 50.0, c, in_vertices, "cube at " + std::to_string(c[0]) + (in_vertices ? " (vertices)" : " (instance)"));
}

// Random directions from inside, with axis-parallel, ±0, denormal and 1e-9 components (case 3).
TYPED_TEST(TraceWatertight, InsideRaysWithSpecialDirections) {
  constexpr int W = TypeParam::W, B = TypeParam::B;
  for (const auto& c : kCentres) {
    const TestScene<W, B> scene = build_scene<W, B>({soup(make_icosphere(2), 10.0, c)}, {{0, identity()}});
    Rng rng(3);
    std::vector<fmt::Ray> rays;
    const float specials[] = {0.0f, -0.0f, 1e-40f, -1e-40f, 1e-9f, -1e-9f};
    for (int i = 0; i < 3000; ++i) {
      fmt::Ray r{{float(c[0]), float(c[1]), float(c[2])}, 0, {rng.range(-1, 1), rng.range(-1, 1), rng.range(-1, 1)}, INFINITY};
      // One component normal or +-1e-9 (a direction of denormal length has t beyond FLT_MAX), the
      // others special with some probability.
      const int keep = int(rng.below(3));
      for (int a = 0; a < 3; ++a)
        if (a != keep && rng.below(2) == 0) r.dir[a] = specials[rng.below(6)];
      if (rng.below(4) == 0) r.dir[keep] = rng.below(2) ? 1e-9f : -1e-9f;
      rays.push_back(r);
    }
    const PathResult res = check_all_paths<W, B>(scene.view(), rays, "special directions");
    int leaks = 0;
    for (const fmt::Hit& h : res.hits) leaks += h.instance == fmt::Hit::kNone;
    EXPECT_EQ(leaks, 0) << "centre " << c[0];
  }
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp
