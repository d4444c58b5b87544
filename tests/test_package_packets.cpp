// Issue 11 packets through a package (Wu 2016 §3.4.1): the Hilbert tile order of an image's primary
// rays is a permutation whose aligned runs of 4, 8 and 16 are 2x2, 2x4 and 4x4 pixel blocks, and
// PackageTracer::closest with packets of 4, 8 and 16 gives the single-ray hits bit for bit on packages
// of several batching points, culling on and off, every SIMD ISA — with the packet path really taken.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "cluster/cluster.h"
#include "mesh/prepare.h"
#include "oracle/rays.h"
#include "package/write_package.h"
#include "scene/import.h"
#include "trace/package_tracer.h"
#include "reader/tile_order.h"
#include "test_trace_util.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

TEST(TileOrder, HilbertIndexIsABijectionWhoseNeighboursShareASide) {
  for (uint32_t n : {1u, 2u, 4u, 8u, 64u}) {
    std::vector<int> x_at(size_t(n) * n, -1), y_at(size_t(n) * n, -1);
    for (uint32_t y = 0; y < n; ++y)
      for (uint32_t x = 0; x < n; ++x) {
        const uint64_t d = hilbert_index(n, x, y);
        ASSERT_LT(d, uint64_t(n) * n) << n << ": " << x << "," << y;
        ASSERT_EQ(x_at[d], -1) << n << ": position " << d << " taken twice";
        x_at[d] = int(x), y_at[d] = int(y);
      }
    for (size_t d = 1; d < size_t(n) * n; ++d) {
      const int step = std::abs(x_at[d] - x_at[d - 1]) + std::abs(y_at[d] - y_at[d - 1]);
      EXPECT_EQ(step, 1) << n << ": positions " << d - 1 << " and " << d << " are not side neighbours";
    }
  }
}

TEST(TileOrder, EveryPixelOnceAndAlignedRunsAreCompactBlocks) {
  struct Size {
    int w, h;
  };
  for (const Size s :
       {Size{1, 1}, Size{7, 5}, Size{3, 17}, Size{64, 64}, Size{96, 64}, Size{1280, 720}, Size{130, 66}, Size{1366, 768}}) {
    const std::vector<uint32_t> order = hilbert_tile_order(s.w, s.h);
    ASSERT_EQ(order.size(), size_t(s.w) * size_t(s.h)) << s.w << "x" << s.h;
    std::vector<uint8_t> seen(order.size(), 0);
    for (uint32_t p : order) {
      ASSERT_LT(p, order.size());
      ASSERT_EQ(seen[p]++, 0) << s.w << "x" << s.h << ": pixel " << p << " twice";
    }
    // Runs of 4 / 8 / 16 aligned in the order: 2x2, 2x4 (or 4x2), 4x4 blocks over all the whole tiles,
    // which come before the cut ones (130x66: 8192 of its 8580 pixels); consecutive tiles touch.
    const size_t whole = size_t(s.w / kTileSide) * size_t(s.h / kTileSide) * kTileSide * kTileSide;
    for (size_t k = whole; k < order.size(); ++k) {  // the rest: pixels of cut tiles only
      const uint32_t x = order[k] % uint32_t(s.w), y = order[k] / uint32_t(s.w);
      ASSERT_TRUE(x >= uint32_t(s.w / kTileSide * kTileSide) || y >= uint32_t(s.h / kTileSide * kTileSide))
          << s.w << "x" << s.h << ": pixel " << x << "," << y << " of a whole tile after the whole tiles";
    }
    for (size_t run : {4u, 8u, 16u})
      for (size_t b = 0; b + run <= whole; b += run) {
        int x0 = s.w, x1 = -1, y0 = s.h, y1 = -1;
        for (size_t k = b; k < b + run; ++k) {
          const int x = int(order[k] % uint32_t(s.w)), y = int(order[k] / uint32_t(s.w));
          x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
        }
        EXPECT_EQ(size_t(x1 - x0 + 1) * size_t(y1 - y0 + 1), run) << s.w << "x" << s.h << ": run at " << b;
      }
    // On a power-of-two square of tiles, every tile is a side neighbour of the one before.
    const int tiles_x = s.w / kTileSide, tiles_y = s.h / kTileSide;
    if (s.w % kTileSide == 0 && s.h % kTileSide == 0 && tiles_x == tiles_y && (tiles_x & (tiles_x - 1)) == 0) {
      for (size_t b = kTileSide * kTileSide; b < order.size(); b += kTileSide * kTileSide) {
        const int ax = int(order[b - 1] % uint32_t(s.w)) / kTileSide, ay = int(order[b - 1] / uint32_t(s.w)) / kTileSide;
        const int bx = int(order[b] % uint32_t(s.w)) / kTileSide, by = int(order[b] / uint32_t(s.w)) / kTileSide;
        EXPECT_EQ(std::abs(ax - bx) + std::abs(ay - by), 1) << s.w << "x" << s.h << ": tile step at " << b;
      }
    }
  }
  // A cut tile keeps the pixels inside the image, in the order of the full tile.
  const std::vector<uint32_t> order = hilbert_tile_order(6, 4);
  const std::set<uint32_t> second_tile(order.begin() + 16, order.end());
  EXPECT_EQ(second_tile, (std::set<uint32_t>{4, 5, 10, 11, 16, 17, 22, 23}));
  EXPECT_TRUE(hilbert_tile_order(0, 5).empty());
}

using trace_test::simd_isas;

struct Package {
  Scene scene;
  std::unique_ptr<PackageReader> reader;
  std::unique_ptr<PackageTracer> tracer;
};

// import -> prepare -> about `points` batching points -> write_package (culling DAGs) -> load in core.
Package package(const std::string& gltf, const fs::path& dir, uint64_t points) {
  Package p;
  p.scene = import_gltf(gltf);
  prepare_scene(p.scene, {});
  ClusterOptions co;
  co.chunk_target = std::max<uint64_t>(64, p.scene.instanced_triangles() / points);
  const std::string path = (dir / (fs::path(gltf).stem().string() + ".rtp")).string();
  write_package(p.scene, plan_batching_points(p.scene, co), path, ConvertOptions{});
  p.reader = std::make_unique<PackageReader>(path);
  p.tracer = load_package_in_core(*p.reader);
  return p;
}

// Primary rays (4x4 jittered tiles), the same with a few made invalid, random and bounce rays.
std::vector<fmt::Ray> rays_for(const Package& p) {
  RayGenOptions gen;
  gen.seed = 23;
  gen.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) {
    PackageTraceOptions o;
    o.isa = detect_isa();
    p.tracer->closest(r, h, n, o);
  };
  // The same counts under ASan (about 8 s there): fewer primary rays leave gallery's sparse view too few
  // tiles that enter a point together to show packets at all.
  std::vector<fmt::Ray> rays = generate_rays(p.scene, RayKind::kPrimary, 8192, gen);
  for (size_t i = 5; i < rays.size(); i += 37) rays[i].tnear = std::numeric_limits<float>::quiet_NaN();
  for (RayKind k : {RayKind::kRandom, RayKind::kBounce}) {
    const std::vector<fmt::Ray> more = generate_rays(p.scene, k, 2048, gen);
    rays.insert(rays.end(), more.begin(), more.end());
  }
  rays.resize(rays.size() - 3);  // a last run shorter than every packet
  return rays;
}

void expect_packets_equal_single(const Package& p, const std::string& name) {
  ASSERT_GT(p.tracer->batching_points(), 2u) << name << ": the test needs several batching points";
  ASSERT_TRUE(p.tracer->has_dags()) << name;
  const std::vector<fmt::Ray> rays = rays_for(p);
  for (Isa isa : simd_isas())
    for (bool cull : {true, false}) {
      PackageTraceOptions o;
      o.isa = isa;
      o.cull = cull;
      std::vector<fmt::Hit> want(rays.size()), got(rays.size());
      const PackageTraceStats single = p.tracer->closest(rays.data(), want.data(), rays.size(), o);
      EXPECT_EQ(single.packets, 0u);
      size_t hits = 0;
      for (const fmt::Hit& h : want) hits += h.prim != fmt::Hit::kNone;
      ASSERT_GT(hits, rays.size() / 20) << name << ": too few hits to compare";  // gallery: about 6 %
      for (uint32_t size : {4u, 8u, 16u}) {
        o.packet = size;
        std::fill(got.begin(), got.end(), fmt::Hit{-1, 7, 7, 7, 7});
        const PackageTraceStats st = p.tracer->closest(rays.data(), got.data(), rays.size(), o);
        const std::string what =
            name + " " + isa_name(isa) + (cull ? " culled" : " unculled") + ", packets of " + std::to_string(size);
        size_t bad = 0;
        for (size_t i = 0; i < rays.size(); ++i)
          if (std::memcmp(&want[i], &got[i], sizeof(fmt::Hit)) != 0 && bad++ < 5) {
            ADD_FAILURE() << what << ": ray " << i << " t " << got[i].t << " vs " << want[i].t << ", prim " << got[i].prim
                          << " vs " << want[i].prim << ", instance " << got[i].instance << " vs " << want[i].instance;
          }
        EXPECT_EQ(bad, 0u) << what;
        EXPECT_EQ(st.rays, rays.size()) << what;
        EXPECT_EQ(st.invalid_rays, single.invalid_rays) << what;
        EXPECT_GT(st.invalid_rays, 0u) << what;
        // The same batching-point visits as single rays, and primary tiles really went as packets.
        EXPECT_EQ(st.point_visits, single.point_visits) << what;
        EXPECT_EQ(st.culled_visits, single.culled_visits) << what;
        // A third of the rays are incoherent (random, bounce): they go alone. Of the visits of all rays,
        // 8-25 % went in packets on these scenes; a packet holds at least 3 rays.
        EXPECT_GT(st.packets, 0u) << what;
        EXPECT_GE(st.packet_rays, 3 * st.packets) << what;
        EXPECT_GT(st.packet_rays, (st.point_visits - st.culled_visits) / 20) << what;
        EXPECT_GT(st.packet_node_tests, 0u) << what;
        EXPECT_LE(st.packet_active_lanes, st.packet_node_tests * size) << what;
      }
    }
}

TEST(PackagePackets, ClosestHitsEqualSingleRaysOnASample) {
  if (simd_isas().empty()) GTEST_SKIP() << "no AVX2 on this CPU: packets are SIMD only";
  const fs::path dir = fs::path(testing::TempDir()) / "rtp_package_packets_sample";
  fs::create_directories(dir);
  expect_packets_equal_single(package(RTP_SOURCE_DIR "/samples/khronos/FlightHelmet/glTF/FlightHelmet.gltf", dir, 8),
                              "FlightHelmet");
  fs::remove_all(dir);
}

TEST(PackagePackets, ClosestHitsEqualSingleRaysOnAnInstancedScene) {
  if (simd_isas().empty()) GTEST_SKIP() << "no AVX2 on this CPU: packets are SIMD only";
  const fs::path dir = fs::path(testing::TempDir()) / "rtp_package_packets_instanced";
  fs::create_directories(dir);
  expect_packets_equal_single(package(RTP_SOURCE_DIR "/samples/generated/gallery.glb", dir, 12), "gallery");
  fs::remove_all(dir);
}

TEST(PackagePackets, ScalarIsaAndSizeZeroTraceSingleRays) {
  const fs::path dir = fs::path(testing::TempDir()) / "rtp_package_packets_scalar";
  fs::create_directories(dir);
  const Package p = package(RTP_SOURCE_DIR "/samples/khronos/Lantern/glTF/Lantern.gltf", dir, 4);
  const std::vector<fmt::Ray> rays = rays_for(p);
  std::vector<fmt::Hit> a(rays.size()), b(rays.size());
  PackageTraceOptions o;
  const PackageTraceStats sa = p.tracer->closest(rays.data(), a.data(), rays.size(), o);
  o.packet = 16;  // the scalar reference has no packets: ignored
  const PackageTraceStats sb = p.tracer->closest(rays.data(), b.data(), rays.size(), o);
  EXPECT_EQ(sb.packets, 0u);
  EXPECT_EQ(sa.point_visits, sb.point_visits);
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(fmt::Hit)), 0);
  fs::remove_all(dir);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
