// Instance boxes as a culling proxy (formats/dag.h kDagBoxes, SPEC §4.5, version 7.0): the 8-bit
// rounding contains every box and stays within a step of it, and the reader's check refuses every
// malformed proxy a hostile file could hold. End to end (no hit culled): test_culling.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "formats/bvh_layout.h"
#include "formats/dag.h"
#include "layout/dag_query.h"
#include "voxel/instance_boxes.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

constexpr float kInf = std::numeric_limits<float>::infinity();

// Random nodes: boxes from 1e-3 to 1e5 across, centred up to 3e6 from the origin, some flat, some lanes
// empty (as the builder leaves them: +inf / -inf, ChildRef::kEmpty).
template <int W>
std::vector<fmt::WideNode<W>> random_nodes(size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<fmt::WideNode<W>> out(n);
  for (size_t i = 0; i < n; ++i) {
    fmt::WideNode<W>& nd = out[i];
    const double centre = (u(rng) < 0.3 ? 3e6 : 10.0) * (2 * u(rng) - 1);
    for (int l = 0; l < W; ++l) {
      const bool empty = l > 0 && u(rng) < 0.25;
      nd.child[l] = empty ? fmt::ChildRef::kEmpty : fmt::ChildRef::leaf(uint32_t(l), 1);
      for (int k = 0; k < 3; ++k) {
        const double size = std::pow(10.0, -3 + 8 * u(rng)) * (u(rng) < 0.1 ? 0 : 1);
        const double lo = centre + (2 * u(rng) - 1) * 1e3;
        nd.lo[k][l] = empty ? kInf : float(lo);
        nd.hi[k][l] = empty ? -kInf : float(lo + size);
        if (!empty && nd.hi[k][l] < nd.lo[k][l]) nd.hi[k][l] = nd.lo[k][l];
      }
    }
  }
  return out;
}

template <int W>
void expect_contained(uint64_t seed) {
  const std::vector<fmt::WideNode<W>> nodes = random_nodes<W>(2000, seed);
  std::vector<fmt::CullNode<W>> q;
  ASSERT_TRUE(voxel::quantize_instance_bvh<W>(nodes, q));
  ASSERT_EQ(q.size(), nodes.size());
  for (size_t i = 0; i < nodes.size(); ++i)
    for (int l = 0; l < W; ++l) {
      EXPECT_EQ(q[i].child[l], nodes[i].child[l]);
      if (fmt::ChildRef::is_empty(nodes[i].child[l])) continue;
      for (int k = 0; k < 3; ++k) {
        const fmt::CullNode<W>& c = q[i];
        const double lo = fmt::cull_plane(c.origin[k], c.scale[k], c.lo[k][l]);
        const double hi = fmt::cull_plane(c.origin[k], c.scale[k], c.hi[k][l]);
        ASSERT_LE(lo, double(nodes[i].lo[k][l])) << "W=" << W << " node " << i << " lane " << l << " axis " << k;
        ASSERT_GE(hi, double(nodes[i].hi[k][l])) << "W=" << W << " node " << i << " lane " << l << " axis " << k;
        // Outward by less than two steps of 1/255 of the node: rounding, not a box that covers all.
        const double step = double(c.scale[k]);
        ASSERT_LE(double(nodes[i].lo[k][l]) - lo, 2 * step) << "W=" << W << " node " << i << " lane " << l;
        ASSERT_LE(hi - double(nodes[i].hi[k][l]), 2 * step) << "W=" << W << " node " << i << " lane " << l;
      }
    }
}

TEST(InstanceBoxes, QuantizedBoxesContainTheBoxesWithinAStep) {
  expect_contained<4>(1);
  expect_contained<8>(2);
  expect_contained<16>(3);
}

TEST(InstanceBoxes, NonFiniteBoxIsNotQuantized) {
  std::vector<fmt::WideNode<8>> nodes = random_nodes<8>(3, 4);
  nodes[2].hi[1][0] = kInf;
  std::vector<fmt::CullNode<8>> q(5);
  EXPECT_FALSE(voxel::quantize_instance_bvh<8>(nodes, q));
  EXPECT_EQ(q.size(), 5u) << "nothing appended";
}

// A two-level tree: node 0 holds leaves in lanes 0-1 and node 1 in lane 2; node 1 holds two leaves.
struct Tree {
  std::vector<fmt::CullNode<8>> nodes;
  fmt::DagGrid grid{};
  voxel::DagView view() const {
    voxel::DagView v;
    v.cull = nodes.data(), v.cull_count = nodes.size(), v.cull_width = 8;
    return v;
  }
};
Tree tree() {
  std::vector<fmt::WideNode<8>> w(2);
  for (auto& n : w)
    for (int l = 0; l < 8; ++l) {
      n.child[l] = fmt::ChildRef::kEmpty;
      for (int k = 0; k < 3; ++k) n.lo[k][l] = kInf, n.hi[k][l] = -kInf;
    }
  auto box = [](fmt::WideNode<8>& n, int l, uint32_t child, float x0, float x1) {
    n.child[l] = child;
    n.lo[0][l] = x0, n.hi[0][l] = x1;
    n.lo[1][l] = n.lo[2][l] = 0, n.hi[1][l] = n.hi[2][l] = 1;
  };
  box(w[0], 0, fmt::ChildRef::leaf(0, 1), 0, 1);
  box(w[0], 1, fmt::ChildRef::leaf(1, 1), 2, 3);
  box(w[0], 2, fmt::ChildRef::inner(1), 10, 13);
  box(w[1], 0, fmt::ChildRef::leaf(2, 1), 10, 11);
  box(w[1], 1, fmt::ChildRef::leaf(3, 1), 12, 13);
  Tree t;
  EXPECT_TRUE(voxel::quantize_instance_bvh<8>(w, t.nodes));
  t.grid.resolution = fmt::kDagBoxes;
  t.grid.root = 0;
  return t;
}

fmt::Ray ray_along_x(float y) { return {{-5, y, 0.5f}, 0, {1, 0, 0}, kInf}; }

TEST(InstanceBoxes, RayMeetsTheBoxesItCrossesAndNoOthers) {
  const Tree t = tree();
  ASSERT_EQ(voxel::check_dags(&t.grid, 1, t.view()), "");
  fmt::Ray r = ray_along_x(0.5f);
  EXPECT_TRUE(voxel::dag_enter(t.grid, t.view(), r));
  EXPECT_EQ(r.tnear, 0.0f) << "instance boxes leave tnear as it is";
  r = ray_along_x(0.5f);
  r.tnear = 9.5f, r.tfar = 14.5f;  // x in [4.5, 9.5]: between the boxes
  EXPECT_FALSE(voxel::dag_enter(t.grid, t.view(), r));
  r.tnear = 16.2f, r.tfar = 16.8f;  // x in [11.2, 11.8]: inside node 1's box, between its two leaves
  EXPECT_FALSE(voxel::dag_enter(t.grid, t.view(), r));
  r = ray_along_x(3.0f);  // above every box
  EXPECT_FALSE(voxel::dag_enter(t.grid, t.view(), r));
}

TEST(InstanceBoxes, CheckRefusesMalformedProxies) {
  auto check = [](const Tree& t, uint64_t grids = 1) {
    const fmt::DagGrid g[2] = {t.grid, t.grid};
    return voxel::check_dags(g, grids, t.view());
  };
  auto expect_refused = [&](const Tree& t, const std::string& part, uint64_t grids = 1) {
    const std::string e = check(t, grids);
    EXPECT_NE(e.find(part), std::string::npos) << "got: '" << e << "'";
  };
  Tree t = tree();
  t.nodes[1].child[0] = fmt::ChildRef::inner(0);  // a child before its parent: a cycle
  expect_refused(t, "not after it");
  t = tree();
  t.nodes[0].child[2] = fmt::ChildRef::inner(7);  // past the last node
  expect_refused(t, "out of range");
  t = tree();
  t.grid.root = 2;
  expect_refused(t, "out of range");
  t = tree();
  expect_refused(t, "reached twice", 2);  // two points sharing their nodes
  t = tree();
  t.nodes[1].scale[2] = std::numeric_limits<float>::quiet_NaN();
  expect_refused(t, "non-finite");
  t = tree();
  t.nodes[0].scale[0] = -1;
  expect_refused(t, "negative");
  t = tree();
  t.grid.cell = 1;
  expect_refused(t, "must be 0");
  t = tree();
  voxel::DagView none;
  EXPECT_NE(voxel::check_dags(&t.grid, 1, none).find("no instance-box nodes"), std::string::npos);
  fmt::Ray r = ray_along_x(0.5f);
  EXPECT_TRUE(voxel::dag_enter(t.grid, none, r)) << "without nodes nothing is culled";
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
