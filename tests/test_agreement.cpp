// rtpack's in-core tracer (lib/bvh InCoreScene + lib/trace) against the Embree ROBUST oracle, ray by
// ray (TESTING.md): every committed sample and, when ../shared is present, the shared scenes; W = B =
// 4, 8, 16; both traversal orders; every ISA up to the one this CPU has; primary, random, bounce,
// shadow, inside and short rays. Closest hits: 0 failures beyond classified edge ties. Any hit:
// consistent with rtpack's own closest hit and with Embree's.
//
// Ray counts are modest (2000 per kind, a quarter under RTP_SANITIZED) so the suite stays fast also
// under ASan+UBSan.
#include <gtest/gtest.h>

#include <array>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <filesystem>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "bvh/bvh.h"
#include "gltf_builder.h"
#include "oracle/compare.h"
#include "oracle/embree_oracle.h"
#include "oracle/instance_reference.h"
#include "oracle/rays.h"
#include "oracle/reference.h"
#include "scene/import.h"
#include "trace/trace.h"

namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using namespace rtp;
namespace fs = std::filesystem;

const std::string kSamples = RTP_SOURCE_DIR "/samples";
const std::string kShared = RTP_SOURCE_DIR "/../shared/assets";

size_t rays_per_kind() { return std::getenv("RTP_SANITIZED") ? 500 : 2000; }

std::vector<Isa> isas() {
  std::vector<Isa> out = {Isa::kScalar};
  if (int(detect_isa()) >= int(Isa::kAvx2)) out.push_back(Isa::kAvx2);
  if (int(detect_isa()) >= int(Isa::kAvx512)) out.push_back(Isa::kAvx512);
  return out;
}

// The rays of one kind with Embree's answers.
struct KindCase {
  RayKind kind;
  std::vector<fmt::Ray> rays;
  std::vector<fmt::Hit> ref;
  std::vector<uint8_t> ref_occ;
  std::vector<uint8_t> skip;
};

std::vector<KindCase> make_cases(const Scene& scene, const EmbreeOracle& oracle) {
  std::vector<KindCase> cases;
  RayGenOptions opt;
  opt.seed = 11;
  opt.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { oracle.closest(r, h, n); };
  for (RayKind kind : kAllRayKinds) {
    KindCase c;
    c.kind = kind;
    c.rays = generate_rays(scene, kind, rays_per_kind(), opt);
    const size_t n = c.rays.size();
    c.ref.resize(n);
    c.ref_occ.resize(n);
    oracle.closest(c.rays.data(), c.ref.data(), n);
    oracle.occluded(c.rays.data(), c.ref_occ.data(), n);
    c.skip = unsupported_mask(c.rays.data(), n);
    // The oracle is consistent with itself.
    const AnyHitReport self = check_any_hit(c.rays.data(), c.ref.data(), c.ref_occ.data(), n);
    EXPECT_EQ(self.failures, 0u) << ray_kind_name(kind) << ": Embree any-hit vs closest-hit: " << self.details();
    cases.push_back(std::move(c));
  }
  return cases;
}

// Totals over one scene, for the one-line summary every test prints.
struct Tally {
  uint64_t rays = 0, agree = 0, ties = 0, precision_ties = 0, failures = 0, reference_errors = 0;
};

// exact: the double brute-force reference that decides where rtpack and Embree disagree (TESTING.md),
// given for far.glb, whose instances sit where Embree's float matrices are off by more than the
// triangles; ties of either kind must stay rare everywhere.
template <int W>
void check_width(const Scene& scene, const std::vector<KindCase>& cases, const BruteForceReference* exact, Tally& tally) {
  CompareOptions own_opt;  // rtpack's any hit against its own closest hit: no third party decides
  own_opt.scene = &scene;
  CompareOptions copt = own_opt;
  copt.exact = exact;
  const InCoreScene<W, W> bvh = InCoreScene<W, W>::build(scene);
  const SceneView<W, W> view = bvh.view();
  for (Isa isa : isas()) {
    for (TraversalOrder order : {TraversalOrder::kOctantStack, TraversalOrder::kActiveList}) {
      const TraceOptions topt{isa, order};
      for (const KindCase& c : cases) {
        SCOPED_TRACE(std::string("W=") + std::to_string(W) + " isa=" + isa_name(isa) + " order=" + order_name(order) +
                     " kind=" + ray_kind_name(c.kind));
        const size_t n = c.rays.size();
        std::vector<fmt::Hit> hits(n);
        std::vector<uint8_t> occ(n);
        const TraceStats sc = trace_closest<W, W>(view, c.rays.data(), hits.data(), n, topt);
        const TraceStats sa = trace_any<W, W>(view, c.rays.data(), occ.data(), n, topt);
        EXPECT_EQ(sc.invalid_rays, 0u);
        EXPECT_EQ(sc.overflow_rays, 0u);
        EXPECT_EQ(sa.overflow_rays, 0u);
        const CompareReport rep = compare_closest(c.rays.data(), c.ref.data(), hits.data(), n, copt, c.skip.data());
        EXPECT_EQ(rep.failures, 0u) << "closest hit vs Embree: " << rep.details();
        EXPECT_LE(rep.edge_ties, n / 100) << rep.details();
        EXPECT_LE(rep.precision_ties, n / 100) << rep.details();
        const AnyHitReport own = check_any_hit(c.rays.data(), hits.data(), occ.data(), n, own_opt);
        EXPECT_EQ(own.failures, 0u) << "any hit vs rtpack's closest hit: " << own.details();
        const AnyHitReport cross = check_any_hit(c.rays.data(), c.ref.data(), occ.data(), n, copt, c.skip.data(), hits.data());
        EXPECT_EQ(cross.failures, 0u) << "any hit vs Embree's closest hit: " << cross.details();
        tally.rays += n;
        tally.agree += rep.agree();
        tally.ties += rep.edge_ties;
        tally.precision_ties += rep.precision_ties;
        tally.failures += rep.failures + own.failures + cross.failures;
        tally.reference_errors += rep.reference_errors;
      }
    }
  }
}

void check_scene(const std::string& path, bool far_from_origin) {
  const Scene scene = import_gltf(path);
  ASSERT_GT(scene.instanced_triangles(), 0u);
  const EmbreeOracle oracle(scene, OracleQuality::kMedium);
  const std::vector<KindCase> cases = make_cases(scene, oracle);
  Tally tally;
  const std::unique_ptr<BruteForceReference> exact = far_from_origin ? std::make_unique<BruteForceReference>(scene) : nullptr;
  check_width<4>(scene, cases, exact.get(), tally);
  check_width<8>(scene, cases, exact.get(), tally);
  check_width<16>(scene, cases, exact.get(), tally);
  std::printf(
      "[ agreement] %s: %llu closest-hit rays, %llu agree, %llu edge ties, %llu precision ties, %llu failures, "
      "%llu Embree errors settled by the double reference\n",
      fs::path(path).filename().c_str(), (unsigned long long)tally.rays, (unsigned long long)tally.agree,
      (unsigned long long)tally.ties, (unsigned long long)tally.precision_ties, (unsigned long long)tally.failures,
      (unsigned long long)tally.reference_errors);
  if (far_from_origin) {
    EXPECT_GT(tally.reference_errors, 0u) << "far.glb: Embree's float matrices are never caught";
  }
}

// Rays that once failed, replayed on every W, ISA and order against Embree and the double brute force.
struct ReplayRay {
  const char* scene;  // relative to samples/, or to ../shared/assets when `shared`
  std::array<uint32_t, 8> bits;
  const char* what;
  bool shared = false;
  bool embree_wrong = false;  // the double reference disagrees with Embree on this ray
};
const ReplayRay kReplays[] = {
    {"khronos/Lantern/glTF-Draco/Lantern.gltf",
     {0x3f5cb0d0, 0x41b085de, 0x3f3c274d, 0x00000000, 0x3f406bbd, 0xbf150b2d, 0xbe9eb280, 0x7f800000},
     "needle triangle (15.4 x 0.04) at 84 degrees: t was off by 2.3e-4 relative"},
    {"generated/gallery.glb",
     {0xc034332c, 0x415fd89a, 0xc09e1f07, 0x00000000, 0x00000000, 0xbf800000, 0xa5800000, 0x4171c52b},
     "direction (0, -1, -2.2e-16): Embree's packet path misses it"},
    {"scenes/forest-2k.glb",
     {0x4192ece9, 0x3eacc1f5, 0xc18afae1, 0x00000000, 0xbe44f2aa, 0xbf4fe48e, 0x3f0d0a44, 0x7f800000},
     "bounce ray #61120 (rtpack-bench, seed 1): its origin is 2.5e-7 in front of instance 338's prim 10123, "
     "crossed at t = 1.2e-6 in double; Embree's float instance matrix puts it behind and answers prim 18575 "
     "at 0.084 (reported as a failure until the bench had a double judge for large scenes)",
     true,
     true},
};

template <int W>
void replay_width(const Scene& scene, const fmt::Ray& ray, const fmt::Hit& ref, const CompareOptions& copt) {
  const InCoreScene<W, W> bvh = InCoreScene<W, W>::build(scene);
  for (Isa isa : isas())
    for (TraversalOrder order : {TraversalOrder::kOctantStack, TraversalOrder::kActiveList}) {
      fmt::Hit hit;
      uint8_t occ = 2;
      trace_closest<W, W>(bvh.view(), &ray, &hit, 1, {isa, order});
      trace_any<W, W>(bvh.view(), &ray, &occ, 1, {isa, order});
      EXPECT_EQ(classify_hit(ray, ref, hit, copt), Verdict::kAgree)
          << "W=" << W << " " << isa_name(isa) << " " << order_name(order) << "\n"
          << RayDiff{0, Verdict::kFail, ray, ref, hit}.describe();
      EXPECT_EQ(occ, ref.t < std::numeric_limits<float>::infinity() ? 1 : 0);
    }
}

TEST(AgreementReplay, RaysThatOnceFailed) {
  for (const ReplayRay& r : kReplays) {
    SCOPED_TRACE(std::string(r.scene) + ": " + r.what);
    const std::string path = (r.shared ? kShared : kSamples) + "/" + r.scene;
    if (r.shared) RTP_NEED_SHARED(path);
    const Scene scene = import_gltf(path);
    const fmt::Ray ray = ray_from_bits(r.bits);
    fmt::Hit embree, brute, by_instance;
    EmbreeOracle(scene, OracleQuality::kHigh).closest(&ray, &embree, 1);
    // The double judge: flattened for small scenes; instance by instance at any size, with the same answer.
    InstanceReference(scene).closest(&ray, &by_instance, 1);
    if (scene.instanced_triangles() <= 4'000'000) {
      BruteForceReference(scene).closest(&ray, &brute, 1);
      EXPECT_EQ(std::memcmp(&brute, &by_instance, sizeof brute), 0);
    } else {
      brute = by_instance;
    }
    CompareOptions copt;
    copt.scene = &scene;
    ASSERT_EQ(classify_hit(ray, brute, embree, copt), r.embree_wrong ? Verdict::kFail : Verdict::kAgree);
    replay_width<4>(scene, ray, brute, copt);
    replay_width<8>(scene, ray, brute, copt);
    replay_width<16>(scene, ray, brute, copt);
  }
}

struct SceneCase {
  const char* name;
  const char* path;  // relative to samples/ or to ../shared/assets
  bool shared;
  bool far_from_origin = false;
};

void PrintTo(const SceneCase& c, std::ostream* os) { *os << c.path; }

class Agreement : public ::testing::TestWithParam<SceneCase> {};

TEST_P(Agreement, TracerAgreesWithEmbreeRayByRay) {
  const SceneCase& sc = GetParam();
  const std::string path = (sc.shared ? kShared : kSamples) + "/" + sc.path;
  if (sc.shared) RTP_NEED_SHARED(path);
  check_scene(path, sc.far_from_origin);
}

INSTANTIATE_TEST_SUITE_P(Samples, Agreement,
                         ::testing::Values(SceneCase{"Lantern", "khronos/Lantern/glTF/Lantern.gltf", false},
                                           SceneCase{"LanternQuantized", "khronos/Lantern/glTF-Quantized/Lantern.gltf", false},
                                           SceneCase{"LanternDraco", "khronos/Lantern/glTF-Draco/Lantern.gltf", false},
                                           SceneCase{"BoomBox", "khronos/BoomBox/glTF/BoomBox.gltf", false},
                                           SceneCase{"FlightHelmet", "khronos/FlightHelmet/glTF/FlightHelmet.gltf", false},
                                           SceneCase{"FlightHelmetMeshopt", "khronos/FlightHelmet/FlightHelmet-meshopt.glb",
                                                     false},
                                           SceneCase{"Suzanne", "khronos/Suzanne/glTF/Suzanne.gltf", false},
                                           SceneCase{"Gallery", "generated/gallery.glb", false},
                                           SceneCase{"ForestSmall", "generated/forest-small.glb", false},
                                           SceneCase{"Far", "generated/far.glb", false, true}),
                         [](const auto& info) { return std::string(info.param.name); });

INSTANTIATE_TEST_SUITE_P(Shared, Agreement,
                         ::testing::Values(SceneCase{"SharedGallery", "scenes/gallery.glb", true},
                                           SceneCase{"SharedForest2k", "scenes/forest-2k.glb", true}),
                         [](const auto& info) { return std::string(info.param.name); });

// The instance-wise double judge (used above the brute force's limit, and by rtpack-bench) must answer
// exactly as the flattened brute force does: every ray kind, closest and any hit, on instanced scenes
// near and far from the origin.
TEST(InstanceReference, AnswersExactlyAsTheBruteForce) {
  for (const char* name : {"generated/gallery.glb", "generated/far.glb"}) {
    SCOPED_TRACE(name);
    const Scene scene = import_gltf(kSamples + "/" + name);
    const EmbreeOracle embree(scene, OracleQuality::kHigh);
    RayGenOptions g;
    g.seed = 11;
    g.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { embree.closest(r, h, n); };
    std::vector<fmt::Ray> rays;
    for (RayKind kind : kAllRayKinds) {
      const auto v = generate_rays(scene, kind, 300, g);
      rays.insert(rays.end(), v.begin(), v.end());
    }
    const size_t n = rays.size();
    const BruteForceReference brute(scene);
    const InstanceReference by_instance(scene);
    std::vector<fmt::Hit> a(n), b(n);
    std::vector<uint8_t> oa(n), ob(n);
    brute.closest(rays.data(), a.data(), n);
    by_instance.closest(rays.data(), b.data(), n);
    brute.occluded(rays.data(), oa.data(), n);
    by_instance.occluded(rays.data(), ob.data(), n);
    size_t hits = 0;
    for (size_t i = 0; i < n; ++i) {
      EXPECT_EQ(std::memcmp(&a[i], &b[i], sizeof(fmt::Hit)), 0) << "ray " << i;
      hits += a[i].t < std::numeric_limits<float>::infinity();
    }
    EXPECT_EQ(oa, ob);
    EXPECT_GT(hits, n / 10);  // the answers compared include real hits
  }
}

}  // namespace RTP_UNITY_ID
}  // namespace
