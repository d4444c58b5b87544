// The public API out of core (issue 54, rtpack/rtpack.h): Package::open under a memory budget traces as
// in core; a RayStream through the public types answers every submitted ray, continuation rays
// submitted from the callback included, as Package::trace/occluded in core; a stream over an in-core
// package too; the misuses a renderer can make throw rtpack::Error with the tools' codes; a damaged
// batching point out of core makes the flush that loads it throw code 3 naming the chunk.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <random>

#include "formats/chunk.h"
#include "gltf_builder.h"
#include "reader/reader.h"
#include "rtpack/rtpack.h"
#include "tool_run.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

class ReaderStream : public ::testing::Test {
 protected:
  static fs::path dir, forest;
  static void SetUpTestSuite() {
    dir = temp_dir("ReaderStream");
    forest = dir / "forest.rtp";
    // 40 unique trees (490k triangles) in about 25 batching points: a 5 % budget holds one or two.
    const fs::path glb = dir / "forest.glb";
    ToolResult r = run_tool("rtpack-make-scene", {"forest", "--unique", "--count", "40", "-o", glb.string()}, dir);
    ASSERT_EQ(r.code, 0) << r.err;
    r = run_tool("rtpack-convert", {glb.string(), "-q", "--chunk-target", "20000", "-o", forest.string()}, dir);
    ASSERT_EQ(r.code, 0) << r.err;
  }
  static void TearDownTestSuite() { fs::remove_all(dir); }

  // Rays from a box around the bounds towards random points inside it.
  static std::vector<rtpack::Ray> rays_into(const rtpack::Bounds& b, size_t n, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0, 1);
    std::vector<rtpack::Ray> rays(n);
    for (rtpack::Ray& r : rays) {
      float len = 0;
      for (int k = 0; k < 3; ++k) {
        const float ext = b.hi[k] - b.lo[k];
        r.org[k] = b.lo[k] - 0.3f * ext + 1.6f * ext * u(rng);
        r.dir[k] = b.lo[k] + ext * u(rng) - r.org[k];
        len += r.dir[k] * r.dir[k];
      }
      for (float& d : r.dir) d /= std::sqrt(len);
      r.tnear = 0;
      r.tfar = INFINITY;
    }
    return rays;
  }
};
fs::path ReaderStream::dir, ReaderStream::forest;

TEST_F(ReaderStream, OutOfCoreTraceAndOccludedAreTheInCoreAnswers) {
  const rtpack::Package in_core = rtpack::Package::open(forest.string());
  rtpack::OpenOptions o;
  o.memory_fraction = 0.1;
  const rtpack::Package ooc = rtpack::Package::open(forest.string(), o);
  EXPECT_FALSE(in_core.out_of_core());
  ASSERT_TRUE(ooc.out_of_core());
  ASSERT_GT(in_core.batching_points().size(), 8u);
  EXPECT_EQ(ooc.geometry_bytes(), in_core.geometry_bytes());
  EXPECT_LT(ooc.minimum_budget(), ooc.geometry_bytes() / 4);
  const std::vector<rtpack::Ray> rays = rays_into(in_core.info().bounds, 4000, 3);
  std::vector<rtpack::Hit> a(rays.size()), b(rays.size());
  std::vector<uint8_t> oa(rays.size()), ob(rays.size());
  const size_t hits = in_core.trace(rays.data(), a.data(), rays.size());
  EXPECT_GT(hits, rays.size() / 10);
  EXPECT_EQ(ooc.trace(rays.data(), b.data(), rays.size()), hits);
  ASSERT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof a[0]), 0);
  in_core.occluded(rays.data(), oa.data(), rays.size());
  ooc.occluded(rays.data(), ob.data(), rays.size());
  EXPECT_EQ(oa, ob);
}

TEST_F(ReaderStream, StreamWithContinuationRaysAnswersAsInCore) {
  const rtpack::Package in_core = rtpack::Package::open(forest.string());
  for (double fraction : {0.0, 0.05, 0.25}) {
    for (bool cull : {true, false}) {
      rtpack::OpenOptions o;
      o.memory_fraction = fraction;
      const rtpack::Package pkg = rtpack::Package::open(forest.string(), o);
      rtpack::StreamOptions so;
      so.max_in_flight = 500;
      so.cull = cull;
      so.threads = 2;
      rtpack::RayStream stream = pkg.stream(so);
      std::vector<rtpack::StreamRay> all;
      for (const rtpack::Ray& r : rays_into(pkg.info().bounds, 2000, 5)) all.push_back({r, all.size(), 0, 0});
      stream.submit(all.data(), all.size());
      std::vector<rtpack::StreamHit> got;
      const rtpack::StreamStats st = stream.flush([&](const rtpack::StreamHit* h, size_t n) {
        for (size_t j = 0; j < n; ++j) {
          got.push_back(h[j]);
          const rtpack::StreamRay& parent = all[h[j].payload];
          if (parent.any || !(h[j].hit.t < INFINITY)) continue;
          // A shadow ray towards a fixed direction from the hit point, off the surface along the normal.
          rtpack::StreamRay shadow{};
          for (int k = 0; k < 3; ++k)
            shadow.ray.org[k] = parent.ray.org[k] + h[j].hit.t * parent.ray.dir[k] + 1e-3f * h[j].normal[k];
          shadow.ray.dir[0] = 0.3f, shadow.ray.dir[1] = 0.9f, shadow.ray.dir[2] = 0.3f;
          shadow.ray.tnear = 0;
          shadow.ray.tfar = INFINITY;
          shadow.payload = all.size();
          shadow.any = 1;
          all.push_back(shadow);
          stream.submit(&shadow, 1);
        }
      });
      const std::string where = "fraction " + std::to_string(fraction) + (cull ? " cull" : " no cull");
      ASSERT_EQ(got.size(), all.size()) << where;
      ASSERT_GT(all.size(), 2100u) << where;
      EXPECT_EQ(st.rays, all.size()) << where;
      if (fraction > 0) {
        EXPECT_LT(st.budget_bytes, pkg.geometry_bytes()) << where;
        EXPECT_GT(st.chunks_loaded, 0u) << where;
      }
      std::vector<rtpack::Ray> r(all.size());
      for (size_t i = 0; i < all.size(); ++i) r[i] = all[i].ray;
      std::vector<rtpack::Hit> hits(r.size());
      std::vector<uint8_t> occ(r.size());
      in_core.trace(r.data(), hits.data(), r.size());
      in_core.occluded(r.data(), occ.data(), r.size());
      for (const rtpack::StreamHit& h : got) {
        const size_t i = h.payload;
        if (all[i].any) {
          ASSERT_EQ(h.occluded, occ[i]) << where << " ray " << i;
          ASSERT_EQ(h.hit.instance, rtpack::Hit::kNone) << where;
        } else {
          ASSERT_EQ(std::memcmp(&h.hit, &hits[i], sizeof h.hit), 0) << where << " ray " << i;
        }
      }
    }
  }
}

TEST_F(ReaderStream, MisusesThrowWithTheToolsCodes) {
  rtpack::OpenOptions o;
  o.memory_budget = 1000;
  try {
    (void)rtpack::Package::open(forest.string(), o);
    FAIL() << "a budget below the largest batching point opened";
  } catch (const rtpack::Error& e) {
    EXPECT_EQ(e.code(), 1);
    EXPECT_NE(std::string(e.what()).find("minimum"), std::string::npos) << e.what();
  }
  o.memory_budget = 0;
  o.memory_fraction = 1.5;
  EXPECT_THROW((void)rtpack::Package::open(forest.string(), o), rtpack::Error);
  o.memory_fraction = 0.2;
  const rtpack::Package pkg = rtpack::Package::open(forest.string(), o);
  rtpack::StreamOptions so;
  so.max_in_flight = 0;
  EXPECT_THROW((void)pkg.stream(so), rtpack::Error);
  rtpack::RayStream stream = pkg.stream();
  const std::vector<rtpack::Ray> rays = rays_into(pkg.info().bounds, 64, 9);
  std::vector<rtpack::StreamRay> in;
  in.reserve(rays.size());
  for (const rtpack::Ray& r : rays) in.push_back({r, in.size(), 0, 0});
  stream.submit(in.data(), in.size());
  // Tracing through the package a stream holds, from its callback, would reenter the scheduler.
  try {
    stream.flush([&](const rtpack::StreamHit*, size_t) {
      rtpack::Hit h;
      pkg.trace(rays.data(), &h, 1);
    });
    FAIL() << "trace() from the callback of an out-of-core stream did not throw";
  } catch (const rtpack::Error& e) {
    EXPECT_EQ(e.code(), 1);
    EXPECT_NE(std::string(e.what()).find("callback"), std::string::npos) << e.what();
  }
  // The stream is empty after the failed flush, and works again.
  stream.submit(in.data(), in.size());
  size_t back = 0;
  stream.flush([&](const rtpack::StreamHit*, size_t n) { back += n; });
  EXPECT_EQ(back, in.size());
}

TEST_F(ReaderStream, ADamagedBatchingPointFailsTheFlushThatLoadsIt) {
  const fs::path bad = dir / "bad.rtp";
  fs::copy_file(forest, bad, fs::copy_options::overwrite_existing);
  size_t chunk = 0;
  {
    const PackageReader r(bad.string());
    for (size_t i = 0; i < r.toc().size(); ++i)
      if (r.toc()[i].kind == uint32_t(fmt::ChunkKind::kBatchingPoint)) chunk = i;
    std::fstream f(bad, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(std::streamoff(r.toc()[chunk].offset + r.toc()[chunk].stored_size / 2));
    f.put(char(0x5A));
  }
  rtpack::OpenOptions o;
  o.memory_fraction = 0.05;
  const rtpack::Package pkg = rtpack::Package::open(bad.string(), o);  // the resident chunks are intact
  rtpack::RayStream stream = pkg.stream();
  std::vector<rtpack::StreamRay> in;
  for (const rtpack::Ray& r : rays_into(pkg.info().bounds, 20000, 11)) in.push_back({r, in.size(), 0, 0});
  stream.submit(in.data(), in.size());
  try {
    stream.flush([](const rtpack::StreamHit*, size_t) {});
    FAIL() << "a flush over a damaged batching point succeeded";
  } catch (const rtpack::Error& e) {
    EXPECT_EQ(e.code(), 3) << e.what();
    EXPECT_NE(std::string(e.what()).find("chunk #" + std::to_string(chunk)), std::string::npos) << e.what();
  }
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
