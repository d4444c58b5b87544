// The ray stream (issue 54, lib/trace/ray_stream.h): rays submitted with payloads, closest and any hits
// mixed, a cap on rays in flight far below the rays submitted, continuation rays submitted from the
// callback; every answer byte-identical to the in-core tracer's for budgets of 100 %, 25 % and 5 %, 1 and
// 2 threads, culling on and off; every payload handed back once; the normals those of the hit
// triangles in the scene (brute force over the imported scene's transforms).
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "core/error.h"
#include "gltf_builder.h"
#include "oracle/rays.h"
#include "package/convert.h"
#include "trace/out_of_core.h"
#include "trace/package_tracer.h"
#include "trace/ray_stream.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

// A sample converted into about `points` batching points.
Scene convert_into_points(const std::string& input, const std::string& out, int width, uint64_t points) {
  ConvertSettings cs;
  cs.input = input;
  cs.output = out;
  cs.width = width;
  ConvertSettings dry = cs;
  dry.dry_run = true;
  cs.chunk_target = std::max<uint64_t>(64, convert_scene(dry).scene.instanced_triangles() / points);
  return convert_scene(cs).scene;
}

PackageTraceOptions trace_options(bool cull) {
  PackageTraceOptions o;
  o.isa = detect_isa();
  o.cull = cull;
  return o;
}

struct StreamCase {
  std::string name;
  fs::path input;
  int width;
};

class RayStreamTest : public ::testing::TestWithParam<StreamCase> {
 protected:
  void SetUp() override {
    const StreamCase& c = GetParam();
    path_ = (fs::path(::testing::TempDir()) / ("stream_" + c.name + ".rtp")).string();
    scene_ = convert_into_points(c.input.string(), path_, c.width, 40);
    reader_ = std::make_unique<PackageReader>(path_);
    in_core_ = load_package_in_core(*reader_);
    RayGenOptions g;
    g.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { in_core_->closest(r, h, n, trace_options(false)); };
    const size_t n = std::getenv("RTP_SANITIZED") ? 200 : 2000;
    for (RayKind k : {RayKind::kPrimary, RayKind::kRandom, RayKind::kBounce, RayKind::kShadow}) {
      g.seed = 7 + uint64_t(k);
      const std::vector<fmt::Ray> r = generate_rays(scene_, k, n, g);
      rays_.insert(rays_.end(), r.begin(), r.end());
    }
  }

  // What the in-core tracer answers for `rays` (closest when any[i] = 0, else occluded).
  std::vector<StreamResult> reference(const std::vector<StreamRay>& rays) const {
    std::vector<fmt::Ray> r(rays.size());
    for (size_t i = 0; i < rays.size(); ++i) r[i] = rays[i].ray;
    std::vector<fmt::Hit> hits(r.size());
    std::vector<uint8_t> occ(r.size());
    in_core_->closest(r.data(), hits.data(), r.size(), trace_options(false));
    in_core_->any(r.data(), occ.data(), r.size(), trace_options(false));
    std::vector<StreamResult> out(rays.size());
    for (size_t i = 0; i < rays.size(); ++i) {
      out[i].payload = rays[i].payload;
      out[i].hit =
          rays[i].any ? fmt::Hit{std::numeric_limits<float>::infinity(), fmt::Hit::kNone, fmt::Hit::kNone, 0, 0} : hits[i];
      out[i].occluded = rays[i].any ? occ[i] : (hits[i].t < std::numeric_limits<float>::infinity() ? 1 : 0);
    }
    return out;
  }

  uint64_t budget(int percent) const { return std::max(minimum_budget(*reader_), on_demand_bytes(*reader_) * percent / 100); }

  std::string path_;
  Scene scene_;
  std::unique_ptr<PackageReader> reader_;
  std::unique_ptr<PackageTracer> in_core_;
  std::vector<fmt::Ray> rays_;
};

void expect_same_answer(const StreamResult& got, const StreamResult& want, const std::string& where) {
  ASSERT_EQ(got.payload, want.payload) << where;
  EXPECT_EQ(got.occluded, want.occluded) << where << " payload " << got.payload;
  EXPECT_EQ(std::memcmp(&got.hit, &want.hit, sizeof got.hit), 0)
      << where << " payload " << got.payload << ": t " << got.hit.t << " vs " << want.hit.t << ", instance " << got.hit.instance
      << " vs " << want.hit.instance << ", prim " << got.hit.prim << " vs " << want.hit.prim;
}

TEST_P(RayStreamTest, AnswersAsTheInCoreTracerWhateverTheBudgetThreadsAndCulling) {
  std::vector<StreamRay> in(rays_.size());
  for (size_t i = 0; i < rays_.size(); ++i) in[i] = {rays_[i], 1000 + i, uint32_t(i % 3 == 2), 0};
  const std::vector<StreamResult> want = reference(in);
  for (int percent : {100, 25, 5})
    for (int threads : {1, 2})
      for (bool cull : {true, false}) {
        const std::string where =
            std::to_string(percent) + " %, " + std::to_string(threads) + " threads, cull " + (cull ? "on" : "off");
        auto tracer = open_out_of_core(*reader_, budget(percent));
        StreamOptions so;
        so.trace = trace_options(cull);
        so.max_in_flight = 257;  // most rays wait in submit()'s buffer
        auto stream = tracer->open_stream(so);
        stream->submit(in.data(), in.size() / 2);  // the rest from the callback
        bool rest = false;
        std::vector<StreamResult> got(in.size());
        std::vector<int> seen(in.size(), 0);
        tbb::task_arena arena(threads);
        const TracerStats st = arena.execute([&] {
          return stream->flush([&](const StreamResult* r, size_t n) {
            for (size_t j = 0; j < n; ++j) {
              const size_t i = r[j].payload - 1000;
              ASSERT_LT(i, in.size());
              got[i] = r[j];
              ++seen[i];
            }
            if (!rest) stream->submit(in.data() + in.size() / 2, in.size() - in.size() / 2), rest = true;
          });
        });
        EXPECT_EQ(st.rays, in.size()) << where;
        EXPECT_LE(st.cache.peak_resident_bytes, budget(percent)) << where;
        for (size_t i = 0; i < in.size(); ++i) {
          ASSERT_EQ(seen[i], 1) << where << ": ray " << i << " handed back " << seen[i] << " times";
          expect_same_answer(got[i], want[i], where);
        }
        if (cull && tracer->has_dags() && percent == 5) {
          EXPECT_GT(st.dag_tests, 0u) << where;
        }
      }
}

// A bounce from each closest hit along a direction made from the payload, three levels deep, submitted
// from the callback: every ray of every level answered as the in-core tracer answers it.
TEST_P(RayStreamTest, ContinuationRaysSubmittedFromTheCallbackAreAnsweredAsInCore) {
  std::vector<StreamRay> all;
  for (size_t i = 0; i < rays_.size(); i += 2) all.push_back({rays_[i], all.size(), 0, 0});
  const size_t primary = all.size();
  auto tracer = open_out_of_core(*reader_, budget(25));
  StreamOptions so;
  so.trace = trace_options(true);
  so.max_in_flight = 1024;
  auto stream = tracer->open_stream(so);
  stream->submit(all.data(), all.size());
  std::map<uint64_t, StreamResult> got;
  std::vector<int> depth(all.size(), 0);
  const TracerStats st = stream->flush([&](const StreamResult* r, size_t n) {
    for (size_t j = 0; j < n; ++j) {
      ASSERT_TRUE(got.emplace(r[j].payload, r[j]).second) << "payload " << r[j].payload << " handed back twice";
      const StreamRay& parent = all[r[j].payload];
      if (!(r[j].hit.t < std::numeric_limits<float>::infinity()) || depth[r[j].payload] >= 3) continue;
      StreamRay next{};
      for (int k = 0; k < 3; ++k) next.ray.org[k] = parent.ray.org[k] + r[j].hit.t * parent.ray.dir[k] + 1e-3f * r[j].normal[k];
      const float a = float(r[j].payload % 97) * 0.0647f, b = float(r[j].payload % 89) * 0.0353f;
      next.ray.dir[0] = r[j].normal[0] + std::cos(a) * std::sin(b);
      next.ray.dir[1] = r[j].normal[1] + std::sin(a) * std::sin(b);
      next.ray.dir[2] = r[j].normal[2] + std::cos(b);
      next.ray.tnear = 0;
      next.ray.tfar = std::numeric_limits<float>::infinity();
      next.payload = all.size();
      next.any = uint32_t(all.size() % 4 == 0);  // some shadow-like rays among the bounces
      depth.push_back(depth[r[j].payload] + 1);
      all.push_back(next);
      stream->submit(&next, 1);
    }
  });
  ASSERT_GT(all.size(), primary + primary / 20) << "too few continuation rays to test anything";
  ASSERT_EQ(got.size(), all.size());
  EXPECT_EQ(st.rays, all.size());
  EXPECT_GT(st.passes, st.rounds) << "continuation rays never met a round's points while resident";
  const std::vector<StreamResult> want = reference(all);
  for (size_t i = 0; i < all.size(); ++i) expect_same_answer(got[i], want[i], "continuation");
}

// The normal of each closest hit is that of the hit triangle in the scene: cross(v1 - v0, v2 - v0) of
// its world-space vertices, normalized.
TEST_P(RayStreamTest, NormalsAreThoseOfTheHitTriangles) {
  std::vector<StreamRay> in;
  for (size_t i = 0; i < rays_.size(); ++i) in.push_back({rays_[i], i, 0, 0});
  auto tracer = open_out_of_core(*reader_, budget(25));
  StreamOptions so;
  so.trace = trace_options(true);
  auto stream = tracer->open_stream(so);
  stream->submit(in.data(), in.size());
  size_t hits = 0;
  stream->flush([&](const StreamResult* r, size_t n) {
    for (size_t j = 0; j < n; ++j) {
      if (!(r[j].hit.t < std::numeric_limits<float>::infinity())) continue;
      ++hits;
      ASSERT_LT(r[j].hit.instance, scene_.instances.size());
      const Instance& inst = scene_.instances[r[j].hit.instance];
      const Mesh& m = scene_.meshes[inst.mesh];
      ASSERT_LT(r[j].hit.prim, m.triangle_count());
      double w[3][3];
      for (int v = 0; v < 3; ++v) {
        const Vec3f& p = m.positions[m.indices[3 * size_t(r[j].hit.prim) + v]];
        for (int row = 0; row < 3; ++row)
          w[v][row] =
              inst.transform(row, 0) * p.x + inst.transform(row, 1) * p.y + inst.transform(row, 2) * p.z + inst.transform(row, 3);
      }
      const double e1[3] = {w[1][0] - w[0][0], w[1][1] - w[0][1], w[1][2] - w[0][2]};
      const double e2[3] = {w[2][0] - w[0][0], w[2][1] - w[0][1], w[2][2] - w[0][2]};
      double c[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
      const double len = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
      if (!(len > 0)) continue;
      const double dot = (c[0] * r[j].normal[0] + c[1] * r[j].normal[1] + c[2] * r[j].normal[2]) / len;
      ASSERT_GT(dot, 0.999) << "payload " << r[j].payload << " instance " << r[j].hit.instance << " prim " << r[j].hit.prim;
      const double nl = std::sqrt(double(r[j].normal[0]) * r[j].normal[0] + double(r[j].normal[1]) * r[j].normal[1] +
                                  double(r[j].normal[2]) * r[j].normal[2]);
      ASSERT_NEAR(nl, 1.0, 1e-5);
    }
  });
  EXPECT_GT(hits, in.size() / 40);  // far.glb: about 5 % of the rays hit
}

TEST_P(RayStreamTest, RefusesAFlushFromItsOwnCallbackAndBadCaps) {
  auto tracer = open_out_of_core(*reader_, budget(100));
  StreamOptions so;
  so.max_in_flight = 0;
  EXPECT_THROW(tracer->open_stream(so), Error);
  so.max_in_flight = 16;
  auto stream = tracer->open_stream(so);
  StreamRay r{rays_[0], 1, 0, 0};
  stream->submit(&r, 1);
  EXPECT_THROW(stream->flush([&](const StreamResult*, size_t) { stream->flush([](const StreamResult*, size_t) {}); }), Error);
  // The stream starts over empty after the failed flush and answers again.
  stream->submit(&r, 1);
  size_t n_back = 0;
  stream->flush([&](const StreamResult*, size_t n) { n_back += n; });
  EXPECT_EQ(n_back, 1u);
}

INSTANTIATE_TEST_SUITE_P(Samples, RayStreamTest,
                         ::testing::Values(StreamCase{"forest", source_dir() / "samples/generated/forest-small.glb", 8},
                                           StreamCase{"lantern", source_dir() / "samples/khronos/Lantern/glTF/Lantern.gltf", 8},
                                           StreamCase{"far", source_dir() / "samples/generated/far.glb", 4}),
                         [](const auto& info) { return info.param.name; });

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
