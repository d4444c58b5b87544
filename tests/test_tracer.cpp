// The one tracer interface (trace/tracer.h, issue 53): open_tracer in core and out of core give the
// same closest, any and multi-hit answers, byte for byte, as the in-core package tracer called ray by
// ray, at 1 and 2 threads; the in-core tracer's stats are the sums of the per-ray calls'; a budget below
// the minimum is refused as open_out_of_core refuses it.
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "core/error.h"
#include "gltf_builder.h"
#include "oracle/rays.h"
#include "package/convert.h"
#include "reader/reader.h"
#include "trace/tracer.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

template <class T>
int64_t first_difference(const std::vector<T>& a, const std::vector<T>& b) {
  if (a.size() != b.size()) return 0;
  for (size_t i = 0; i < a.size(); ++i)
    if (std::memcmp(&a[i], &b[i], sizeof(T)) != 0) return int64_t(i);
  return -1;
}

TEST(Tracer, InCoreAndOutOfCoreAnswerAsThePackageTracerRayByRay) {
  const fs::path dir = temp_dir("tracer");
  const std::string pkg = (dir / "gallery.rtp").string();
  ConvertSettings cs;
  cs.input = (source_dir() / "samples/generated/gallery.glb").string();
  cs.output = pkg;
  cs.chunk_target = 2000;  // a few dozen batching points, so a small budget evicts
  const Scene scene = convert_scene(cs).scene;
  const PackageReader reader(pkg);
  const auto loaded = load_package_in_core(reader);
  ASSERT_GT(loaded->batching_points(), 4u);
  PackageTraceOptions o;
  o.isa = detect_isa();
  RayGenOptions g;
  g.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { loaded->closest(r, h, n, o); };
  std::vector<fmt::Ray> rays = generate_rays(scene, RayKind::kRandom, 2000, g);
  for (RayKind k : {RayKind::kPrimary, RayKind::kBounce}) {
    const std::vector<fmt::Ray> more = generate_rays(scene, k, 2000, g);
    rays.insert(rays.end(), more.begin(), more.end());
  }
  rays.push_back(rays.front());
  rays.back().dir[0] = std::nanf("");  // invalid: counted, a miss
  const size_t n = rays.size();
  constexpr uint32_t kMulti = 3;
  // The reference: the loaded package's own calls, one ray at a time.
  std::vector<fmt::Hit> want(n), want_multi(n * kMulti);
  std::vector<uint8_t> want_occ(n);
  std::vector<uint32_t> want_counts(n);
  PackageTraceStats want_st;
  for (size_t i = 0; i < n; ++i) {
    const PackageTraceStats s = loaded->closest(&rays[i], &want[i], 1, o);
    want_st.add(s);
    want_st.point_visits += s.point_visits, want_st.culled_visits += s.culled_visits;
    loaded->any(&rays[i], &want_occ[i], 1, o);
    loaded->multi(&rays[i], 1, kMulti, &want_multi[i * kMulti], &want_counts[i], o);
  }
  uint64_t hits = 0;
  for (const fmt::Hit& h : want) hits += h.t < INFINITY;
  ASSERT_GT(hits, 300u);  // the rays meet the geometry: the comparison has answers to compare
  const uint64_t budget = std::max(minimum_budget(reader), on_demand_bytes(reader) / 8);
  for (const uint64_t b : {uint64_t(0), budget}) {
    for (const int threads : {1, 2}) {
      SCOPED_TRACE("budget " + std::to_string(b) + ", threads " + std::to_string(threads));
      tbb::task_arena arena(threads);
      arena.execute([&] {
        TracerConfig tc;
        tc.memory_budget = b;
        const std::unique_ptr<Tracer> t = open_tracer(reader, tc);
        EXPECT_EQ(t->out_of_core(), b != 0);
        EXPECT_EQ(t->has_dags(), loaded->has_dags());
        std::vector<fmt::Hit> got(n), got_multi(n * kMulti);
        std::vector<uint8_t> occ(n);
        std::vector<uint32_t> counts(n);
        const TracerStats st = t->closest(rays.data(), got.data(), n, o);
        EXPECT_EQ(first_difference(want, got), -1);
        EXPECT_EQ(st.rays, n);
        EXPECT_EQ(st.invalid_rays, 1u);
        if (b == 0) {  // in core: the block loop sums what the per-ray calls count
          EXPECT_EQ(st.point_visits, want_st.point_visits);
          EXPECT_EQ(st.culled_visits, want_st.culled_visits);
          EXPECT_GT(t->load_stats().chunks, 0u);
        } else {
          EXPECT_GT(st.cache.loads, 0u);
          EXPECT_LE(st.cache.peak_resident_bytes, b);
        }
        t->any(rays.data(), occ.data(), n, o);
        EXPECT_EQ(first_difference(want_occ, occ), -1);
        t->multi(rays.data(), n, kMulti, got_multi.data(), counts.data(), o);
        EXPECT_EQ(first_difference(want_counts, counts), -1);
        EXPECT_EQ(first_difference(want_multi, got_multi), -1);
      });
    }
  }
  TracerConfig small;
  small.memory_budget = minimum_budget(reader) - 1;
  try {
    open_tracer(reader, small);
    ADD_FAILURE() << "a budget below the minimum was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ExitCode::kUsage);
    EXPECT_NE(std::string(e.what()).find("minimum"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
