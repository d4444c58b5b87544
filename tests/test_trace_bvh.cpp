// lib/trace on real samples built by lib/bvh (InCoreScene): for every (W, B), every ISA × order gives
// the scalar octant-stack answer bit for bit; every (W, B) gives the same answer as (8, 8) (ties are
// broken by (t, instance, prim), so the tree shape does not matter); and that answer agrees with the
// brute-force double-precision reference ray by ray (TESTING.md "The oracle").
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "bvh/bvh.h"
#include "oracle/compare.h"
#include "oracle/rays.h"
#include "oracle/reference.h"
#include "scene/import.h"
#include "test_trace_paths.h"

namespace rtp {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using trace_test::check_all_paths;
using trace_test::PathResult;
using trace_test::same_hit;

size_t rays_per_kind() { return std::getenv("RTP_SANITIZED") ? 500 : 3000; }

class TraceBvh : public ::testing::TestWithParam<std::string> {};

template <int W, int B>
void check_width(const Scene& scene, const std::vector<fmt::Ray>& rays, const PathResult& base, const std::string& what) {
  const InCoreScene<W, B> built = InCoreScene<W, B>::build(scene);
  const PathResult r = check_all_paths<W, B>(built.view(), rays, what);
  int differ = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (same_hit(r.hits[i], base.hits[i]) && r.occluded[i] == base.occluded[i]) continue;
    if (++differ <= 5)
      ADD_FAILURE() << what << " W=" << W << " B=" << B << " ray " << i << ": t " << r.hits[i].t << " vs " << base.hits[i].t
                    << ", instance " << r.hits[i].instance << " vs " << base.hits[i].instance << ", prim " << r.hits[i].prim
                    << " vs " << base.hits[i].prim;
  }
  EXPECT_EQ(differ, 0) << what << " W=" << W << " B=" << B << " differs from W=8 B=8";
}

TEST_P(TraceBvh, EveryWidthIsaOrderAgreesWithBruteForce) {
  const std::string path = RTP_SOURCE_DIR "/samples/" + GetParam();
  ASSERT_TRUE(std::filesystem::exists(path)) << "committed sample missing: " << path;
  const Scene scene = import_gltf(path);
  const InCoreScene<8, 8> base_scene = InCoreScene<8, 8>::build(scene);
  const SceneView<8, 8> base_view = base_scene.view();
  RayGenOptions gen;
  gen.seed = 5;
  gen.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { trace_closest<8, 8>(base_view, r, h, n, {}); };
  std::vector<fmt::Ray> rays;
  for (RayKind kind : kAllRayKinds) {
    const std::vector<fmt::Ray> k = generate_rays(scene, kind, rays_per_kind(), gen);
    rays.insert(rays.end(), k.begin(), k.end());
  }
  const PathResult base = check_all_paths<8, 8>(base_view, rays, GetParam());

  // Brute force, ray by ray.
  const BruteForceReference reference(scene);
  std::vector<fmt::Hit> ref(rays.size());
  reference.closest(rays.data(), ref.data(), rays.size());
  CompareOptions cmp;
  cmp.scene = &scene;
  size_t hits = 0, ties = 0, failures = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    hits += ref[i].instance != fmt::Hit::kNone;
    const Verdict v = classify_hit(rays[i], ref[i], base.hits[i], cmp);
    ties += v == Verdict::kEdgeTie || v == Verdict::kPrecisionTie;
    if (v == Verdict::kFail && ++failures <= 5)
      ADD_FAILURE() << GetParam() << " ray " << i << ": t " << base.hits[i].t << " prim " << base.hits[i].prim
                    << " vs brute force t " << ref[i].t << " prim " << ref[i].prim;
  }
  EXPECT_EQ(failures, 0u);
  EXPECT_GT(hits, rays.size() / 8);
  EXPECT_LE(ties, rays.size() / 1000) << "classified ties";

  check_width<4, 4>(scene, rays, base, GetParam());
  check_width<16, 16>(scene, rays, base, GetParam());
  check_width<8, 4>(scene, rays, base, GetParam());
  check_width<16, 8>(scene, rays, base, GetParam());
}

INSTANTIATE_TEST_SUITE_P(Samples, TraceBvh, ::testing::Values("khronos/Lantern/glTF/Lantern.gltf", "generated/gallery.glb"),
                         [](const auto& info) { return info.index == 0 ? std::string("Lantern") : std::string("Gallery"); });

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp
