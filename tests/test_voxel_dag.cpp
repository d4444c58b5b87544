// lib/voxel unit tests (TESTING.md item 8 at the unit level): DAG build/decode/pool round trips,
// the structural check, and the ray/DAG test against the dense scalar reference.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "voxel/voxel.h"
#include "voxel_rng.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using voxel::DagHit;
using voxel::DagPool;
using voxel::DagView;
using voxel::Grid;
using voxel::LocalDag;

constexpr double kInf = std::numeric_limits<double>::infinity();

// ---------------------------------------------------------------------------------------------
// ---------------------------------------------------------------------------------------------
// Random grids: sparse noise, solid boxes (full subtrees), and a repeated pattern (shared subtrees).
Grid random_grid(Rng& rng, uint32_t R, double density, int boxes, bool pattern) {
  Grid g({float(rng.range(-4, 4)), float(rng.range(-4, 4)), float(rng.range(-4, 4))}, float(rng.range(0.1, 2)), R);
  for (uint64_t i = 0, n = uint64_t(density * R * R * R); i < n; ++i) g.set(rng.below(R), rng.below(R), rng.below(R));
  for (int b = 0; b < boxes; ++b) {
    uint32_t lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
      lo[k] = rng.below(R);
      hi[k] = std::min(R - 1, lo[k] + rng.below(std::max(2u, R / 2)));
    }
    for (uint32_t z = lo[2]; z <= hi[2]; ++z)
      for (uint32_t y = lo[1]; y <= hi[1]; ++y)
        for (uint32_t x = lo[0]; x <= hi[0]; ++x) g.set(x, y, z);
  }
  if (pattern)
    for (uint32_t z = 0; z < R; ++z)
      for (uint32_t y = 0; y < R; ++y)
        for (uint32_t x = 0; x < R; ++x)
          if ((x % 8 == 1 && y % 8 == 2) || z % 16 == 5) g.set(x, y, z);
  return g;
}

fmt::DagGrid dag_grid(const Grid& g, uint32_t root, float ray_rel = 0) {
  fmt::DagGrid d{};
  for (int k = 0; k < 3; ++k) d.origin[k] = float(g.origin[k]);
  d.cell = float(g.cell);
  d.resolution = g.resolution;
  d.root = root;
  d.margin = 0;
  d.ray_rel = ray_rel;
  return d;
}
DagView view_of(const LocalDag& d) { return {d.words.data(), d.words.size(), d.leaves.data(), d.leaves.size()}; }
DagView view_of(const DagPool& p) { return {p.words().data(), p.words().size(), p.leaves().data(), p.leaves().size()}; }

// TESTING.md item 8 (the proxy stores exactly what was voxelized): build_dag + decode_dag is the
// identity; empty and full grids use the special roots; R = 4 is a single leaf.
TEST(VoxelDag, BuildDecodeRoundTrip) {
  Rng rng(2);
  int grids = 0;
  for (uint32_t R : {4u, 8u, 16u, 32u, 64u})
    for (int t = 0; t < (R >= 64 ? 4 : 12); ++t) {
      const double density = std::ldexp(1.0, -int(rng.below(10)));
      const Grid g = random_grid(rng, R, density, int(rng.below(4)), rng.below(3) == 0);
      const LocalDag d = build_dag(g);
      const fmt::DagGrid dg = dag_grid(g, d.root);
      EXPECT_EQ(voxel::check_dag(dg, view_of(d)), "") << "R=" << R << " grid " << t;
      const Grid back = voxel::decode_dag(dg, view_of(d));
      EXPECT_TRUE(back.dense() == g.dense())
          << "R=" << R << " grid " << t << ": decoded " << back.count() << " cells of " << g.count();
      EXPECT_EQ(back.resolution, R);
      EXPECT_EQ(voxel::dag_reachable_bytes(dg, view_of(d)), d.bytes()) << "a DAG built alone is all reachable";
      if (R == 4 && d.root != fmt::kDagEmpty && d.root != fmt::kDagFull) {
        EXPECT_TRUE(d.words.empty());
        ASSERT_LT(d.root, d.leaves.size()) << "an R = 4 root is a leaf index";
        EXPECT_EQ(d.leaves[d.root], g.block(0, 0, 0));
      }
      ++grids;
    }
  EXPECT_GT(grids, 40);
  for (uint32_t R : {4u, 16u, 64u}) {
    const Grid empty({0, 0, 0}, 1, R);
    const LocalDag e = build_dag(empty);
    EXPECT_EQ(e.root, fmt::kDagEmpty);
    EXPECT_EQ(e.bytes(), 0u);
    EXPECT_EQ(voxel::decode_dag(dag_grid(empty, e.root), view_of(e)).count(), 0u);
    Grid full({0, 0, 0}, 1, R);
    const uint32_t nb = full.blocks_per_axis();
    for (uint32_t z = 0; z < nb; ++z)
      for (uint32_t y = 0; y < nb; ++y)
        for (uint32_t x = 0; x < nb; ++x) full.set_block(x, y, z, ~uint64_t(0));
    const LocalDag f = build_dag(full);
    EXPECT_EQ(f.root, fmt::kDagFull);
    EXPECT_EQ(f.bytes(), 0u);
    EXPECT_TRUE(voxel::decode_dag(dag_grid(full, f.root), view_of(f)).dense() == full.dense());
    // A grid that is full but for one cell: every level above a full subtree uses the full mask.
    Grid almost = full;
    almost.set_block(nb - 1, nb - 1, nb - 1, ~uint64_t(0) >> 1);
    const LocalDag a = build_dag(almost);
    EXPECT_EQ(a.leaves.size(), R == 4 ? 1u : 0u);                       // used once: inline in its level-1 node (R = 4: the root)
    EXPECT_EQ(a.node_offsets.size(), size_t(std::countr_zero(R / 4)));  // one node per level
    EXPECT_TRUE(voxel::decode_dag(dag_grid(almost, a.root), view_of(a)).dense() == almost.dense());
  }
}

// formats/dag.h 3.0: a leaf that one level-1 node references is stored inline (two words), a leaf that
// several reference is pooled once; the pool keeps both forms and decodes them back.
TEST(VoxelDag, InlinesLeavesUsedOnce) {
  Grid g({0, 0, 0}, 1, 16);  // 4^3 blocks: a root (level 2) over 8 level-1 nodes of 2^3 blocks each
  const uint64_t shared = 0x0000'0000'0001'0021ull, once = 0x8000'0000'0000'0400ull, other = 0x00F0'0000'0000'0000ull;
  g.set_block(0, 0, 0, shared);  // node (0,0,0): the shared mask twice and `once`
  g.set_block(1, 0, 0, shared);
  g.set_block(0, 1, 0, once);
  g.set_block(2, 2, 2, shared);  // node (1,1,1): the shared mask (a third use) and `other`
  g.set_block(3, 3, 3, other);
  const LocalDag d = build_dag(g);
  ASSERT_EQ(d.leaves, std::vector<uint64_t>{shared});
  // Root 1 + 2 references; node (0,0,0): 1 + 2 references + 2 inline words; node (1,1,1): 1 + 1 + 2.
  EXPECT_EQ(d.words.size(), 3u + 5u + 4u);
  EXPECT_EQ(d.bytes(), 12u * 4 + 8);
  uint32_t inline_children = 0;
  for (size_t k = 0; k < d.node_offsets.size(); ++k)
    if (d.node_levels[k] == 1) inline_children += uint32_t(std::popcount(fmt::dag_inline_mask(d.words[d.node_offsets[k]])));
  EXPECT_EQ(inline_children, 2u);
  EXPECT_EQ(voxel::check_dag(dag_grid(g, d.root), view_of(d)), "");
  EXPECT_TRUE(voxel::decode_dag(dag_grid(g, d.root), view_of(d)).dense() == g.dense());
  // In a pool with a grid that uses `once` twice, `once` is pooled for that grid and stays inline here.
  Grid h({0, 0, 0}, 1, 16);
  h.set_block(0, 0, 0, once);
  h.set_block(3, 3, 3, once);
  DagPool pool;
  const uint32_t rg = pool.add(d), rh = pool.add(build_dag(h));
  EXPECT_EQ(pool.leaves(), (std::vector<uint64_t>{shared, once}));
  EXPECT_EQ(voxel::check_dags(std::vector<fmt::DagGrid>{dag_grid(g, rg), dag_grid(h, rh)}.data(), 2, view_of(pool)), "");
  EXPECT_TRUE(voxel::decode_dag(dag_grid(g, rg), view_of(pool)).dense() == g.dense());
  EXPECT_TRUE(voxel::decode_dag(dag_grid(h, rh), view_of(pool)).dense() == h.dense());
  EXPECT_EQ(voxel::dag_reachable_bytes(dag_grid(g, rg), view_of(pool)), d.bytes());
}

// TESTING.md item 8: the shared pool returns every grid exactly, shares identical subtrees, and is
// deterministic.
TEST(VoxelDag, PoolSharingAndDeterminism) {
  Rng rng(3);
  std::vector<Grid> grids;
  for (int i = 0; i < 24; ++i) {
    const uint32_t R = 4u << rng.below(5);
    grids.push_back(random_grid(rng, R, std::ldexp(1.0, -int(2 + rng.below(8))), int(rng.below(3)), rng.below(2) == 0));
  }
  std::vector<LocalDag> dags;
  dags.reserve(grids.size());
  for (const Grid& g : grids) dags.push_back(build_dag(g));
  DagPool pool, again;
  std::vector<uint32_t> roots;
  uint64_t separate = 0;
  for (const LocalDag& d : dags) {
    roots.push_back(pool.add(d));
    again.add(d);
    separate += d.bytes();
  }
  for (size_t i = 0; i < grids.size(); ++i) {
    const fmt::DagGrid dg = dag_grid(grids[i], roots[i]);
    EXPECT_EQ(voxel::check_dag(dg, view_of(pool)), "") << "grid " << i;
    EXPECT_TRUE(voxel::decode_dag(dg, view_of(pool)).dense() == grids[i].dense()) << "grid " << i;
    EXPECT_LE(voxel::dag_reachable_bytes(dg, view_of(pool)), dags[i].bytes());
  }
  EXPECT_LE(pool.bytes(), separate);
  EXPECT_GT(pool.bytes(), 0u);
  EXPECT_TRUE(pool.words() == again.words());
  EXPECT_TRUE(pool.leaves() == again.leaves());
  // The same DAG again: the same root, no growth.
  const uint64_t before = pool.bytes();
  for (size_t i = 0; i < dags.size(); ++i) EXPECT_EQ(pool.add(dags[i]), roots[i]) << "grid " << i;
  EXPECT_EQ(pool.bytes(), before);
  // A translated copy of a pattern shares its subtrees: the pool grows by less than the copy alone.
  Grid a({0, 0, 0}, 1, 32), b({5, 5, 5}, 0.5, 32);
  for (uint32_t z = 0; z < 32; ++z)
    for (uint32_t y = 0; y < 32; ++y)
      for (uint32_t x = 0; x < 32; ++x)
        if ((x * 7 + y * 3 + z) % 11 == 0 && x < 16) a.set(x, y, z), b.set(x, y, z);
  for (uint32_t z = 0; z < 32; ++z) b.set(31, 31, z);
  DagPool p2;
  const LocalDag da = build_dag(a), db = build_dag(b);
  const uint32_t ra = p2.add(da);
  const uint64_t after_a = p2.bytes();
  const uint32_t rb = p2.add(db);
  EXPECT_LT(p2.bytes() - after_a, db.bytes());
  EXPECT_TRUE(voxel::decode_dag(dag_grid(a, ra), view_of(p2)).dense() == a.dense());
  EXPECT_TRUE(voxel::decode_dag(dag_grid(b, rb), view_of(p2)).dense() == b.dense());
}

// TESTING.md "Hostile input" + item 8: check_dag names every broken reference the ray test follows.
TEST(VoxelDag, CheckDagReportsCorruption) {
  Rng rng(4);
  Grid g({0, 0, 0}, 1, 32);
  // Random cells (leaves used once: stored inline) and one cell in every other empty block of the
  // lower half (the same mask in many blocks: a pooled leaf that several level-1 nodes reference).
  for (int i = 0; i < 300; ++i) g.set(rng.below(32), rng.below(32), rng.below(32));
  for (uint32_t z = 0; z < 4; ++z)
    for (uint32_t y = 0; y < 8; ++y)
      for (uint32_t x = 0; x < 8; ++x)
        if ((x + y + z) % 2 == 0 && g.block(x, y, z) == 0) g.set(4 * x + 1, 4 * y + 2, 4 * z + 3);
  const LocalDag d = build_dag(g);
  ASSERT_NE(d.root, fmt::kDagEmpty);
  ASSERT_NE(d.root, fmt::kDagFull);
  const fmt::DagGrid dg = dag_grid(g, d.root);
  ASSERT_EQ(voxel::check_dag(dg, view_of(d)), "");
  // Level-1 nodes with an empty child: one whose children are all pooled leaves (n1), one whose first
  // child is inline (n2); and the root (level 3, children are nodes).
  uint32_t n1 = ~0u, n2 = ~0u;
  for (size_t k = 0; k < d.node_offsets.size(); ++k) {
    const uint32_t off = d.node_offsets[k], h = d.words[off];
    if (d.node_levels[k] != 1 || fmt::dag_full_mask(h) != 0 || fmt::dag_child_mask(h) == 0xFF) continue;
    if (fmt::dag_inline_mask(h) == 0 && n1 == ~0u) n1 = off;
    if ((fmt::dag_inline_mask(h) & (fmt::dag_child_mask(h) & -fmt::dag_child_mask(h))) != 0 && n2 == ~0u) n2 = off;
  }
  ASSERT_NE(n1, ~0u);
  ASSERT_NE(n2, ~0u);
  const uint32_t root = d.root;
  ASSERT_EQ(fmt::dag_full_mask(d.words[root]), 0u);
  ASSERT_EQ(fmt::dag_inline_mask(d.words[root]), 0u);
  struct Case {
    const char* what;
    std::function<void(std::vector<uint32_t>&, std::vector<uint64_t>&, fmt::DagGrid&)> corrupt;
  };
  const Case cases[] = {
      {"child offset out of range", [&](auto& w, auto&, auto&) { w[root + 1] = uint32_t(w.size() + 5); }},
      {"child offset far out of range", [&](auto& w, auto&, auto&) { w[root + 1] = 0xFFFFFF00u; }},
      {"root out of range", [&](auto& w, auto&, auto& gr) { gr.root = uint32_t(w.size()); }},
      {"empty child mask", [&](auto& w, auto&, auto&) { w[n1] = 0; }},
      {"full mask 0xFF", [&](auto& w, auto&, auto&) { w[n1] = 0xFFu | 0xFFu << 8; }},
      {"full mask outside the child mask", [&](auto& w, auto&, auto&) { w[n1] = (w[n1] & 0xFFu) | (~w[n1] & 0xFFu) << 8; }},
      {"high bits set", [&](auto& w, auto&, auto&) { w[n1] |= 1u << 26; }},
      {"references past the pool", [&](auto& w, auto&, auto&) { w.resize(root + 1); }},  // the root is written last
      {"leaf index out of range", [&](auto& w, auto& l, auto&) { w[n1 + 1] = uint32_t(l.size() + 3); }},
      {"leaf mask 0", [&](auto& w, auto& l, auto&) { l[w[n1 + 1]] = 0; }},
      {"leaf mask all ones", [&](auto& w, auto& l, auto&) { l[w[n1 + 1]] = ~uint64_t(0); }},
      {"inline leaf 0", [&](auto& w, auto&, auto&) { w[n2 + 1] = w[n2 + 2] = 0; }},
      {"inline leaf all ones", [&](auto& w, auto&, auto&) { w[n2 + 1] = w[n2 + 2] = ~0u; }},
      {"inline mask outside the references", [&](auto& w, auto&, auto&) { w[n2] |= (~w[n2] & 0xFFu) << 16; }},
      {"inline leaves above level 1", [&](auto& w, auto&, auto&) { w[root] |= (w[root] & 0xFFu) << 16; }},
      {"inline leaf runs past the pool",
       [&](auto& w, auto&, auto& gr) {
         gr.resolution = 8, gr.root = n2;  // n2 as the level-1 root of an 8^3 grid, its last word cut off
         w.resize(n2 + fmt::dag_node_words(w[n2]) - 1);
       }},
      {"resolution not a power of two", [&](auto&, auto&, auto& gr) { gr.resolution = 48; }},
      {"resolution too large", [&](auto&, auto&, auto& gr) { gr.resolution = 2048; }},
      {"cell 0", [&](auto&, auto&, auto& gr) { gr.cell = 0; }},
      {"origin NaN", [&](auto&, auto&, auto& gr) { gr.origin[1] = std::numeric_limits<float>::quiet_NaN(); }},
      {"negative margin", [&](auto&, auto&, auto& gr) { gr.margin = -1; }},
  };
  for (const Case& c : cases) {
    std::vector<uint32_t> w = d.words;
    std::vector<uint64_t> l = d.leaves;
    fmt::DagGrid gr = dg;
    c.corrupt(w, l, gr);
    const std::string e = voxel::check_dag(gr, {w.data(), w.size(), l.data(), l.size()});
    EXPECT_NE(e, "") << c.what;
  }
  // An R = 4 grid whose root is a leaf: out of range and empty leaves.
  Grid small({0, 0, 0}, 1, 4);
  small.set(1, 2, 3);
  const LocalDag s = build_dag(small);
  std::vector<uint64_t> l = s.leaves;
  EXPECT_EQ(voxel::check_dag(dag_grid(small, s.root), {nullptr, 0, l.data(), l.size()}), "");
  EXPECT_NE(voxel::check_dag(dag_grid(small, uint32_t(l.size())), {nullptr, 0, l.data(), l.size()}), "");
  l[s.root] = 0;
  EXPECT_NE(voxel::check_dag(dag_grid(small, s.root), {nullptr, 0, l.data(), l.size()}), "");
}

// ---------------------------------------------------------------------------------------------
// A float ray (as fmt::Ray stores it) against a grid, in grid units mapped to world.
struct TestRay {
  double org[3], dir[3], tnear, tfar;
};

float f(double v) { return float(v); }

TestRay random_test_ray(Rng& rng, const Grid& g, int kind) {
  const double R = g.resolution;
  auto world = [&](double gx, double gy, double gz) { return g.origin + Vec3d{gx, gy, gz} * g.cell; };
  auto inside = [&] { return world(rng.range(0, R), rng.range(0, R), rng.range(0, R)); };
  Vec3d o, d;
  double tnear = 0, tfar = kInf;
  switch (kind % 6) {
    case 0: {  // from outside (a sphere around the grid) through a point inside
      Vec3d u{rng.range(-1, 1), rng.range(-1, 1), rng.range(-1, 1)};
      o = g.origin + Vec3d{R / 2, R / 2, R / 2} * g.cell + u * (R * g.cell * rng.range(1, 3) / std::max(1e-9, length(u)));
      d = (inside() - o) * rng.range(0.25, 4);
      break;
    }
    case 1:  // from inside in a random direction
      o = inside();
      d = {rng.range(-1, 1), rng.range(-1, 1), rng.range(-1, 1)};
      break;
    case 2: {  // axis-parallel: exact zero components, origins often on cell planes or cell centres
      o = world(std::floor(rng.range(-2, R + 2)), std::floor(rng.range(-2, R + 2)), std::floor(rng.range(-2, R + 2)));
      for (int k = 0; k < 3; ++k)
        if (rng.below(2)) o[k] += g.cell * (rng.below(2) ? 0.5 : rng.uniform());
      d = {0, 0, 0};
      const int axis = int(rng.below(3));
      d[axis] = rng.below(2) ? 1 : -1;
      if (rng.below(3) == 0) d[(axis + 1) % 3] = rng.range(-1, 1);  // one zero component
      o[axis] = d[axis] > 0 ? g.origin[axis] - g.cell * rng.range(0, 3) : g.origin[axis] + g.cell * (R + rng.range(0, 3));
      if (rng.below(4) == 0) o[axis] = g.origin[axis] + g.cell * std::floor(rng.range(0, R));  // starts inside, on a plane
      break;
    }
    case 3:  // tiny and huge direction lengths, tnear > 0
      o = inside();
      d = Vec3d{rng.range(-1, 1), rng.range(-1, 1), rng.range(-1, 1)} * std::ldexp(1.0, int(rng.below(40)) - 20);
      tnear = rng.range(0, R * g.cell / std::max(1e-30, length(d)));
      break;
    case 4: {  // short rays: tfar a fraction of the way through the grid
      o = inside();
      d = inside() - o;
      tfar = rng.range(0, 1.5);
      tnear = rng.below(2) ? 0 : tfar * rng.uniform();
      break;
    }
    default: {  // directions with denormal / 1e-9 components
      o = inside();
      d = {rng.range(-1, 1), rng.range(-1, 1), rng.range(-1, 1)};
      const int k = int(rng.below(3));
      d[k] = rng.below(2) ? 1e-9 : std::numeric_limits<float>::denorm_min() * double(1 + rng.below(8));
      if (rng.below(2)) d[k] = -d[k];
      break;
    }
  }
  TestRay r;
  for (int k = 0; k < 3; ++k) r.org[k] = f(o[k]), r.dir[k] = f(d[k]);
  if (r.dir[0] == 0 && r.dir[1] == 0 && r.dir[2] == 0) r.dir[0] = 1;
  r.tnear = f(tnear);
  r.tfar = std::isinf(tfar) ? kInf : double(f(tfar));
  return r;
}

// TESTING.md item 8 at the unit level: the DAG walk never culls a ray the dense reference says
// meets a set cell (with the growth the walk is given), never enters later than the reference,
// including interval edges just before and just after a set cell; and it does cull.
TEST(VoxelDagQuery, NeverCullsWhatTheReferenceHits) {
  Rng rng(5);
  uint64_t rays = 0, ref_hits = 0, ref_culled = 0, dag_culled = 0, false_culls = 0, late = 0, edge_rays = 0;
  for (uint32_t R : {4u, 8u, 16u, 32u}) {
    for (int gi = 0; gi < (R == 32 ? 6 : 12); ++gi) {
      const Grid g = random_grid(rng, R, std::ldexp(1.0, -int(3 + rng.below(8))), int(rng.below(2)), rng.below(4) == 0);
      const LocalDag d = build_dag(g);
      const float ray_rel = rng.below(2) ? 0.0f : float(std::ldexp(1.0, -int(14 + rng.below(10))));
      const fmt::DagGrid dg = dag_grid(g, d.root, ray_rel);
      ASSERT_EQ(voxel::check_dag(dg, view_of(d)), "");
      Grid ref_grid = g;  // the cells of g at the DAG grid's float origin and cell
      ref_grid.origin = {dg.origin[0], dg.origin[1], dg.origin[2]};
      ref_grid.cell = dg.cell;
      const int n = R == 32 ? 250 : 500;
      for (int i = 0; i < n; ++i) {
        TestRay r = random_test_ray(rng, ref_grid, i);
        for (int variant = 0; variant < 3; ++variant) {
          const double growth = voxel::dag_ray_growth(dg, r.org);
          const DagHit ref = voxel::grid_first_entry_reference(ref_grid, growth, r.org, r.dir, r.tnear, r.tfar);
          const DagHit got = voxel::dag_first_entry(dg, view_of(d), r.org, r.dir, r.tnear, r.tfar);
          ++rays;
          ref_culled += ref.culled;
          dag_culled += got.culled;
          if (!ref.culled) {
            ++ref_hits;
            const bool bad = got.culled;
            const bool is_late = !got.culled && got.t_entry > ref.t_entry + 1e-12 * std::max(1.0, std::fabs(ref.t_entry));
            false_culls += bad;
            late += is_late;
            EXPECT_FALSE(bad || is_late) << "R=" << R << " grid " << gi << " ray " << i << " variant " << variant
                                         << (bad ? ": culled" : ": late entry ") << " ref t=" << ref.t_entry
                                         << " dag t=" << got.t_entry << " org (" << r.org[0] << "," << r.org[1] << "," << r.org[2]
                                         << ") dir (" << r.dir[0] << "," << r.dir[1] << "," << r.dir[2] << ") [" << r.tnear << ","
                                         << r.tfar << "]";
            if (!got.culled) {
              EXPECT_GE(got.t_entry, r.tnear);
            }
          }
          // Variants around the first set cell: the interval ending just before / at / just after its
          // entry, and starting just before it.
          const DagHit open = voxel::grid_first_entry_reference(ref_grid, growth, r.org, r.dir, r.tnear, kInf);
          if (open.culled || variant == 2) break;
          const float te = float(open.t_entry);
          ++edge_rays;
          if (variant == 0) {
            r.tfar = rng.below(2) ? double(std::nextafter(te, -INFINITY)) : double(std::nextafter(te, INFINITY));
            if (r.tfar < r.tnear) r.tfar = r.tnear;
          } else {
            r.tfar = kInf;
            r.tnear = std::max(0.0, double(std::nextafter(te, -INFINITY)));
          }
        }
      }
    }
  }
  std::printf(
      "[ dag query] %llu rays (%llu at interval edges): reference hits %llu, reference culls %llu, DAG culls %llu, "
      "%llu false culls, %llu late entries\n",
      (unsigned long long)rays, (unsigned long long)edge_rays, (unsigned long long)ref_hits, (unsigned long long)ref_culled,
      (unsigned long long)dag_culled, (unsigned long long)false_culls, (unsigned long long)late);
  EXPECT_EQ(false_culls, 0u);
  EXPECT_EQ(late, 0u);
  EXPECT_GT(ref_hits, rays / 5) << "the rays must meet set cells";
  EXPECT_GT(ref_culled, rays / 5) << "the grids must be sparse enough to cull";
  // Not trivially conservative: the DAG culls most of what the reference culls.
  EXPECT_GT(dag_culled, ref_culled * 3 / 4);
  EXPECT_LE(dag_culled, ref_culled);
}

// TESTING.md item 8: special roots and the interval edges on a single cell, exactly.
TEST(VoxelDagQuery, SingleCellAndSpecialRoots) {
  Grid g({0, 0, 0}, 1, 16);
  g.set(5, 6, 7);
  const LocalDag d = build_dag(g);
  const fmt::DagGrid dg = dag_grid(g, d.root);
  const double org[3] = {-10, 6.5, 7.5}, dir[3] = {1, 0, 0};
  DagHit h = voxel::dag_first_entry(dg, view_of(d), org, dir, 0, kInf);
  EXPECT_FALSE(h.culled);
  EXPECT_LE(h.t_entry, 15.0);
  EXPECT_GT(h.t_entry, 14.9);
  EXPECT_FALSE(voxel::dag_first_entry(dg, view_of(d), org, dir, 0, 15.0).culled) << "tfar exactly at the entry";
  EXPECT_TRUE(voxel::dag_first_entry(dg, view_of(d), org, dir, 0, 14.5).culled) << "tfar half a cell before";
  EXPECT_TRUE(voxel::dag_first_entry(dg, view_of(d), org, dir, 16.5, kInf).culled) << "tnear half a cell after";
  EXPECT_FALSE(voxel::dag_first_entry(dg, view_of(d), org, dir, 15.5, kInf).culled) << "tnear inside the cell";
  const double miss[3] = {-10, 7.5, 7.5};
  EXPECT_TRUE(voxel::dag_first_entry(dg, view_of(d), miss, dir, 0, kInf).culled) << "the next row";
  const double face[3] = {-10, 7, 7.5};  // exactly on the cell's face: touching counts
  EXPECT_FALSE(voxel::dag_first_entry(dg, view_of(d), face, dir, 0, kInf).culled);
  EXPECT_TRUE(voxel::dag_first_entry(dag_grid(g, fmt::kDagEmpty), view_of(d), org, dir, 0, kInf).culled);
  const DagHit full = voxel::dag_first_entry(dag_grid(g, fmt::kDagFull), view_of(d), org, dir, 0, kInf);
  EXPECT_FALSE(full.culled);
  EXPECT_LE(full.t_entry, 10.0);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
