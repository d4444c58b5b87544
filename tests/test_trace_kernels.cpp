// lib/trace kernels one node / one block at a time: every SIMD path equals the scalar reference bit for
// bit on random and adversarial input; the slab test's NaN/zero-direction cases (TESTING.md case 3);
// interval ends (case 5); invalid rays (case 4).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "test_trace_util.h"
#include "trace/kernels/kernels.h"

namespace rtp {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using trace_test::kInf;
using trace_test::Rng;

uint32_t bits_of(float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

// The SIMD ISAs to compare with the scalar reference (those this CPU runs).
using trace_test::simd_isas;

float special_component(Rng& rng, float x) {
  switch (rng.below(24)) {
    case 0: return 0.0f;
    case 1: return -0.0f;
    case 2: return 1e-40f;  // denormal
    case 3: return -1e-40f;
    case 4: return 1e-9f;
    case 5: return -1e-9f;
    default: return x;
  }
}

template <int B>
fmt::LeafBlock<B> random_block(Rng& rng) {
  fmt::LeafBlock<B> blk;
  const int kind = int(rng.below(5));
  const int used = kind == 4 ? 1 + int(rng.below(B)) : B;  // kind 4: padded like a short block
  float base[3] = {rng.range(-1, 1), rng.range(-1, 1), rng.range(-1, 1)};
  for (int lane = 0; lane < B; ++lane) {
    const int src = lane < used ? lane : used - 1;
    Rng lr(uint64_t(src) * 7919 + rng.next() % 3);  // kind 4 copies come out equal below
    for (int a = 0; a < 3; ++a) {
      float v[3] = {rng.range(-1, 1), rng.range(-1, 1), rng.range(-1, 1)};
      if (kind == 1) v[0] = base[a];                                       // fan: every lane shares vertex 0
      if (kind == 2 && (lane % 3) == 0) v[2] = v[1];                       // degenerate: repeated vertex
      if (kind == 2 && (lane % 3) == 1) v[2] = 0.5f * v[0] + 0.5f * v[1];  // collinear (about)
      if (kind == 3 && rng.below(8) == 0) v[rng.below(3)] = rng.below(2) ? 1e30f : NAN;
      blk.v0[a][lane] = v[0];
      blk.v1[a][lane] = v[1];
      blk.v2[a][lane] = v[2];
    }
    blk.prim[lane] = uint32_t(src);
    if (lane >= used)
      for (int a = 0; a < 3; ++a) {
        blk.v0[a][lane] = blk.v0[a][used - 1];
        blk.v1[a][lane] = blk.v1[a][used - 1];
        blk.v2[a][lane] = blk.v2[a][used - 1];
      }
  }
  return blk;
}

template <int B>
fmt::Ray ray_at_block(Rng& rng, const fmt::LeafBlock<B>& blk) {
  fmt::Ray r;
  for (int a = 0; a < 3; ++a) r.org[a] = rng.range(-2, 2);
  const int lane = int(rng.below(B));
  float w[3] = {0, 0, 0};
  switch (rng.below(4)) {
    case 0: w[0] = 1, w[1] = 0, w[2] = 0; break;        // at a vertex
    case 1: w[0] = 0.5f, w[1] = 0.5f, w[2] = 0; break;  // at an edge midpoint
    case 2: {
      const float u = float(rng.uniform()), v = float(rng.uniform()) * (1 - u);
      w[0] = 1 - u - v, w[1] = u, w[2] = v;
      break;
    }
    default: w[0] = -1; break;  // random direction
  }
  for (int a = 0; a < 3; ++a) {
    const float target =
        w[0] < 0 ? r.org[a] + rng.range(-1, 1) : w[0] * blk.v0[a][lane] + w[1] * blk.v1[a][lane] + w[2] * blk.v2[a][lane];
    r.dir[a] = special_component(rng, (target - r.org[a]) * rng.range(0.25f, 4.0f));
  }
  r.tnear = rng.below(3) == 0 ? rng.range(0, 0.5f) : 0.0f;
  r.tfar = rng.below(3) == 0 ? rng.range(0.3f, 2.0f) : kInf;
  return r;
}

template <int B>
void check_blocks(uint64_t seed) {
  Rng rng(seed);
  int hits = 0;
  for (int iter = 0; iter < 4000; ++iter) {
    const fmt::LeafBlock<B> blk = random_block<B>(rng);
    for (int k = 0; k < 8; ++k) {
      const fmt::Ray ray = ray_at_block<B>(rng, blk);
      BlockHits<B> ref;
      intersect_block<B>(Isa::kScalar, blk, ray, &ref);
      hits += ref.mask != 0;
      for (Isa isa : simd_isas()) {
        BlockHits<B> got;
        intersect_block<B>(isa, blk, ray, &got);
        ASSERT_EQ(got.mask, ref.mask) << isa_name(isa) << " B=" << B << " iter " << iter;
        for (int i = 0; i < B; ++i) {
          if (!((ref.mask >> i) & 1)) continue;
          ASSERT_EQ(bits_of(got.t[i]), bits_of(ref.t[i])) << isa_name(isa) << " lane " << i;
          ASSERT_EQ(bits_of(got.u[i]), bits_of(ref.u[i])) << isa_name(isa) << " lane " << i;
          ASSERT_EQ(bits_of(got.v[i]), bits_of(ref.v[i])) << isa_name(isa) << " lane " << i;
        }
      }
    }
  }
  EXPECT_GT(hits, 4000 * 8 / 20);  // many rays do hit: the comparison has teeth
}

// Every SIMD test here runs the ISAs this CPU supports and leaves the others out without a word: on a
// CPU without AVX-512 (this project's 2-core CI machine, an AMD EPYC) the AVX-512 kernels are compiled
// but never run. This test says so as a skip that ctest lists, and fails instead when RTP_REQUIRE_ISA
// (e.g. "avx512") names an ISA this CPU lacks, for a machine that is meant to cover it.
TEST(TraceKernels, EveryCompiledSimdIsaRunsOnThisCpu) {
  std::string missing;
  for (Isa isa : {Isa::kAvx2, Isa::kAvx512})
    if (static_cast<int>(isa) > static_cast<int>(detect_isa()))
      missing += std::string(missing.empty() ? "" : ", ") + isa_name(isa);
  const char* required = std::getenv("RTP_REQUIRE_ISA");
  if (required && *required) {
    const std::string want(required);
    EXPECT_EQ(missing.find(want), std::string::npos)
        << "RTP_REQUIRE_ISA=" << want << ", but this CPU runs " << isa_name(detect_isa()) << " at best";
  }
  if (!missing.empty())
    GTEST_SKIP() << "compiled but not run on this CPU (best: " << isa_name(detect_isa()) << "): " << missing
                 << " kernels; the SIMD tests here cover " << simd_isas().size() << " of 2 SIMD ISAs";
  EXPECT_EQ(simd_isas().size(), 2u);
}

TEST(TraceKernels, BlockSimdEqualsScalarB4) { check_blocks<4>(1); }
TEST(TraceKernels, BlockSimdEqualsScalarB8) { check_blocks<8>(2); }
TEST(TraceKernels, BlockSimdEqualsScalarB16) { check_blocks<16>(3); }

template <int W>
fmt::WideNode<W> random_node(Rng& rng) {
  fmt::WideNode<W> n;
  const int filled = 1 + int(rng.below(W));
  for (int lane = 0; lane < W; ++lane)
    for (int a = 0; a < 3; ++a) {
      float x = rng.range(-1, 1), y = rng.range(-1, 1);
      if (rng.below(6) == 0) y = x;  // flat box
      n.lo[a][lane] = lane < filled ? std::min(x, y) : kInf;
      n.hi[a][lane] = lane < filled ? std::max(x, y) : -kInf;
    }
  for (int lane = 0; lane < W; ++lane) n.child[lane] = lane < filled ? uint32_t(lane) : fmt::ChildRef::kEmpty;
  for (int o = 0; o < 8; ++o)
    for (int i = 0; i < W; ++i) n.order[o][i] = uint8_t(i);
  return n;
}

template <int W>
void check_nodes(uint64_t seed) {
  Rng rng(seed);
  int hits = 0;
  for (int iter = 0; iter < 20000; ++iter) {
    const fmt::WideNode<W> node = random_node<W>(rng);
    fmt::Ray ray;
    const int lane = int(rng.below(W));
    for (int a = 0; a < 3; ++a) {
      ray.org[a] = rng.range(-2, 2);
      ray.dir[a] = special_component(rng, rng.range(-1, 1));
    }
    if (rng.below(2) && std::isfinite(node.lo[0][lane]))  // aimed at a point of some box
      for (int a = 0; a < 3; ++a)
        ray.dir[a] =
            special_component(rng, node.lo[a][lane] + rng.range(0, 1) * (node.hi[a][lane] - node.lo[a][lane]) - ray.org[a]);
    if (rng.below(2) && std::isfinite(node.lo[0][lane])) {  // origin on a face of some box
      const int a = int(rng.below(3));
      ray.org[a] = rng.below(2) ? node.lo[a][lane] : node.hi[a][lane];
      ray.dir[a] = rng.below(2) ? 0.0f : -0.0f;
    }
    ray.tnear = rng.below(3) == 0 ? rng.range(-1, 1) : 0.0f;
    ray.tfar = rng.below(3) == 0 ? ray.tnear + rng.range(0, 2) : kInf;
    NodeHits<W> ref;
    intersect_node<W>(Isa::kScalar, node, ray, &ref);
    hits += ref.mask != 0;
    for (Isa isa : simd_isas()) {
      NodeHits<W> got;
      intersect_node<W>(isa, node, ray, &got);
      ASSERT_EQ(got.mask, ref.mask) << isa_name(isa) << " W=" << W << " iter " << iter;
      for (int i = 0; i < W; ++i) ASSERT_EQ(bits_of(got.dist[i]), bits_of(ref.dist[i])) << isa_name(isa);
    }
  }
  EXPECT_GT(hits, 20000 / 8);
}

TEST(TraceKernels, NodeSimdEqualsScalarW4) { check_nodes<4>(11); }
TEST(TraceKernels, NodeSimdEqualsScalarW8) { check_nodes<8>(12); }
TEST(TraceKernels, NodeSimdEqualsScalarW16) { check_nodes<16>(13); }

std::vector<Isa> all_isas() {
  std::vector<Isa> v{Isa::kScalar};
  for (Isa i : simd_isas()) v.push_back(i);
  return v;
}

// A W=8 node whose lane 0 is the unit box [0,1]^3 and the others are empty.
fmt::WideNode<8> unit_box_node() {
  fmt::WideNode<8> n;
  for (int lane = 0; lane < 8; ++lane)
    for (int a = 0; a < 3; ++a) {
      n.lo[a][lane] = lane == 0 ? 0.0f : kInf;
      n.hi[a][lane] = lane == 0 ? 1.0f : -kInf;
    }
  for (int lane = 0; lane < 8; ++lane) n.child[lane] = lane == 0 ? 0 : fmt::ChildRef::kEmpty;
  for (int o = 0; o < 8; ++o)
    for (int i = 0; i < 8; ++i) n.order[o][i] = uint8_t(i);
  return n;
}

uint32_t node_mask(Isa isa, const fmt::WideNode<8>& n, const fmt::Ray& r) {
  NodeHits<8> h;
  intersect_node<8>(isa, n, r, &h);
  return h.mask;
}

// TESTING.md case 3: origin exactly on a box face, a zero (+0 or -0) direction component along that
// axis (0·inf = NaN in the slab), denormal and 1e-9 components: a hit, never a false miss.
TEST(TraceKernels, SlabOriginOnFaceWithZeroDirectionHits) {
  const fmt::WideNode<8> node = unit_box_node();
  // Exactly in the face plane (±0) or leaving it inward by a denormal or 1e-9 per unit t.
  const float zeros[] = {0.0f, -0.0f, 1e-40f, 1e-9f};
  for (Isa isa : all_isas())
    for (int a = 0; a < 3; ++a)
      for (float face : {0.0f, 1.0f})
        for (float z : zeros)
          for (float other : {1.0f, -1.0f}) {
            fmt::Ray r{{0.5f, 0.5f, 0.5f}, 0.0f, {0, 0, 0}, kInf};
            const int b = (a + 1) % 3;
            r.org[a] = face;
            r.org[b] = other > 0 ? -1.0f : 2.0f;  // outside along b, moving in
            r.dir[a] = face == 0.0f ? z : -z;
            r.dir[b] = other;
            EXPECT_EQ(node_mask(isa, node, r), 1u)
                << isa_name(isa) << " axis " << a << " face " << face << " dir " << r.dir[a] << " " << other;
            // The same ray outside the slab misses.
            r.org[a] = face == 0.0f ? -0.25f : 1.25f;
            r.dir[a] = face == 0.0f ? -z : z;
            EXPECT_EQ(node_mask(isa, node, r), 0u) << isa_name(isa);
          }
}

TEST(TraceKernels, SlabCornersEdgesAndEmptyLanes) {
  const fmt::WideNode<8> node = unit_box_node();
  for (Isa isa : all_isas()) {
    // Along an edge of the box (two zero components, origin on two faces).
    EXPECT_EQ(node_mask(isa, node, {{0, 1, -3}, 0, {0.0f, -0.0f, 1}, kInf}), 1u) << isa_name(isa);
    // Starting exactly at a corner, going out: the corner point is at t = 0.
    EXPECT_EQ(node_mask(isa, node, {{1, 1, 1}, 0, {1, 1, 1}, kInf}), 1u) << isa_name(isa);
    // Box exactly at tfar / tnear (entry at t = 2, exit at t = 3).
    EXPECT_EQ(node_mask(isa, node, {{-2, 0.5f, 0.5f}, 0, {1, 0, 0}, 2.0f}), 1u) << isa_name(isa);
    EXPECT_EQ(node_mask(isa, node, {{-2, 0.5f, 0.5f}, 3.0f, {1, 0, 0}, 5.0f}), 1u) << isa_name(isa);
    EXPECT_EQ(node_mask(isa, node, {{-2, 0.5f, 0.5f}, 3.01f, {1, 0, 0}, 5.0f}), 0u) << isa_name(isa);
    EXPECT_EQ(node_mask(isa, node, {{-2, 0.5f, 0.5f}, 0, {1, 0, 0}, 1.99f}), 0u) << isa_name(isa);
  }
  // Empty lanes (lo = +inf, hi = -inf) never hit, whatever the ray.
  fmt::WideNode<16> empty;
  for (int lane = 0; lane < 16; ++lane)
    for (int a = 0; a < 3; ++a) empty.lo[a][lane] = kInf, empty.hi[a][lane] = -kInf;
  Rng rng(5);
  for (int i = 0; i < 5000; ++i) {
    fmt::Ray r;
    for (int a = 0; a < 3; ++a) r.org[a] = rng.range(-1e30f, 1e30f), r.dir[a] = special_component(rng, rng.range(-1, 1));
    r.tnear = rng.below(2) ? -kInf : 0.0f;
    r.tfar = kInf;
    for (Isa isa : all_isas()) {
      NodeHits<16> h;
      intersect_node<16>(isa, empty, r, &h);
      ASSERT_EQ(h.mask, 0u) << isa_name(isa);
    }
  }
}

fmt::LeafBlock<4> one_triangle_block(float z) {
  fmt::LeafBlock<4> blk;
  const float v[3][3] = {{-1, -1, z}, {3, -1, z}, {-1, 3, z}};
  for (int lane = 0; lane < 4; ++lane) {
    for (int a = 0; a < 3; ++a) blk.v0[a][lane] = v[0][a], blk.v1[a][lane] = v[1][a], blk.v2[a][lane] = v[2][a];
    blk.prim[lane] = 7;
  }
  return blk;
}

// TESTING.md case 5: a hit exactly at tnear or at tfar is a hit; one ulp outside is not.
TEST(TraceKernels, TriangleIntervalEndsAreInclusive) {
  const fmt::LeafBlock<4> blk = one_triangle_block(5.0f);
  for (Isa isa : all_isas())
    for (float dz : {1.0f, 2.0f, 0.25f}) {
      const float t = 5.0f / dz;  // exact
      auto mask = [&](float tnear, float tfar) {
        BlockHits<4> h;
        intersect_block<4>(isa, blk, {{0, 0, 0}, tnear, {0, 0, dz}, tfar}, &h);
        if (h.mask) {
          EXPECT_EQ(h.t[0], t);
        }
        return h.mask;
      };
      EXPECT_EQ(mask(t, t), 0xFu) << isa_name(isa);
      EXPECT_EQ(mask(0, t), 0xFu) << isa_name(isa);
      EXPECT_EQ(mask(t, kInf), 0xFu) << isa_name(isa);
      EXPECT_EQ(mask(std::nextafter(t, kInf), kInf), 0u) << isa_name(isa);
      EXPECT_EQ(mask(0, std::nextafter(t, 0.0f)), 0u) << isa_name(isa);
    }
}

// TESTING.md case 4: invalid rays give no hit from either kernel, on every ISA.
TEST(TraceKernels, InvalidRaysNeverHit) {
  const fmt::LeafBlock<4> blk = one_triangle_block(5.0f);
  const fmt::WideNode<8> node = unit_box_node();
  const fmt::Ray good{{0.5f, 0.5f, -1}, 0, {0, 0, 1}, kInf};
  std::vector<fmt::Ray> bad;
  for (int c : {0, 1, 2, 4, 5, 6})  // org, dir
    for (float x : {NAN, kInf, -kInf}) {
      fmt::Ray r = good;
      (c < 3 ? r.org[c] : r.dir[c - 4]) = x;
      bad.push_back(r);
    }
  for (auto [tn, tf] : {std::pair{NAN, kInf}, {0.0f, NAN}, {2.0f, 1.0f}, {kInf, kInf}, {NAN, NAN}}) {
    fmt::Ray r = good;
    r.tnear = tn, r.tfar = tf;
    bad.push_back(r);
  }
  for (Isa isa : all_isas()) {
    BlockHits<4> bh;
    intersect_block<4>(isa, blk, good, &bh);
    EXPECT_EQ(bh.mask, 0xFu);
    EXPECT_EQ(node_mask(isa, node, good), 1u);
    for (const fmt::Ray& r : bad) {
      intersect_block<4>(isa, blk, r, &bh);
      EXPECT_EQ(bh.mask, 0u) << isa_name(isa);
      EXPECT_EQ(node_mask(isa, node, r), 0u) << isa_name(isa);
    }
  }
}

// Woop 2013: a ray through the shared edge of two triangles that lie on opposite sides of it (as seen
// along the ray) hits at least one of them, whatever the winding.
TEST(TraceKernels, SharedEdgesOfABlockDoNotLeak) {
  Rng rng(9);
  int checked = 0;
  for (int iter = 0; iter < 40000; ++iter) {
    fmt::LeafBlock<8> blk;
    float p[4][3];
    for (auto& q : p)
      for (float& c : q) c = rng.range(-1, 1);
    // Lanes 0/1: (p0 p1 p2) and (p0 p2 p3) sharing the diagonal p0-p2; lanes 4/5 the same with the
    // second triangle wound the other way; lanes 2, 3, 6, 7 repeat them.
    for (int lane = 0; lane < 8; ++lane)
      for (int a = 0; a < 3; ++a) {
        const bool second = lane % 2;
        blk.v0[a][lane] = p[0][a];
        blk.v1[a][lane] = second ? p[2][a] : p[1][a];
        blk.v2[a][lane] = second ? p[3][a] : p[2][a];
        if (lane >= 4 && second) std::swap(blk.v1[a][lane], blk.v2[a][lane]);
        blk.prim[lane] = uint32_t(lane);
      }
    const float s = iter % 2 ? 0.5f : float(rng.uniform());
    fmt::Ray r;
    r.tnear = 0, r.tfar = kInf;
    for (int a = 0; a < 3; ++a) r.org[a] = rng.range(-3, 3);
    for (int a = 0; a < 3; ++a) r.dir[a] = ((1 - s) * p[0][a] + s * p[2][a]) - r.org[a];
    // Side of p1 and p3 relative to the edge, seen along the ray: det[dir, p2 - p0, p - p0].
    auto side = [&](const float* q) {
      const double e[3] = {double(p[2][0]) - p[0][0], double(p[2][1]) - p[0][1], double(p[2][2]) - p[0][2]};
      const double f[3] = {double(q[0]) - p[0][0], double(q[1]) - p[0][1], double(q[2]) - p[0][2]};
      const double c[3] = {e[1] * f[2] - e[2] * f[1], e[2] * f[0] - e[0] * f[2], e[0] * f[1] - e[1] * f[0]};
      const double v = c[0] * r.dir[0] + c[1] * r.dir[1] + c[2] * r.dir[2];
      const double scale = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) *
                           std::sqrt(double(r.dir[0]) * r.dir[0] + double(r.dir[1]) * r.dir[1] + double(r.dir[2]) * r.dir[2]);
      return v > 1e-3 * scale ? 1 : (v < -1e-3 * scale ? -1 : 0);
    };
    const int s1 = side(p[1]), s3 = side(p[3]);
    if (s1 == 0 || s3 == 0 || s1 == s3) continue;  // not a crossing of the edge between the two
    ++checked;
    BlockHits<8> ref;
    intersect_block<8>(Isa::kScalar, blk, r, &ref);
    for (Isa isa : all_isas()) {
      BlockHits<8> h;
      intersect_block<8>(isa, blk, r, &h);
      ASSERT_EQ(h.mask, ref.mask) << isa_name(isa);
      ASSERT_NE(h.mask & 0x3u, 0u) << "leak through a shared edge: " << isa_name(isa) << " iter " << iter;
      ASSERT_NE(h.mask & 0x30u, 0u) << "leak through a shared edge: " << isa_name(isa) << " iter " << iter;
    }
  }
  EXPECT_GT(checked, 5000);
}

// t of long thin triangles hit at grazing angles (a Lantern triangle: 15 x 0.04, 84 degrees off the
// normal, where Woop's T / det was 2e-4 off): the plane-equation t stays within 1e-5 of double.
TEST(TraceKernels, TriangleTIsAccurateOnGrazingNeedles) {
  Rng rng(17);
  double worst = 0;
  int hits = 0;
  for (int iter = 0; iter < 20000; ++iter) {
    fmt::LeafBlock<4> blk;
    float p[3][3];
    for (int a = 0; a < 3; ++a) p[0][a] = rng.range(-10, 10);
    float dir_long[3], across[3];
    for (int a = 0; a < 3; ++a) dir_long[a] = rng.range(-1, 1), across[a] = rng.range(-1, 1);
    const float len = rng.range(1, 20), width = rng.range(1e-3f, 0.1f);
    for (int a = 0; a < 3; ++a) {
      p[1][a] = p[0][a] + len * dir_long[a] + width * across[a];
      p[2][a] = p[0][a] + len * dir_long[a];
    }
    for (int lane = 0; lane < 4; ++lane)
      for (int a = 0; a < 3; ++a) blk.v0[a][lane] = p[0][a], blk.v1[a][lane] = p[1][a], blk.v2[a][lane] = p[2][a];
    for (int lane = 0; lane < 4; ++lane) blk.prim[lane] = 0;
    // Aim at an interior point from a random origin.
    const float b1 = float(rng.uniform()) * 0.5f, b2 = float(rng.uniform()) * 0.5f;
    fmt::Ray r{{rng.range(-12, 12), rng.range(-12, 12), rng.range(-12, 12)}, 0, {0, 0, 0}, kInf};
    for (int a = 0; a < 3; ++a) r.dir[a] = ((1 - b1 - b2) * p[0][a] + b1 * p[1][a] + b2 * p[2][a]) - r.org[a];
    // Double reference: plane through the float vertices.
    double e1[3], e2[3], n[3], num = 0, den = 0;
    for (int a = 0; a < 3; ++a) e1[a] = double(p[1][a]) - p[0][a], e2[a] = double(p[2][a]) - p[0][a];
    n[0] = e1[1] * e2[2] - e1[2] * e2[1], n[1] = e1[2] * e2[0] - e1[0] * e2[2], n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    for (int a = 0; a < 3; ++a) num += n[a] * (double(p[0][a]) - r.org[a]), den += n[a] * r.dir[a];
    const double t_ref = num / den;
    const double cosine =
        std::fabs(den) / (std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) *
                          std::sqrt(double(r.dir[0]) * r.dir[0] + double(r.dir[1]) * r.dir[1] + double(r.dir[2]) * r.dir[2]));
    if (cosine < 0.05) continue;  // closer to the plane t is ill-conditioned in any float test
    for (Isa isa : all_isas()) {
      BlockHits<4> h;
      intersect_block<4>(isa, blk, r, &h);
      if (!h.mask) continue;        // a ray grazing right along the needle may pass beside it
      hits += isa == Isa::kScalar;  // counted once per ray: the threshold holds on any CPU
      worst = std::max(worst, std::fabs(h.t[0] - t_ref) / std::fabs(t_ref));
    }
  }
  EXPECT_GT(hits, 10000);
  EXPECT_LT(worst, 1e-5);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp
