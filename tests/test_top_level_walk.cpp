// The top level over batching points (lib/trace/top_level_walk.h): top_lanes, the four-lane SSE2 form
// that both package tracers use, against top_lane, the one-lane reference, lane by lane and bit for
// bit, on random boxes and rays and on the cases its comparisons decide: a zero direction component
// (origin inside, outside and on a slab's face), entry exactly at tnear, boxes behind the ray, a
// degenerate (flat) box, equal planes whose entry distances are ±0.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>

#include "test_trace_util.h"
#include "trace/top_level_walk.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

uint64_t bits(double d) {
  uint64_t u;
  std::memcpy(&u, &d, 8);
  return u;
}

// Every lane's hit equals top_lane's; t0 equals it bit for bit where top_lane computed it fully (the
// lane's slabs of zero-direction axes hold the origin), which includes every lane that hits.
void expect_same(const fmt::TopNode& node, const fmt::Ray& ray, const char* what) {
  double inv[3];
  top_inverse(ray, inv);
  const TopLanes all = top_lanes(node, ray, inv);
  for (int l = 0; l < 4; ++l) {
    const TopLane one = top_lane(node, l, ray, inv);
    bool inside = true;
    for (int k = 0; k < 3; ++k)
      if (ray.dir[k] == 0) inside = inside && ray.org[k] >= node.lo[k][l] && ray.org[k] <= node.hi[k][l];
    ASSERT_EQ(((all.hit >> l) & 1u) != 0, one.hit) << what << " lane " << l;
    if (inside) {
      ASSERT_EQ(bits(all.t0[l]), bits(one.t0)) << what << " lane " << l << ": " << all.t0[l] << " vs " << one.t0;
    }
  }
}

TEST(TopLevelWalk, FourLanesEqualOneLaneOnRandomBoxesAndRays) {
  trace_test::Rng rng(77);
  auto coord = [&] { return float(rng.uniform() * 20 - 10); };
  for (int iter = 0; iter < 20000; ++iter) {
    fmt::TopNode node{};
    for (int l = 0; l < 4; ++l)
      for (int k = 0; k < 3; ++k) {
        float a = coord(), b = coord();
        if (rng.below(16) == 0) b = a;  // flat
        node.lo[k][l] = a < b ? a : b, node.hi[k][l] = a < b ? b : a;
      }
    fmt::Ray ray{};
    for (int k = 0; k < 3; ++k) {
      ray.org[k] = coord();
      ray.dir[k] = float(rng.uniform() * 2 - 1);
      switch (rng.below(8)) {
        case 0: ray.dir[k] = 0.0f; break;
        case 1: ray.dir[k] = -0.0f; break;
        case 2: ray.org[k] = node.lo[k][rng.below(4)]; break;  // on a face
        default: break;
      }
    }
    ray.tnear = rng.below(4) == 0 ? 0.0f : float(rng.uniform() * 5);
    ray.tfar = rng.below(4) == 0 ? trace_test::kInf : ray.tnear + float(rng.uniform() * 20);
    expect_same(node, ray, "random");
    if (::testing::Test::HasFatalFailure()) return;
  }
}

TEST(TopLevelWalk, FourLanesEqualOneLaneOnDecidingCases) {
  fmt::TopNode node{};
  const float lo[4] = {0, 2, -3, 1}, hi[4] = {1, 2, -1, 1};  // lane 1 and 3 flat along x
  for (int l = 0; l < 4; ++l)
    for (int k = 0; k < 3; ++k) node.lo[k][l] = lo[l], node.hi[k][l] = hi[l];
  const fmt::Ray rays[] = {
      {{0.5f, 0.5f, 0.5f}, 0, {0, 0, 1}, trace_test::kInf},  // zero x and y: inside lane 0 only
      {{2, 2, -5}, 0, {0, -0.0f, 1}, trace_test::kInf},      // on lane 1's flat faces
      {{-5, 0.5f, 0.5f}, 5, {1, 0, 0}, trace_test::kInf},    // enters lane 0 exactly at tnear
      {{5, 5, 5}, 0, {1, 1, 1}, trace_test::kInf},           // every box behind the ray
      {{1, 1, 1}, 0, {-1, -1, -1}, 0.0f},                    // tfar 0: only boxes at the origin
      {{0, 0, 0}, 0, {1, 1, 1}, trace_test::kInf},           // on lane 0's corner: entry ±0
      {{-2, -2, -2}, 0, {1, 1e-30f, -1}, trace_test::kInf},  // a huge reciprocal
  };
  int k = 0;
  for (const fmt::Ray& r : rays) {
    SCOPED_TRACE(k++);
    expect_same(node, r, "case");
  }
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
