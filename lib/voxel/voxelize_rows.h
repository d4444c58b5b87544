#pragma once
// Internal to lib/voxel: the per-triangle constants of the conservative cell test (Schwarz & Seidel
// 2010 §3.1, as voxelize.cpp sets them up) and its AVX2 evaluation over a small box of cells.
#include <cstdint>

namespace rtp::voxel::detail {

// Boxes the AVX2 rows test takes: at most this many cells, at most 8 along x (two lanes of 4).
constexpr int kRowsMaxCells = 64;
constexpr int kRowsMaxX = 8;

// Cell (i0, i1, i2) has the grown corner p[k] = (org[k] + i_k * cell) - margin and is set when every
// test of voxelize_triangle's exhaustive loop passes, in this arithmetic:
//   boxes:  !(p[k] > box_hi[k] || p[k] + dp < box_lo[k])        (box_hi = hi - margin, box_lo = lo + margin)
//   plane:  np = (n0 p0 + n1 p1) + n2 p2;  !((np + d1) * (np + d2) > 0)
//   edges:  (ex[q][i] p[q] + ey[q][i] p[q+1 mod 3]) + ed[q][i] >= 0 for the planes q = xy, yz, zx.
struct CellTests {
  double org[3], cell, margin, dp;
  double box_lo[3], box_hi[3];
  double n[3], d1, d2;
  double ex[3][3], ey[3][3], ed[3][3];
  int f[3], l[3];  // the box of candidate cells (inside the grid)
};

// The cells of the box [f, l] (at most kRowsMaxCells, at most kRowsMaxX along x) that pass every
// test, bit-identical to testing each one in double: row (y, z) in masks[(z - f2) * ny + (y - f1)],
// bit j = cell x = f0 + j. Only on CPUs with AVX2 (voxelize_rows_avx2.cpp).
void row_masks_avx2(const CellTests& t, uint8_t* masks);

}  // namespace rtp::voxel::detail
