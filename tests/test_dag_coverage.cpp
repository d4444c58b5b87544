// rtpack-inspect --verify's coverage test (lib/inspect/dag_coverage.h, formats/SPEC.md §4.5): a voxel
// grid covers a triangle when every cell the triangle meets is set. Checked against grids the
// converter's voxelizer builds (every triangle covered) and against a reference that needs no
// triangle/box test: points sampled on the triangle, each deep inside one cell, whose cell must be set.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>
#include <tuple>
#include <vector>

#include "inspect/dag_coverage.h"
#include "voxel/voxel.h"
#include "voxel_rng.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using voxel::Grid;
using Cell = std::tuple<uint32_t, uint32_t, uint32_t>;

struct Tri {
  double v[3][3];
};

// A triangle inside the grid box, away from its faces by two cells.
Tri random_triangle(Rng& rng, const Grid& g, double size_cells) {
  Tri t;
  const double span = g.cell * g.resolution;
  double c[3];
  for (int a = 0; a < 3; ++a)
    c[a] = g.origin[a] + rng.range(2 * g.cell + size_cells * g.cell, span - 2 * g.cell - size_cells * g.cell);
  for (int i = 0; i < 3; ++i)
    for (int a = 0; a < 3; ++a) t.v[i][a] = c[a] + rng.range(-size_cells, size_cells) * g.cell;
  return t;
}

// The grid as the pool stores it: its DAG added to a pool (pooled and inline leaves), with `margin`.
struct PooledGrid {
  voxel::DagPool pool;
  fmt::DagGrid grid{};
  voxel::DagView view() const { return {pool.words().data(), pool.words().size(), pool.leaves().data(), pool.leaves().size()}; }
};
void pool_grid(const Grid& g, double margin, PooledGrid& out) {
  out.grid.root = out.pool.add(voxel::build_dag(g));
  for (int a = 0; a < 3; ++a) out.grid.origin[a] = float(g.origin[a]);
  out.grid.cell = float(g.cell);
  out.grid.resolution = g.resolution;
  out.grid.margin = float(margin);
  ASSERT_EQ(voxel::check_dag(out.grid, out.view()), "");
}

// Cells that points sampled on the triangle fall into, each farther than `inset` cells from its cell's faces.
std::set<Cell> sampled_cells(const Grid& g, const Tri& t, double inset) {
  std::set<Cell> cells;
  const int n = 96;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; i + j <= n; ++j) {
      const double b1 = double(i) / n, b2 = double(j) / n, b0 = 1 - b1 - b2;
      uint32_t idx[3];
      bool deep = true;
      for (int a = 0; a < 3; ++a) {
        const double p = (b0 * t.v[0][a] + b1 * t.v[1][a] + b2 * t.v[2][a] - g.origin[a]) / g.cell;
        const double f = std::floor(p);
        deep &= p - f > inset && f + 1 - p > inset;
        idx[a] = uint32_t(f);
      }
      if (deep) cells.insert({idx[0], idx[1], idx[2]});
    }
  return cells;
}

// The converter's voxelization (Schwarz & Seidel 2010 with its margin) covers every triangle it set; a
// cell the triangle passes through, once cleared, leaves it uncovered.
TEST(DagCoverage, VoxelizedTrianglesAreCoveredAndACellClearedIsFound) {
  Rng rng(58);
  int covered = 0, cleared = 0;
  for (uint32_t R : {4u, 16u, 64u})
    for (int trial = 0; trial < 12; ++trial) {
      Grid g({rng.range(-5, 5), rng.range(-5, 5), rng.range(-5, 5)}, rng.range(0.05, 1.5), R);
      const double margin = 1e-3 * g.cell;
      std::vector<Tri> tris;
      for (int k = 0; k < 3; ++k) {
        tris.push_back(random_triangle(rng, g, std::min(double(R) / 8, rng.range(0.2, 6))));
        const Tri& t = tris.back();
        voxel::voxelize_triangle(g, {t.v[0][0], t.v[0][1], t.v[0][2]}, {t.v[1][0], t.v[1][1], t.v[1][2]},
                                 {t.v[2][0], t.v[2][1], t.v[2][2]}, margin);
      }
      PooledGrid pg;
      pool_grid(g, margin, pg);
      for (const Tri& t : tris) {
        EXPECT_TRUE(dag_covers_triangle(pg.grid, pg.view(), t.v)) << "R " << R << " trial " << trial;
        ++covered;
      }
      // Clear one cell the first triangle surely passes through (a sample deep inside it): the first
      // triangle must then be reported.
      for (const Cell& c : sampled_cells(g, tris[0], 0.05)) {
        Grid holed = g;
        const auto [x, y, z] = c;
        const uint64_t bit = uint64_t(1) << ((x & 3) + 4 * (y & 3) + 16 * (z & 3));
        holed.set_block(x >> 2, y >> 2, z >> 2, holed.block(x >> 2, y >> 2, z >> 2) & ~bit);
        PooledGrid ph;
        pool_grid(holed, margin, ph);
        EXPECT_FALSE(dag_covers_triangle(ph.grid, ph.view(), tris[0].v))
            << "R " << R << " trial " << trial << ": cell " << x << "," << y << "," << z << " cleared";
        ++cleared;
        break;
      }
    }
  EXPECT_EQ(covered, 3 * 36);
  EXPECT_GE(cleared, 30);
}

// A 6-separating (thin) voxelization leaves gaps a ray passes through: the test finds them.
TEST(DagCoverage, ThinVoxelizationIsNotCovering) {
  Rng rng(7);
  int uncovered = 0;
  for (int trial = 0; trial < 20; ++trial) {
    Grid g({0, 0, 0}, 1.0, 32);
    const Tri t = random_triangle(rng, g, 8);
    voxel::voxelize_triangle_thin(g, {t.v[0][0], t.v[0][1], t.v[0][2]}, {t.v[1][0], t.v[1][1], t.v[1][2]},
                                  {t.v[2][0], t.v[2][1], t.v[2][2]});
    PooledGrid pg;
    pool_grid(g, 0.0, pg);
    uncovered += !dag_covers_triangle(pg.grid, pg.view(), t.v);
  }
  EXPECT_GE(uncovered, 15);
}

// Special roots, a triangle reaching outside the grid, and a triangle no ray can hit.
TEST(DagCoverage, SpecialRootsOutsideAndNonFinite) {
  const voxel::DagView none{};
  fmt::DagGrid g{{0, 0, 0}, 1.0f, 16, fmt::kDagFull, 0.01f, 0};
  const Tri inside{{{1, 1, 1}, {5, 2, 1}, {2, 6, 3}}};
  EXPECT_TRUE(dag_covers_triangle(g, none, inside.v));
  const Tri out{{{1, 1, 1}, {17, 2, 1}, {2, 6, 3}}};
  EXPECT_FALSE(dag_covers_triangle(g, none, out.v));
  g.root = fmt::kDagEmpty;
  EXPECT_FALSE(dag_covers_triangle(g, none, inside.v));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Tri never{{{nan, 1, 1}, {5, 2, 1}, {2, 6, 3}}};
  EXPECT_TRUE(dag_covers_triangle(g, none, never.v));
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
