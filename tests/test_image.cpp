// lib/image: shading of primary-ray hits (normal, depth, instance) and PNG encoding, checked pixel by
// pixel against analytic surfaces and a PNG decoder (stb_image from libstb-dev).
#include <gtest/gtest.h>
#include <stb_image.h>

#include <cmath>
#include <limits>
#include <random>
#include <set>

#include "core/error.h"
#include "image/image.h"

namespace rtp::image {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

constexpr float kInf = std::numeric_limits<float>::infinity();

uint8_t byte_of(double v) { return uint8_t(std::lround(std::clamp(v, 0.0, 1.0) * 255.0)); }

// Rays straight down -z from a grid over [-1, 1]^2 at z = 10, hitting the plane z = a x + b y of
// `instance` (or missing where `miss` says).
struct Grid {
  int w, h;
  std::vector<fmt::Ray> rays;
  std::vector<fmt::Hit> hits;
};

Grid plane(int w, int h, double a, double b, uint32_t instance = 7) {
  Grid g{w, h, {}, {}};
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double px = 2.0 * (x + 0.5) / w - 1, py = 1 - 2.0 * (y + 0.5) / h;
      g.rays.push_back({{float(px), float(py), 10.f}, 0.f, {0.f, 0.f, -1.f}, kInf});
      g.hits.push_back({float(10 - (a * px + b * py)), instance, uint32_t(x), 0.25f, 0.25f});
    }
  return g;
}

TEST(Image, PngRoundTripsThroughADecoder) {
  Rgb8 img{13, 7, {}};
  std::mt19937 rng(5);
  for (int i = 0; i < 13 * 7 * 3; ++i) img.rgb.push_back(uint8_t(rng()));
  const std::vector<uint8_t> png = encode_png(img);
  ASSERT_GT(png.size(), 8u);
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(png.data()) + 1, 3), "PNG");
  int w = 0, h = 0, c = 0;
  uint8_t* px = stbi_load_from_memory(png.data(), int(png.size()), &w, &h, &c, 3);
  ASSERT_NE(px, nullptr) << stbi_failure_reason();
  EXPECT_EQ(w, 13);
  EXPECT_EQ(h, 7);
  EXPECT_EQ(std::vector<uint8_t>(px, px + 13 * 7 * 3), img.rgb);
  stbi_image_free(px);
  EXPECT_THROW(encode_png(Rgb8{4, 4, std::vector<uint8_t>(10)}), Error);
}

TEST(Image, NormalsOfATiltedPlaneFromNeighbouringHits) {
  // z = 0.3 x - 0.2 y: normal (-0.3, 0.2, 1) / |.|, facing the rays (which go down -z).
  const Grid g = plane(40, 30, 0.3, -0.2);
  const Rgb8 img = shade(g.rays.data(), g.hits.data(), g.w, g.h, Shade::kNormal);
  const double l = std::sqrt(0.09 + 0.04 + 1);
  const uint8_t want[3] = {byte_of(0.5 * (-0.3 / l + 1)), byte_of(0.5 * (0.2 / l + 1)), byte_of(0.5 * (1 / l + 1))};
  for (size_t i = 0; i < g.rays.size(); ++i)
    for (int c = 0; c < 3; ++c) ASSERT_NEAR(img.rgb[i * 3 + c], want[c], 1) << "pixel " << i << " channel " << c;
  // A plane seen from below faces down: the normal is flipped toward the ray.
  Grid up = plane(8, 8, 0.0, 0.0);
  for (auto& r : up.rays) r.org[2] = -10, r.dir[2] = 1;
  for (auto& h : up.hits) h.t = 10;
  const Rgb8 under = shade(up.rays.data(), up.hits.data(), 8, 8, Shade::kNormal);
  for (size_t i = 0; i < 64; ++i) ASSERT_EQ(under.rgb[i * 3 + 2], 0) << i;
}

TEST(Image, StoredNormalsWinAndZeroNormalsFallBack) {
  const Grid g = plane(6, 5, 0.0, 0.0);
  std::vector<fmt::Shading> sh(g.hits.size(), fmt::Shading{{0, 2, 0}, {0, 0}});
  sh[7] = fmt::Shading{{0, 0, 0}, {0, 0}};  // no stored normal: estimated (the plane faces +z)
  const Rgb8 img = shade(g.rays.data(), g.hits.data(), 6, 5, Shade::kNormal, sh.data());
  for (size_t i = 0; i < g.hits.size(); ++i) {
    const std::array<uint8_t, 3> want = i == 7 ? std::array<uint8_t, 3>{128, 128, 255} : std::array<uint8_t, 3>{128, 255, 128};
    for (int c = 0; c < 3; ++c) EXPECT_EQ(img.rgb[i * 3 + c], want[size_t(c)]) << "pixel " << i;
  }
}

TEST(Image, MissesAreBackgroundAndDepthIsMonotone) {
  Grid g = plane(16, 16, 0.0, 0.0);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> t(1.f, 50.f);
  for (size_t i = 0; i < g.hits.size(); ++i) {
    if (i % 5 == 0)
      g.hits[i] = {kInf, fmt::Hit::kNone, fmt::Hit::kNone, 0, 0};
    else
      g.hits[i].t = t(rng);
  }
  const Rgb8 img = shade(g.rays.data(), g.hits.data(), 16, 16, Shade::kDepth);
  float tmin = kInf, tmax = 0;
  for (const auto& h : g.hits)
    if (h.instance != fmt::Hit::kNone) tmin = std::min(tmin, h.t), tmax = std::max(tmax, h.t);
  for (size_t i = 0; i < g.hits.size(); ++i) {
    const uint8_t* p = &img.rgb[i * 3];
    if (i % 5 == 0) {
      EXPECT_TRUE(p[0] == kBackground[0] && p[1] == kBackground[1] && p[2] == kBackground[2]) << i;
      continue;
    }
    EXPECT_TRUE(p[0] == p[1] && p[1] == p[2]) << i;
    if (g.hits[i].t == tmin) {
      EXPECT_EQ(p[0], 255);
    }
    if (g.hits[i].t == tmax) {
      EXPECT_EQ(p[0], byte_of(0.2));
    }
    for (size_t j = 0; j < g.hits.size(); ++j) {
      if (j % 5 != 0 && g.hits[j].t > g.hits[i].t) {
        ASSERT_GE(p[0], img.rgb[j * 3]) << i << " vs " << j;
      }
    }
  }
}

TEST(Image, InstanceColoursAreDistinctAndShadedByAngle) {
  std::set<std::array<uint8_t, 3>> seen;
  for (uint32_t i = 0; i < 64; ++i) {
    const auto c = instance_color(i);
    EXPECT_NE(c, kBackground);
    EXPECT_GE(*std::max_element(c.begin(), c.end()), 200) << i;  // bright, never near the background
    seen.insert(c);
  }
  EXPECT_GE(seen.size(), 60u);
  // Facing the rays: full colour; tilted 60 degrees (|cos| = 0.5): 0.3 + 0.7 * 0.5 of it.
  for (const double slope : {0.0, std::sqrt(3.0)}) {
    const Grid g = plane(10, 10, slope, 0.0, 42);
    const Rgb8 img = shade(g.rays.data(), g.hits.data(), 10, 10, Shade::kInstance);
    const double k = slope == 0 ? 1.0 : 0.3 + 0.7 * 0.5;
    const auto c = instance_color(42);
    for (size_t i = 0; i < 100; ++i)
      for (int ch = 0; ch < 3; ++ch) ASSERT_NEAR(img.rgb[i * 3 + ch], c[size_t(ch)] * k, 1.0) << i;
  }
}

TEST(Image, ParseShade) {
  Shade s{};
  EXPECT_TRUE(parse_shade("depth", &s));
  EXPECT_EQ(s, Shade::kDepth);
  EXPECT_TRUE(parse_shade("instance", &s));
  EXPECT_EQ(s, Shade::kInstance);
  EXPECT_TRUE(parse_shade("normal", &s));
  EXPECT_EQ(s, Shade::kNormal);
  EXPECT_FALSE(parse_shade("Normal", &s));
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::image
