// The public reader API (lib/rtpack/rtpack.h, installed as rtpack::reader) against the internals it
// wraps, ray by ray: same hits and occlusion as the package tracer for every thread count, same
// attributes as AttributeLookup, same camera rays, packets of tiled camera rays give the single rays'
// hits; errors carry the tools' codes and name the file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include "gltf_builder.h"
#include "reader/attribute_lookup.h"
#include "reader/camera.h"
#include "reader/reader.h"
#include "rtpack/rtpack.h"
#include "tool_run.h"
#include "trace/package_tracer.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

class ReaderApi : public ::testing::Test {
 protected:
  static fs::path dir, gallery, helmet;
  static void SetUpTestSuite() {
    dir = temp_dir("ReaderApi");
    gallery = dir / "gallery.rtp";
    helmet = dir / "helmet.rtp";
    ToolResult r = run_tool("rtpack-convert",
                            {(source_dir() / "samples/generated/gallery.glb").string(), "-q", "-o", gallery.string()}, dir);
    ASSERT_EQ(r.code, 0) << r.err;
    r = run_tool("rtpack-convert",
                 {(source_dir() / "samples/khronos/FlightHelmet/glTF/FlightHelmet.gltf").string(), "-q", "--attributes",
                  "normal,uv", "-o", helmet.string()},
                 dir, {}, 120);
    ASSERT_EQ(r.code, 0) << r.err;
  }
  static void TearDownTestSuite() { fs::remove_all(dir); }

  // Rays from a box around the bounds in random directions, and one invalid (NaN) ray.
  static std::vector<rtpack::Ray> random_rays(const rtpack::Bounds& b, size_t n, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0, 1), s(-1, 1);
    std::vector<rtpack::Ray> rays(n);
    for (rtpack::Ray& r : rays) {
      float len = 0;
      for (int k = 0; k < 3; ++k) {
        const float ext = b.hi[k] - b.lo[k];
        r.org[k] = b.lo[k] - 0.2f * ext + 1.4f * ext * u(rng);
        r.dir[k] = s(rng);
        len += r.dir[k] * r.dir[k];
      }
      for (float& d : r.dir) d /= std::sqrt(len);
      r.tnear = 0;
      r.tfar = INFINITY;
    }
    rays[n / 2].dir[1] = NAN;
    return rays;
  }
};
fs::path ReaderApi::dir, ReaderApi::gallery, ReaderApi::helmet;

TEST_F(ReaderApi, InfoMatchesTheHeaderAndTables) {
  const rtpack::Package pkg = rtpack::Package::open(gallery.string());
  const PackageReader reader(gallery.string());
  const fmt::Header& h = reader.header();
  const rtpack::Info& in = pkg.info();
  EXPECT_EQ(in.format_major, fmt::kVersionMajor);
  EXPECT_EQ(in.package_bytes, fs::file_size(gallery));
  EXPECT_EQ(in.unique_triangles, h.unique_triangles);
  EXPECT_EQ(in.instanced_triangles, h.instanced_triangles);
  EXPECT_EQ(in.instances, 12u);  // gallery.glb: 12 instances, 2 cameras
  EXPECT_EQ(in.cameras, 2u);
  EXPECT_EQ(in.bvh_width, h.bvh_width);
  EXPECT_EQ(std::memcmp(in.bounds.lo, h.bounds_lo, 12), 0);
  const auto tracer = load_package_in_core(reader);
  ASSERT_EQ(pkg.batching_points().size(), tracer->batching_points());
  EXPECT_EQ(in.has_dags, tracer->has_dags());
  uint64_t unique = 0, instanced = 0, instances = 0;
  float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (const rtpack::BatchingPoint& p : pkg.batching_points()) {
    unique += p.unique_triangles;
    instanced += p.instanced_triangles;
    instances += p.instances;
    EXPECT_GT(p.stored_bytes, 0u);
    EXPECT_GE(p.raw_bytes, p.stored_bytes / 2);
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], p.bounds.lo[k]);
      hi[k] = std::max(hi[k], p.bounds.hi[k]);
    }
  }
  // The header's bounds are the exact instanced bounds; the points' boxes (transformed mesh boxes) hold them.
  for (int k = 0; k < 3; ++k) {
    EXPECT_LE(lo[k], in.bounds.lo[k]) << k;
    EXPECT_GE(hi[k], in.bounds.hi[k]) << k;
  }
  EXPECT_EQ(instanced, h.instanced_triangles);
  EXPECT_EQ(instances, in.instances);
  EXPECT_LE(unique, h.unique_triangles);
  uint64_t mesh_tris = 0;
  for (const rtpack::Mesh& m : pkg.meshes()) mesh_tris += m.triangles;
  EXPECT_EQ(unique + mesh_tris, h.unique_triangles);
  EXPECT_STREQ(rtpack::version(), RTP_VERSION_FOR_TESTS);
}

TEST_F(ReaderApi, HitsEqualThePackageTracerRayByRayForEveryThreadCount) {
  for (const fs::path& p : {gallery, helmet}) {
    const rtpack::Package pkg = rtpack::Package::open(p.string());
    const PackageReader reader(p.string());
    const auto tracer = load_package_in_core(reader);
    std::vector<rtpack::Ray> rays = random_rays(pkg.info().bounds, 5000, 7);
    const std::vector<rtpack::Ray> cam = pkg.camera_rays(64, 48);
    rays.insert(rays.end(), cam.begin(), cam.end());
    std::vector<fmt::Hit> want(rays.size());
    PackageTraceOptions opt;
    opt.isa = detect_isa();
    tracer->closest(reinterpret_cast<const fmt::Ray*>(rays.data()), want.data(), rays.size(), opt);
    size_t want_hits = 0;
    for (const fmt::Hit& h : want) want_hits += h.instance != fmt::Hit::kNone;
    ASSERT_GT(want_hits, rays.size() / 50) << p;      // the gallery is sparse: 4 % of these rays hit
    EXPECT_EQ(want[2500].instance, fmt::Hit::kNone);  // the NaN ray
    std::vector<uint8_t> want_occ(rays.size());
    tracer->any(reinterpret_cast<const fmt::Ray*>(rays.data()), want_occ.data(), rays.size(), opt);
    for (const int threads : {1, 2, 0}) {
      for (const bool cull : {true, false}) {
        rtpack::TraceOptions o;
        o.threads = threads;
        o.cull = cull;
        std::vector<rtpack::Hit> hits(rays.size());
        EXPECT_EQ(pkg.trace(rays.data(), hits.data(), rays.size(), o), want_hits);
        for (size_t i = 0; i < rays.size(); ++i)
          ASSERT_EQ(std::memcmp(&hits[i], &want[i], sizeof(fmt::Hit)), 0) << p << " ray " << i << " threads " << threads;
        std::vector<uint8_t> occ(rays.size(), 7);
        size_t n_occ = pkg.occluded(rays.data(), occ.data(), rays.size(), o);
        EXPECT_EQ(occ, want_occ) << p << " threads " << threads;
        size_t expect_occ = 0;
        for (uint8_t v : want_occ) expect_occ += v;
        EXPECT_EQ(n_occ, expect_occ);
      }
    }
  }
}

TEST_F(ReaderApi, ShadingAndCameraRaysEqualTheInternals) {
  const rtpack::Package pkg = rtpack::Package::open(helmet.string());
  EXPECT_TRUE(pkg.info().has_normals);
  EXPECT_TRUE(pkg.info().has_uvs);
  const PackageReader reader(helmet.string());
  const CameraRays cr = camera_rays(reader, 40, 30);
  const std::vector<rtpack::Ray> rays = pkg.camera_rays(40, 30);
  ASSERT_EQ(rays.size(), cr.rays.size());
  ASSERT_EQ(std::memcmp(rays.data(), cr.rays.data(), rays.size() * sizeof(rtpack::Ray)), 0);
  std::vector<rtpack::Hit> hits(rays.size());
  ASSERT_GT(pkg.trace(rays.data(), hits.data(), rays.size()), 100u);
  std::vector<rtpack::Shading> sh(hits.size());
  pkg.shade(hits.data(), sh.data(), hits.size());
  const AttributeLookup lookup(reader);
  size_t nonzero = 0;
  for (size_t i = 0; i < hits.size(); ++i) {
    const fmt::Shading want = lookup.shade(reinterpret_cast<const fmt::Hit&>(hits[i]));
    ASSERT_EQ(std::memcmp(&sh[i], &want, sizeof want), 0) << i;
    nonzero += sh[i].normal[0] != 0 || sh[i].normal[1] != 0 || sh[i].normal[2] != 0;
  }
  EXPECT_GT(nonzero, 100u);
}

// TraceOptions::packet over camera rays in PixelOrder::kTiles: the hits of single rays bit for bit, for
// every SIMD ISA, packet size and thread count, with an invalid ray inside a packet, a short last run
// and scattered rays after the image; the stats show the packets were taken.
TEST_F(ReaderApi, PacketsOfTiledCameraRaysGiveTheSingleRayHits) {
  constexpr int kW = 130, kH = 66;  // cut edge tiles; 8580 rays, not a multiple of 16 or 256
  const std::vector<uint32_t> order = rtpack::tile_order(kW, kH);
  ASSERT_EQ(order.size(), size_t(kW) * kH);
  std::vector<uint8_t> seen(order.size(), 0);
  for (uint32_t px : order) {
    ASSERT_LT(px, order.size());
    ASSERT_EQ(seen[px]++, 0) << "pixel " << px << " twice";
  }
  std::vector<rtpack::Isa> isas;
  if (int(detect_isa()) >= int(Isa::kAvx2)) isas.push_back(rtpack::Isa::kAvx2);
  if (detect_isa() == Isa::kAvx512) isas.push_back(rtpack::Isa::kAvx512);
  if (isas.empty()) GTEST_SKIP() << "packets are SIMD only; this CPU has no AVX2";
  for (const fs::path& p : {gallery, helmet}) {
    const rtpack::Package pkg = rtpack::Package::open(p.string());
    const std::vector<rtpack::Ray> rows = pkg.camera_rays(kW, kH);
    std::vector<rtpack::Ray> rays = pkg.camera_rays(kW, kH, -1, rtpack::PixelOrder::kTiles);
    ASSERT_EQ(rays.size(), rows.size());
    for (size_t k = 0; k < rays.size(); ++k)
      ASSERT_EQ(std::memcmp(&rays[k], &rows[order[k]], sizeof(rtpack::Ray)), 0) << p << " ray " << k;
    rays[37].tnear = NAN;
    const std::vector<rtpack::Ray> scattered = random_rays(pkg.info().bounds, 1000, 11);
    rays.insert(rays.end(), scattered.begin(), scattered.end());

    rtpack::TraceOptions single;
    single.threads = 1;
    std::vector<rtpack::Hit> want(rays.size());
    rtpack::TraceStats ws;
    const size_t want_hits = pkg.trace(rays.data(), want.data(), rays.size(), single, &ws);
    ASSERT_GT(want_hits, 150u) << p;  // gallery: 2 % of its pixels show geometry
    EXPECT_EQ(ws.rays, rays.size());
    EXPECT_EQ(ws.invalid_rays, 2u);  // tnear NaN in the image, a NaN direction among the scattered rays
    EXPECT_EQ(ws.packets, 0u);
    ASSERT_GT(ws.batching_point_visits, 0u);
    for (const rtpack::Isa isa : isas)
      for (const int packet : {4, 8, 16})
        for (const int threads : {1, 2}) {
          rtpack::TraceOptions o;
          o.isa = isa, o.packet = packet, o.threads = threads;
          std::vector<rtpack::Hit> hits(rays.size());
          rtpack::TraceStats st;
          EXPECT_EQ(pkg.trace(rays.data(), hits.data(), rays.size(), o, &st), want_hits);
          for (size_t i = 0; i < rays.size(); ++i)
            ASSERT_EQ(std::memcmp(&hits[i], &want[i], sizeof(rtpack::Hit)), 0)
                << p << " ray " << i << " isa " << int(isa) << " packet " << packet << " threads " << threads;
          EXPECT_EQ(st.rays, ws.rays);
          EXPECT_EQ(st.invalid_rays, ws.invalid_rays);
          EXPECT_EQ(st.batching_point_visits, ws.batching_point_visits);
          EXPECT_EQ(st.culled_visits, ws.culled_visits);
          EXPECT_GT(st.packets, 0u) << p << " packet " << packet;
          // The image's rays make most of the traced (not culled) visits, and they go in packets.
          const uint64_t traced = ws.batching_point_visits - ws.culled_visits;
          EXPECT_GT(st.packet_ray_visits, traced / 2) << p << " packet " << packet;
          EXPECT_LE(st.packet_ray_visits, traced);
          EXPECT_GT(st.packet_node_tests, 0u);
          EXPECT_LE(st.packet_active_lanes, st.packet_node_tests * uint64_t(packet));
          EXPECT_GE(st.packet_active_lanes, st.packet_node_tests * 3);  // a packet node test has 3+ rays
        }
    // The scalar reference and occluded() trace single rays whatever TraceOptions::packet says.
    rtpack::TraceOptions scalar;
    scalar.isa = rtpack::Isa::kScalar, scalar.packet = 16;
    std::vector<rtpack::Hit> hits(rays.size());
    rtpack::TraceStats st;
    EXPECT_EQ(pkg.trace(rays.data(), hits.data(), rays.size(), scalar, &st), want_hits);
    EXPECT_EQ(st.packets, 0u);
    std::vector<uint8_t> want_occ(rays.size()), occ(rays.size());
    const size_t n_occ = pkg.occluded(rays.data(), want_occ.data(), rays.size(), single);
    rtpack::TraceOptions any16;
    any16.packet = 16;
    EXPECT_EQ(pkg.occluded(rays.data(), occ.data(), rays.size(), any16, &st), n_occ);
    EXPECT_EQ(occ, want_occ);
    EXPECT_EQ(st.packets, 0u);
    EXPECT_EQ(st.rays, rays.size());
  }
}

TEST_F(ReaderApi, ErrorsCarryTheToolsCodesAndNameTheFile) {
  auto code_of = [](auto&& f) {
    try {
      f();
    } catch (const rtpack::Error& e) {
      return std::make_pair(e.code(), std::string(e.what()));
    }
    return std::make_pair(0, std::string());
  };
  const std::string missing = (dir / "missing.rtp").string();
  auto [c1, m1] = code_of([&] { rtpack::Package::open(missing); });
  EXPECT_EQ(c1, 2);
  EXPECT_NE(m1.find(missing), std::string::npos) << m1;
  // Truncated: the header's file size disagrees.
  const std::string bytes = slurp_file(gallery);
  const fs::path cut = dir / "cut.rtp";
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  auto [c2, m2] = code_of([&] { rtpack::Package::open(cut.string()); });
  EXPECT_EQ(c2, 3);
  EXPECT_NE(m2.find(cut.string()), std::string::npos) << m2;
  // A flipped byte inside a chunk: its CRC names it.
  std::string flipped = bytes;
  flipped[flipped.size() / 2] = char(flipped[flipped.size() / 2] ^ 0x40);
  const fs::path fl = dir / "flipped.rtp";
  std::ofstream(fl, std::ios::binary) << flipped;
  auto [c3, m3] = code_of([&] { rtpack::Package::open(fl.string()); });
  EXPECT_EQ(c3, 3) << m3;
  EXPECT_NE(m3.find("chunk"), std::string::npos) << m3;

  const rtpack::Package pkg = rtpack::Package::open(gallery.string());
  auto [c4, m4] = code_of([&] { pkg.camera_rays(0, 10); });
  EXPECT_EQ(c4, 1);
  auto [c5, m5] = code_of([&] { pkg.camera_rays(8, 8, 5); });
  EXPECT_EQ(c5, 1);
  EXPECT_NE(m5.find("camera 5: the package has 2 cameras"), std::string::npos) << m5;
  if (detect_isa() != Isa::kAvx512) {
    rtpack::TraceOptions o;
    o.isa = rtpack::Isa::kAvx512;
    rtpack::Ray r{{0, 0, 0}, 0, {0, 0, 1}, 1};
    rtpack::Hit h{};
    auto [c6, m6] = code_of([&] { pkg.trace(&r, &h, 1, o); });
    EXPECT_EQ(c6, 1);
    EXPECT_NE(m6.find("this CPU runs up to"), std::string::npos) << m6;
  }
  for (const int packet : {-4, 1, 5, 32}) {
    rtpack::TraceOptions o;
    o.packet = packet;
    rtpack::Ray r{{0, 0, 0}, 0, {0, 0, 1}, 1};
    rtpack::Hit h{};
    auto [c7, m7] = code_of([&] { pkg.trace(&r, &h, 1, o); });
    EXPECT_EQ(c7, 1) << packet;
    EXPECT_NE(m7.find("TraceOptions::packet = " + std::to_string(packet) + ": rays per packet are 4, 8 or 16"), std::string::npos)
        << m7;
  }
  auto [c8, m8] = code_of([&] { rtpack::tile_order(4, -1); });
  EXPECT_EQ(c8, 1);
  EXPECT_NE(m8.find("tile_order: 4x-1 is not a size"), std::string::npos) << m8;
  auto [c9, m9] = code_of([&] { pkg.camera_rays(8, 8, -1, rtpack::PixelOrder(7)); });
  EXPECT_EQ(c9, 1);
  EXPECT_NE(m9.find("PixelOrder 7 is not an order"), std::string::npos) << m9;
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
