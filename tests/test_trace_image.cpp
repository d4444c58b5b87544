// rtpack-trace --image: the camera's primary rays traced through a package and shaded, pixel by pixel
// against the hit file of the same rays; cameras, sizes and usage errors.
#include <gtest/gtest.h>
#include <stb_image.h>

#include <cstring>
#include <set>

#include "formats/ray_file.h"
#include "gltf_builder.h"
#include "image/image.h"
#include "trace/trace.h"
#include "tool_run.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

template <class T>
std::vector<T> read_records(const fs::path& p) {
  const std::string b = slurp_file(p);
  std::vector<T> v(b.size() / sizeof(T));
  std::memcpy(v.data(), b.data(), v.size() * sizeof(T));
  return v;
}

struct Png {
  int w = 0, h = 0;
  std::vector<uint8_t> rgb;
};

Png load_png(const fs::path& p) {
  const std::string b = slurp_file(p);
  Png png;
  int c = 0;
  uint8_t* px = stbi_load_from_memory(reinterpret_cast<const uint8_t*>(b.data()), int(b.size()), &png.w, &png.h, &c, 3);
  if (!px) return png;
  png.rgb.assign(px, px + size_t(png.w) * png.h * 3);
  stbi_image_free(px);
  return png;
}

class TraceImage : public ::testing::Test {
 protected:
  static fs::path dir;
  static fs::path gallery;  // gallery.glb converted: 12 instances, 2 glTF cameras
  static void SetUpTestSuite() {
    dir = temp_dir("TraceImage");
    gallery = dir / "gallery.rtp";
    const ToolResult r = run_tool("rtpack-convert",
                                  {(source_dir() / "samples/generated/gallery.glb").string(), "-q", "-o", gallery.string()}, dir);
    ASSERT_EQ(r.code, 0) << r.err;
  }
  static void TearDownTestSuite() { fs::remove_all(dir); }
  ToolResult trace(const std::vector<std::string>& args) { return run_tool("rtpack-trace", args, dir); }
};
fs::path TraceImage::dir, TraceImage::gallery;

TEST_F(TraceImage, InstanceColoursMatchTheHitsRayByRay) {
  const fs::path png = dir / "inst.png", hits = dir / "inst.hits", rays = dir / "cam.rays", hits2 = dir / "cam.hits";
  const ToolResult r =
      trace({gallery.string(), "--image", png.string(), "--size", "96x64", "--shade", "instance", "--hits", hits.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("image: " + png.string() + ", 96x64, camera 0"), std::string::npos) << r.err;
  // The image's rays are the camera rays --make-camera-rays writes: the same hits, byte for byte.
  ASSERT_EQ(trace({gallery.string(), "--make-camera-rays", "96x64", "--rays", rays.string(), "--hits", hits2.string()}).code, 0);
  EXPECT_EQ(slurp_file(hits), slurp_file(hits2));
  const auto h = read_records<fmt::Hit>(hits);
  const Png img = load_png(png);
  ASSERT_EQ(img.w, 96);
  ASSERT_EQ(img.h, 64);
  ASSERT_EQ(h.size(), 96u * 64u);
  size_t hit_pixels = 0;
  std::set<uint32_t> instances;
  for (size_t i = 0; i < h.size(); ++i) {
    const uint8_t* p = &img.rgb[i * 3];
    if (h[i].instance == fmt::Hit::kNone) {
      ASSERT_TRUE(p[0] == image::kBackground[0] && p[1] == image::kBackground[1] && p[2] == image::kBackground[2])
          << "pixel " << i;
      continue;
    }
    ++hit_pixels;
    instances.insert(h[i].instance);
    // The instance's colour times one factor k in [0.3, 1] in every channel.
    const auto c = image::instance_color(h[i].instance);
    const double k = double(p[0] + p[1] + p[2]) / double(c[0] + c[1] + c[2]);
    ASSERT_GE(k, 0.29) << "pixel " << i;
    ASSERT_LE(k, 1.01) << "pixel " << i;
    for (int ch = 0; ch < 3; ++ch) ASSERT_NEAR(p[ch], c[size_t(ch)] * k, 2.0) << "pixel " << i << " instance " << h[i].instance;
  }
  EXPECT_GT(hit_pixels, h.size() / 100);  // the gallery is sparse: about 2.6 % of camera 0's view
  EXPECT_GE(instances.size(), 3u);
}

TEST_F(TraceImage, DepthFollowsTheHitDistance) {
  const fs::path png = dir / "depth.png", hits = dir / "depth.hits";
  ASSERT_EQ(
      trace({gallery.string(), "--image", png.string(), "--size", "48x32", "--shade", "depth", "--hits", hits.string()}).code, 0);
  const auto h = read_records<fmt::Hit>(hits);
  const Png img = load_png(png);
  ASSERT_EQ(h.size(), 48u * 32u);  // one hit record per pixel
  ASSERT_EQ(img.rgb.size(), h.size() * 3);
  size_t hit_pixels = 0, distinct = 0;
  for (size_t i = 0; i < h.size(); ++i) hit_pixels += h[i].instance != fmt::Hit::kNone;
  for (size_t i = 0; i < h.size(); ++i)
    for (size_t j = 0; j < h.size(); ++j) {
      if (h[i].instance != fmt::Hit::kNone && h[j].instance != fmt::Hit::kNone && img.rgb[i * 3] != img.rgb[j * 3]) ++distinct;
      if (h[i].instance != fmt::Hit::kNone && h[j].instance != fmt::Hit::kNone && h[i].t < h[j].t) {
        ASSERT_GE(img.rgb[i * 3], img.rgb[j * 3]) << "pixel " << i << " (t " << h[i].t << ") vs " << j << " (t " << h[j].t << ")";
      }
    }
  EXPECT_GT(hit_pixels, 10u) << "the camera must see the gallery";
  EXPECT_GT(distinct, 0u) << "hit pixels of more than one shade: depth is drawn";
}

TEST_F(TraceImage, CamerasAndTheAutomaticOne) {
  const fs::path h0 = dir / "c0.hits", h1 = dir / "c1.hits";
  ASSERT_EQ(trace({gallery.string(), "--image", (dir / "c0.png").string(), "--size", "32x24", "--hits", h0.string()}).code, 0);
  const ToolResult one =
      trace({gallery.string(), "--image", (dir / "c1.png").string(), "--size", "32x24", "--camera", "1", "--hits", h1.string()});
  ASSERT_EQ(one.code, 0) << one.err;
  EXPECT_NE(one.err.find("camera 1"), std::string::npos) << one.err;
  EXPECT_NE(slurp_file(h0), slurp_file(h1));
  const ToolResult none = trace({gallery.string(), "--image", (dir / "c2.png").string(), "--camera", "2"});
  EXPECT_EQ(none.code, 1);
  EXPECT_NE(none.err.find("camera 2: the package has 2 cameras (0 to 1)"), std::string::npos) << none.err;
  EXPECT_FALSE(fs::exists(dir / "c2.png"));
  // Suzanne has no camera: an automatic one frames the bounds, and the model fills part of the image.
  const fs::path suz = dir / "suzanne.rtp";
  ASSERT_EQ(run_tool("rtpack-convert",
                     {(source_dir() / "samples/khronos/Suzanne/glTF/Suzanne.gltf").string(), "-q", "-o", suz.string()}, dir)
                .code,
            0);
  const ToolResult a =
      trace({suz.string(), "--image", (dir / "s.png").string(), "--size", "40x40", "--hits", (dir / "s.hits").string()});
  ASSERT_EQ(a.code, 0) << a.err;
  EXPECT_NE(a.err.find("automatic camera"), std::string::npos) << a.err;
  size_t hit = 0;
  for (const auto& x : read_records<fmt::Hit>(dir / "s.hits")) hit += x.instance != fmt::Hit::kNone;
  EXPECT_GT(hit, 40u * 40u / 20);
  EXPECT_LT(hit, 40u * 40u);
}

// Issue 11: an image's rays go in packets of 16 along Hilbert-ordered 4x4 tiles by default; packets of 4
// or 8, single rays (--packet 0) and the scalar ISA give the same picture and the same hits byte for byte.
TEST_F(TraceImage, PacketsInHilbertTilesGiveTheSingleRayImage) {
  const fs::path png0 = dir / "p0.png", hits0 = dir / "p0.hits";
  const ToolResult single = trace({gallery.string(), "--image", png0.string(), "--size", "70x46", "--camera", "1", "--packet",
                                   "0", "--hits", hits0.string(), "--json"});
  ASSERT_EQ(single.code, 0) << single.err;
  EXPECT_EQ(nlohmann::json::parse(single.out)["packets"]["packets"].get<uint64_t>(), 0u);
  size_t hit = 0;
  for (const auto& x : read_records<fmt::Hit>(hits0)) hit += x.instance != fmt::Hit::kNone;
  ASSERT_GT(hit, 70u * 46u / 100) << "too few hits to compare";
  for (const char* size : {"", "4", "8", "16"}) {
    const std::string tag = std::string("p") + (*size ? size : "default");
    const fs::path png = dir / (tag + ".png"), hits = dir / (tag + ".hits");
    std::vector<std::string> args = {gallery.string(), "--image", png.string(), "--size",      "70x46",
                                     "--camera",       "1",       "--hits",     hits.string(), "--json"};
    if (*size) args.insert(args.end(), {"--packet", size});
    const ToolResult r = trace(args);
    ASSERT_EQ(r.code, 0) << tag << ": " << r.err;
    EXPECT_EQ(slurp_file(hits), slurp_file(hits0)) << tag;
    EXPECT_EQ(slurp_file(png), slurp_file(png0)) << tag;
    const auto j = nlohmann::json::parse(r.out)["packets"];
    EXPECT_EQ(j["size"].get<int>(), *size ? std::atoi(size) : 16) << tag;
    EXPECT_EQ(j["order"].get<std::string>(), "hilbert 4x4 tiles") << tag;
    if (rtp::detect_isa() == rtp::Isa::kScalar) continue;  // no SIMD: single rays, no packets
    EXPECT_GT(j["packets"].get<uint64_t>(), 0u) << tag;
    EXPECT_GT(j["packet_visit_share"].get<double>(), 0.5) << tag;
    const double u = j["simd_utilization"].get<double>();
    EXPECT_GT(u, 0.0) << tag;
    EXPECT_LE(u, 1.0) << tag;
  }
  // The human summary says how the rays went.
  const ToolResult text = trace({gallery.string(), "--image", (dir / "pt.png").string(), "--size", "32x32"});
  ASSERT_EQ(text.code, 0) << text.err;
  if (rtp::detect_isa() != rtp::Isa::kScalar) {
    EXPECT_NE(text.err.find("packets of 16 (Hilbert-ordered 4x4 tiles)"), std::string::npos) << text.err;
    EXPECT_NE(text.err.find("SIMD utilization"), std::string::npos) << text.err;
  }
  // The scalar reference traces single rays and still gives the same picture.
  const ToolResult scalar = trace({gallery.string(), "--image", (dir / "ps.png").string(), "--size", "70x46", "--camera", "1",
                                   "--isa", "scalar", "--hits", (dir / "ps.hits").string()});
  ASSERT_EQ(scalar.code, 0) << scalar.err;
  EXPECT_EQ(slurp_file(dir / "ps.hits"), slurp_file(hits0));
  EXPECT_EQ(scalar.err.find("packets of"), std::string::npos) << scalar.err;
}

TEST_F(TraceImage, UsageErrorsWriteNothing) {
  const std::string png = (dir / "u.png").string(), g = gallery.string();
  const struct {
    std::vector<std::string> args;
    const char* says;
  } cases[] = {
      {{g, "--image", png, "--rays", (dir / "x.rays").string()}, "leave out --rays"},
      {{g, "--image", png, "--any"}, "cannot be used with --any"},
      {{g, "--rays", (dir / "x.rays").string(), "--hits", (dir / "h").string(), "--packet", "8", "--any"},
       "--packet traces closest hits"},
      {{g, "--rays", (dir / "x.rays").string(), "--hits", (dir / "h").string(), "--packet", "4", "--multi-hit", "3"},
       "--packet traces closest hits"},
      {{g, "--image", png, "--packet", "16", "--memory-budget", "64M"}, "traces single rays"},
      {{g, "--image", png, "--packet", "5"}, "--packet"},
      {{g, "--image", png, "--size", "0x5"}, "--size 0x5: expected WxH"},
      {{g, "--image", png, "--size", "64x"}, "expected WxH"},
      {{g, "--image", png, "--shade", "phong"}, "--shade"},
      {{g, "--hits", (dir / "h").string()}, "--rays and --hits are required"},
      {{g, "--rays", (dir / "x.rays").string(), "--hits", (dir / "h").string(), "--shade", "depth"}, "belong to --image"},
      {{g, "--image", (dir / "no-such-dir" / "u.png").string()}, "no directory"},
      // 2^32 + 1 wrapped to 1 when the size was read with %d.
      {{g, "--image", png, "--size", "4294967297x1"}, "expected WxH"},
      {{g, "--image", png, "--size", "-64x64"}, "expected WxH"},
      {{g, "--image", png, "--size", "16385x16385"}, "expected WxH"},
      {{g, "--make-camera-rays", "8x8", "--rays", (dir / "s").string(), "--hits", (dir / "h").string(), "--shading",
        (dir / "s").string()},
       "two outputs name the same file"},
  };
  for (const auto& c : cases) {
    const ToolResult r = trace(c.args);
    EXPECT_NE(r.code, 0) << c.says;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << c.says << ": " << r.err;
    // Nothing at any output path the cases name.
    for (const char* f : {"u.png", "h", "s", "x.rays", "no-such-dir"}) EXPECT_FALSE(fs::exists(dir / f)) << c.says << ": " << f;
  }
}

TEST_F(TraceImage, UsageErrorsUnderJsonAreEnvelopes) {
  const ToolResult r = trace({gallery.string(), "--image", (dir / "u.png").string(), "--size", "0x5", "--json"});
  EXPECT_EQ(r.code, 1);  // ExitCode::kUsage
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["error"]["code"].get<int>(), 1);
  EXPECT_NE(j["error"]["message"].get<std::string>().find("--size 0x5"), std::string::npos) << r.out;
  EXPECT_EQ(j["schema_version"].get<int>(), 3);
}

TEST_F(TraceImage, SizeParsing) {
  const ToolResult r = trace({gallery.string(), "--image", (dir / "w.png").string(), "--size", "0007x05", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["image"]["width"].get<int>(), 7);
  EXPECT_EQ(j["image"]["height"].get<int>(), 5);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

// glTF 2.0 §5.13: ymag MUST NOT be zero and SHOULD NOT be negative. The importer accepts a negative one, so
// the image does too (by its size); zero is refused naming the camera.
TEST(TraceImageCamera, NegativeYmagIsItsSizeAndZeroIsRefused) {
  const fs::path dir = temp_dir("TraceImageCamera");
  std::vector<std::string> hits;
  for (const double ymag : {2.0, -2.0, 0.0}) {
    GltfBuilder b = one_triangle();
    b.j["cameras"] = nlohmann::json::array(
        {{{"type", "orthographic"}, {"orthographic", {{"xmag", 2}, {"ymag", ymag}, {"znear", 0.01}, {"zfar", 100}}}}});
    const int cam = b.add_node({{"camera", 0}, {"translation", {0.25, 0.25, 5}}});
    b.set_scene({0, cam});
    const std::string tag = ymag > 0 ? "pos" : ymag < 0 ? "neg" : "zero";
    const fs::path rtp = dir / (tag + ".rtp"), h = dir / (tag + ".hits");
    const ToolResult c = run_tool("rtpack-convert", {b.write_gltf(dir / (tag + ".gltf")), "-q", "-o", rtp.string()}, dir);
    ASSERT_EQ(c.code, 0) << c.err;
    const ToolResult r = run_tool(
        "rtpack-trace", {rtp.string(), "--image", (dir / (tag + ".png")).string(), "--size", "16x16", "--hits", h.string()}, dir);
    if (ymag == 0) {
      EXPECT_EQ(r.code, 3);
      EXPECT_NE(r.err.find("/cameras/0/ymag"), std::string::npos) << r.err;
      EXPECT_FALSE(fs::exists(h));
    } else {
      ASSERT_EQ(r.code, 0) << r.err;
      hits.push_back(slurp_file(h));
    }
  }
  ASSERT_EQ(hits.size(), 2u);
  EXPECT_EQ(hits[0], hits[1]);
  const auto* hh = reinterpret_cast<const fmt::Hit*>(hits[0].data());
  size_t n_hit = 0;
  for (size_t i = 0; i < hits[0].size() / sizeof(fmt::Hit); ++i) n_hit += hh[i].instance != fmt::Hit::kNone;
  EXPECT_GT(n_hit, 0u);  // the triangle is in view
  fs::remove_all(dir);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
