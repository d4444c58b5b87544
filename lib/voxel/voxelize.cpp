// Triangle voxelization into a dense block grid: conservative (26-separating) as Schwarz & Seidel
// 2010 §3.1 define it, and thin (6-separating) as a test foil.
#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <utility>

#include "core/error.h"
#include "voxel/voxel.h"
#include "voxel/voxelize_rows.h"

namespace rtp::voxel {

Grid::Grid(const Vec3d& origin_, double cell_, uint32_t resolution_) : origin(origin_), cell(cell_), resolution(resolution_) {
  const uint32_t nb = resolution / 4;
  edge_ = std::min<uint32_t>(8, nb);
  shift_ = uint32_t(std::countr_zero(edge_));
  bricks_ = nb / edge_;
  brick_blocks_ = size_t(edge_) * edge_ * edge_;
  brick_.assign(size_t(bricks_) * bricks_ * bricks_, 0);
}

void Grid::allocate_brick(uint32_t& slot) {
  store_.resize(store_.size() + brick_blocks_, 0);
  slot = uint32_t(store_.size() / brick_blocks_);
}

uint64_t Grid::count() const {
  // SWAR bit count (baseline x86-64 has no popcnt: std::popcount is a libgcc call per block there,
  // 1.2 % of a 10^5-instance forest's convert). Per 64-bit block: 2-, 4-, 8-bit sums, then one multiply.
  uint64_t n = 0;
  for (uint64_t b : store_) {
    b -= (b >> 1) & 0x5555555555555555ull;
    b = (b & 0x3333333333333333ull) + ((b >> 2) & 0x3333333333333333ull);
    b = (b + (b >> 4)) & 0x0F0F0F0F0F0F0F0Full;
    n += (b * 0x0101010101010101ull) >> 56;
  }
  return n;
}

void Grid::merge(const Grid& other) {
  if (other.resolution != resolution || other.brick_.size() != brick_.size())
    throw Error(ExitCode::kInternal, "Grid::merge: grids of different resolutions");
  for (size_t i = 0; i < other.brick_.size(); ++i) {
    if (!other.brick_[i]) continue;
    if (!brick_[i]) allocate_brick(brick_[i]);
    uint64_t* dst = store_.data() + size_t(brick_[i] - 1) * brick_blocks_;
    const uint64_t* src = other.store_.data() + size_t(other.brick_[i] - 1) * brick_blocks_;
    for (size_t b = 0; b < brick_blocks_; ++b) dst[b] |= src[b];
  }
}

bool Grid::region_empty(uint32_t bx, uint32_t by, uint32_t bz, uint32_t size) const {
  if (size < edge_) return brick_[brick_index(bx, by, bz)] == 0;
  const uint32_t n = size >> shift_, x0 = bx >> shift_, y0 = by >> shift_, z0 = bz >> shift_;
  for (uint32_t z = z0; z < z0 + n; ++z)
    for (uint32_t y = y0; y < y0 + n; ++y)
      for (uint32_t x = x0; x < x0 + n; ++x)
        if (brick_[x + bricks_ * (y + size_t(bricks_) * z)]) return false;
  return true;
}

std::vector<uint64_t> Grid::dense() const {
  const uint32_t nb = blocks_per_axis();
  std::vector<uint64_t> out(size_t(nb) * nb * nb, 0);
  for (uint32_t z = 0; z < nb; ++z)
    for (uint32_t y = 0; y < nb; ++y)
      for (uint32_t x = 0; x < nb; ++x) out[x + nb * (y + size_t(nb) * z)] = block(x, y, z);
  return out;
}

namespace {

// Cell range [first, last] whose cells overlap [lo, hi] on one axis; false when outside the grid.
inline bool cell_range(double origin, double inv_cell, uint32_t resolution, double lo, double hi, int& first, int& last) {
  // The quotients are rounded (relative 2^-52 each): pad by one cell only when one lies within 1e-9
  // (relative) of a cell plane; the exact tests decide. Most small triangles then test 1-8 cells, not 27.
  const double qa = (lo - origin) * inv_cell, qb = (hi - origin) * inv_cell;
  const double pa = 1e-9 * (std::fabs(qa) + 1), pb = 1e-9 * (std::fabs(qb) + 1);
  const double a = qa - pa, b = qb + pb, r = double(resolution);
  // A closed box touching the grid's upper face (qa == R) or lower face (qb == 0) still reaches the
  // boundary cell: the padding makes floor(a) == R - 1 or floor(b) == 0 there.
  if (!(b >= 0) || !(a < r)) return false;  // also NaN
  // floor() by truncation (no libm call: baseline x86-64 has no roundsd), on values clamped to [0, R]:
  // below 0 the first cell is 0 whatever the floor, and b >= 0 here.
  first = int(std::max(a, 0.0));
  last = std::min(int(std::min(b, r)), int(resolution) - 1);
  return first <= last;
}

bool cell_range(const Grid& g, int axis, double lo, double hi, int& first, int& last) {
  return cell_range(g.origin[axis], 1 / g.cell, g.resolution, lo, hi, first, last);
}

// A 4x4x4 block's cells (bit x + 4y + 16z) whose x, y or z coordinate is in the 4-bit set p.
constexpr auto kAxisBits = [] {
  struct {
    uint64_t axis[3][16];
  } t{};
  for (uint32_t p = 0; p < 16; ++p)
    for (uint32_t i = 0; i < 4; ++i) {
      if (!(p >> i & 1u)) continue;
      t.axis[0][p] |= 0x1111111111111111ull << i;
      t.axis[1][p] |= 0x000F000F000F000Full << (4 * i);
      t.axis[2][p] |= 0xFFFFull << (16 * i);
    }
  return t;
}();

// The cells [first, last] of one axis within block `block`, as that block's mask (first <= last, the
// block meets them).
inline uint64_t axis_mask(int axis, int first, int last, int block) {
  const int a = std::max(first, 4 * block) - 4 * block, b = std::min(last, 4 * block + 3) - 4 * block;
  return kAxisBits.axis[axis][((2u << (b - a)) - 1) << a];
}

// True when every cell of the box [f, l] (cell indices, inside the grid) is set: block by block.
bool all_cells_set(const Grid& g, const int f[3], const int l[3]) {
  for (int bz = f[2] >> 2; bz <= l[2] >> 2; ++bz) {
    const uint64_t mz = axis_mask(2, f[2], l[2], bz);
    for (int by = f[1] >> 2; by <= l[1] >> 2; ++by) {
      const uint64_t myz = mz & axis_mask(1, f[1], l[1], by);
      for (int bx = f[0] >> 2; bx <= l[0] >> 2; ++bx) {
        const uint64_t m = myz & axis_mask(0, f[0], l[0], bx);
        if ((g.block(uint32_t(bx), uint32_t(by), uint32_t(bz)) & m) != m) return false;
      }
    }
  }
  return true;
}

}  // namespace

void Grid::mark_box(const Vec3d& lo, const Vec3d& hi) {
  int f[3], l[3];
  const double inv_cell = 1 / cell;  // once for the three axes
  for (int k = 0; k < 3; ++k) {
    if (!cell_range(origin[k], inv_cell, resolution, lo[k], hi[k], f[k], l[k])) return;
    // Exact overlap on this axis: cell i spans [origin + i*cell, origin + (i+1)*cell].
    while (f[k] < l[k] && origin[k] + (f[k] + 1) * cell < lo[k]) ++f[k];
    while (l[k] > f[k] && origin[k] + l[k] * cell > hi[k]) --l[k];
  }
  mark_cells(f, l);
}

void Grid::mark_cells(const int f[3], const int l[3]) {
  // Block by block: a block's cells in the box are the AND of three per-axis masks (bit x + 4y + 16z).
  for (int bz = f[2] >> 2; bz <= l[2] >> 2; ++bz) {
    const uint64_t mz = axis_mask(2, f[2], l[2], bz);
    for (int by = f[1] >> 2; by <= l[1] >> 2; ++by) {
      const uint64_t myz = mz & axis_mask(1, f[1], l[1], by);
      for (int bx = f[0] >> 2; bx <= l[0] >> 2; ++bx)
        or_block(uint32_t(bx), uint32_t(by), uint32_t(bz), myz & axis_mask(0, f[0], l[0], bx));
    }
  }
}

namespace {

// The fast path of voxelize_triangle where the grown bounding box meets one row of cells (runs <= 1
// axes longer than a cell; `longer` the axis, or -1). Returns false when the triangle leaves the row's
// cross section (the caller's tests decide then).
bool set_single_row(Grid& g, const double org[3], double cell, double margin, const double lo[3], const double hi[3],
                    const int f[3], const int l[3], int longer) {
  // The grown bounding box meets one row of cells: when the triangle lies within the grown cross
  // section of that row, it is connected and its projection on the row's axis covers every cell of
  // the row (each within `margin`), so it touches all of them and no other. Most triangles of a
  // scan at the chosen resolution end here.
  bool inside = true;
  for (int k = 0; k < 3; ++k) {
    if (k == longer) continue;
    const double c0 = org[k] + f[k] * cell;
    inside = inside && lo[k] + margin >= c0 - margin && hi[k] - margin <= c0 + cell + margin;
  }
  if (!inside) return false;
  const int k = longer < 0 ? 0 : longer;
  uint32_t c[3] = {uint32_t(f[0]), uint32_t(f[1]), uint32_t(f[2])};
  for (int i = f[k]; i <= l[k]; ++i) {
    c[k] = uint32_t(i);
    g.set(c[0], c[1], c[2]);
  }
  return true;
}

// voxelize_triangle's small boxes: every cell tested by the AVX2 rows kernel, then the cells gathered
// per 4^3 block and each block's bits stored once.
void or_small_box(Grid& g, const detail::CellTests& t, const int f[3], const int l[3]) {
  uint8_t masks[detail::kRowsMaxCells];
  detail::row_masks_avx2(t, masks);
  // The cells gathered per 4^3 block of the box (at most 3 along x: 8 cells from any offset) and
  // each block's bits stored once: a box across block faces was a brick lookup per cell. A row's
  // mask shifted by the box's x offset in its first block holds 4 cells per block, lowest first.
  const int bx0 = f[0] >> 2, by0 = f[1] >> 2, bz0 = f[2] >> 2;
  const int nbx = (l[0] >> 2) - bx0 + 1, nby = (l[1] >> 2) - by0 + 1, nbz = (l[2] >> 2) - bz0 + 1;
  constexpr int kMaxBlocks = 20;  // the most blocks a box of <= 64 cells, <= 8 along x, meets (2 x 2 x 16 at offset 3)
  uint64_t bits[kMaxBlocks];
  const int blocks = nbx * nby * nbz;
  for (int i = 0; i < blocks; ++i) bits[i] = 0;
  for (int z = f[2], r = 0; z <= l[2]; ++z)
    for (int y = f[1]; y <= l[1]; ++y, ++r) {
      const uint32_t m = uint32_t(masks[r]) << (f[0] & 3);
      if (!m) continue;
      const int shift = 4 * (y & 3) + 16 * (z & 3);
      uint64_t* row = bits + nbx * (((y >> 2) - by0) + nby * ((z >> 2) - bz0));
      for (int i = 0; i < nbx; ++i) row[i] |= uint64_t((m >> (4 * i)) & 0xFu) << shift;
    }
  for (int i = 0; i < blocks; ++i)
    if (bits[i]) g.or_block(uint32_t(bx0 + i % nbx), uint32_t(by0 + i / nbx % nby), uint32_t(bz0 + i / (nbx * nby)), bits[i]);
}

// Schwarz & Seidel 2010 §3.1, the projected edge functions per plane (a, b) = (x, y), (y, z), (z, x) of the
// triangle with normal n, edges e and vertices v against boxes of size dp; the orientation follows the normal's
// component on the third axis: edge (p, i) is inside when ex*pa + ey*pb + ed >= 0.
void edge_functions(const double (&n)[3], const double (&e)[3][3], const double (&v)[3][3], double dp, detail::CellTests& t) {
  for (int p = 0; p < 3; ++p) {
    const int a = p, b = p == 2 ? 0 : p + 1, w = p == 0 ? 2 : p - 1;
    const double s = n[w] >= 0 ? 1.0 : -1.0;
    for (int i = 0; i < 3; ++i) {
      const double nx = -e[i][b] * s, ny = e[i][a] * s;
      t.ex[p][i] = nx, t.ey[p][i] = ny;
      t.ed[p][i] = -(nx * v[i][a] + ny * v[i][b]) + std::max(0.0, dp * nx) + std::max(0.0, dp * ny);
    }
  }
}

}  // namespace

// Schwarz & Seidel 2010 §3.1: a triangle overlaps a box (corner p, size dp) iff their bounding boxes
// overlap, the plane separates the box's critical corners, and in each of the xy, yz, zx projections
// the critical corner of the box lies inside every edge function. The box here is the cell grown by
// `margin`, so a triangle within `margin` of a cell sets it. Plain arrays throughout (no per-axis
// branches): the converter runs this once per triangle of every batching point.
void voxelize_triangle(Grid& g, const Vec3d& v0, const Vec3d& v1, const Vec3d& v2, double margin) {
  static const Isa isa = detect_isa();
  voxelize_triangle(g, v0, v1, v2, margin, isa);
}

void voxelize_triangle(Grid& g, const Vec3d& v0, const Vec3d& v1, const Vec3d& v2, double margin, Isa isa) {
  const double v[3][3] = {{v0.x, v0.y, v0.z}, {v1.x, v1.y, v1.z}, {v2.x, v2.y, v2.z}};
  const double org[3] = {g.origin.x, g.origin.y, g.origin.z};
  double lo[3], hi[3], e[3][3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = std::min(v[0][k], std::min(v[1][k], v[2][k])) - margin;
    hi[k] = std::max(v[0][k], std::max(v[1][k], v[2][k])) + margin;
    for (int i = 0; i < 3; ++i) e[i][k] = v[i == 2 ? 0 : i + 1][k] - v[i][k];  // e0 = v1 - v0, e1 = v2 - v1, e2 = v0 - v2
  }
  const double n[3] = {e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
                       e[0][0] * e[1][1] - e[0][1] * e[1][0]};
  if (!(std::isfinite(n[0]) && std::isfinite(n[1]) && std::isfinite(n[2]))) return;  // non-finite: never hit
  if (n[0] == 0 && n[1] == 0 && n[2] == 0) {
    g.mark_box({lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]});  // zero area: the grown bounding box is a superset
    return;
  }
  const double cell = g.cell, inv_cell = 1 / cell;
  int f[3], l[3];
  for (int k = 0; k < 3; ++k)
    if (!cell_range(org[k], inv_cell, g.resolution, lo[k], hi[k], f[k], l[k])) return;
  // Exact ranges (the quotients were padded): cell i spans [origin + i*cell, origin + (i+1)*cell].
  int longer = -1, runs = 0;
  for (int k = 0; k < 3; ++k) {
    while (f[k] < l[k] && org[k] + (f[k] + 1) * cell < lo[k]) ++f[k];
    while (l[k] > f[k] && org[k] + l[k] * cell > hi[k]) --l[k];
    if (l[k] > f[k]) longer = k, ++runs;
  }
  if (runs <= 1 && set_single_row(g, org, cell, margin, lo, hi, f, l, longer)) return;
  // Every cell the triangle could set is set already (neighbouring triangles of a dense mesh share
  // their cells: about a quarter of the bunny's at 128^3): nothing to test.
  if (all_cells_set(g, f, l)) return;
  const double dp = cell + 2 * margin;  // grown cell size; grown corner = origin + i*cell - margin
  // Plane: d1, d2 from the critical point c (dp where n > 0).
  detail::CellTests t;  // the tests' constants, written once for either loop below
  double& d1 = t.d1;
  double& d2 = t.d2;
  d1 = 0, d2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double c = n[k] > 0 ? dp : 0;
    d1 += n[k] * (c - v[0][k]);
    d2 += n[k] * ((dp - c) - v[0][k]);
  }
  edge_functions(n, e, v, dp, t);
  const double(&ex)[3][3] = t.ex;
  const double(&ey)[3][3] = t.ey;
  const double(&ed)[3][3] = t.ed;
  // A small box (FlightHelmet at 128^3: 44k of its 95k triangles, two or three cells a side): every
  // cell tested, four along x per AVX2 register (voxelize_rows_avx2.cpp, the same tests in the same
  // arithmetic as the loop below, so the same cells).
  const int nx = l[0] - f[0] + 1, nyz = (l[1] - f[1] + 1) * (l[2] - f[2] + 1);
  if (isa != Isa::kScalar && nx <= detail::kRowsMaxX && nx * nyz <= detail::kRowsMaxCells) {
    for (int k = 0; k < 3; ++k) {
      t.org[k] = org[k], t.box_lo[k] = lo[k] + margin, t.box_hi[k] = hi[k] - margin, t.n[k] = n[k];
      t.f[k] = f[k], t.l[k] = l[k];
    }
    t.cell = cell, t.margin = margin, t.dp = dp;
    or_small_box(g, t, f, l);
    return;
  }
  // Schwarz & Seidel 2010 §3.1, by columns of the dominant projection: the plane (a, b) whose third
  // axis w is the normal's largest component. A column (a, b) that passes that plane's bounding-box and
  // edge tests holds the triangle's cells in a short run along w, bounded by the plane test; only that
  // run (padded by one cell and the rounding below) is tested, with every test the exhaustive loop over
  // the bounding box makes, in the same arithmetic, so the cells set are the same. A long thin
  // triangle across a 10^3 box tests about its 10^2 cells instead of 10^3.
  int w = 0;
  for (int k = 1; k < 3; ++k)
    if (std::fabs(n[k]) > std::fabs(n[w])) w = k;
  const int P = w == 2 ? 0 : w + 1, a = P, b = P == 2 ? 0 : P + 1;  // plane P = (a, b), third axis w
  const int others[2] = {P == 2 ? 0 : P + 1, P == 0 ? 2 : P - 1};
  // The run along w: cells whose grown corner p has n·p in [-max(d1, d2), -min(d1, d2)] (the plane
  // test), from n·p = n_a p_a + n_b p_b + n_w p_w solved for p_w. Slack: the rounding of both
  // evaluations (relative 2^-52 per operation on magnitudes bounded by `mag`), in p_w units, and one
  // cell more below. Runs of one or two cells are tested as they are.
  const double np_lo = -std::max(d1, d2), np_hi = -std::min(d1, d2), nw = n[w], inv_nw = 1 / nw;
  const double base_w = org[w] - margin;
  const double wmag = std::max(std::fabs(lo[w]), std::fabs(hi[w])) + dp + std::fabs(base_w);
  const bool solve =
      l[w] - f[w] >= 2 && std::fabs(nw) > 1e-150 && std::isfinite(inv_nw) && std::isfinite(np_lo) && std::isfinite(np_hi);
  const bool one_block = (f[0] >> 2) == (l[0] >> 2) && (f[1] >> 2) == (l[1] >> 2) && (f[2] >> 2) == (l[2] >> 2);
  uint64_t bits = 0;  // one 4^3 block: gathered and stored once
  for (int ib = f[b]; ib <= l[b]; ++ib) {
    const double pb = org[b] + ib * cell - margin;
    if (pb > hi[b] - margin || pb + dp < lo[b] + margin) continue;  // bounding boxes (the range is padded)
    for (int ia = f[a]; ia <= l[a]; ++ia) {
      const double pa = org[a] + ia * cell - margin;
      if (pa > hi[a] - margin || pa + dp < lo[a] + margin) continue;
      bool column = true;
      for (int i = 0; i < 3; ++i) column &= ex[P][i] * pa + ey[P][i] * pb + ed[P][i] >= 0;
      if (!column) continue;
      int w0 = f[w], w1 = l[w];
      if (solve) {
        const double k = n[a] * pa + n[b] * pb;
        double t0 = (np_lo - k) * inv_nw, t1 = (np_hi - k) * inv_nw;
        if (t0 > t1) std::swap(t0, t1);
        const double mag =
            (std::fabs(n[a] * pa) + std::fabs(n[b] * pb) + std::fabs(d1) + std::fabs(d2)) * std::fabs(inv_nw) + wmag;
        const double slack = 64 * std::numeric_limits<double>::epsilon() * mag;
        double q0 = (t0 - slack - base_w) * inv_cell - 1, q1 = (t1 + slack - base_w) * inv_cell;
        if (!(q0 >= w0)) q0 = w0;  // also NaN: the whole range
        if (!(q1 <= w1)) q1 = w1;
        if (q0 > q1) continue;
        w0 = int(q0), w1 = int(q1);  // within [f, l], >= 0: truncation is floor
      }
      for (int iw = w0; iw <= w1; ++iw) {
        double pc[3];
        pc[a] = pa, pc[b] = pb, pc[w] = org[w] + iw * cell - margin;
        if (pc[w] > hi[w] - margin || pc[w] + dp < lo[w] + margin) continue;
        const double np = n[0] * pc[0] + n[1] * pc[1] + n[2] * pc[2];
        if ((np + d1) * (np + d2) > 0) continue;
        bool inside = true;
        for (const int p : others) {
          const double qa = pc[p], qb = pc[p == 2 ? 0 : p + 1];
          for (int i = 0; i < 3; ++i) inside &= ex[p][i] * qa + ey[p][i] * qb + ed[p][i] >= 0;
        }
        if (!inside) continue;
        uint32_t c[3];
        c[a] = uint32_t(ia), c[b] = uint32_t(ib), c[w] = uint32_t(iw);
        if (one_block)
          bits |= uint64_t(1) << ((c[0] & 3) + 4 * (c[1] & 3) + 16 * (c[2] & 3));
        else
          g.set(c[0], c[1], c[2]);
      }
    }
  }
  if (bits) g.or_block(uint32_t(f[0]) >> 2, uint32_t(f[1]) >> 2, uint32_t(f[2]) >> 2, bits);
}

void voxelize_triangle_thin(Grid& g, const Vec3d& v0, const Vec3d& v1, const Vec3d& v2) {
  const Vec3d n = cross(v1 - v0, v2 - v1);
  int w = 0;
  for (int k = 1; k < 3; ++k)
    if (std::fabs(n[k]) > std::fabs(n[w])) w = k;
  if (!(n[w] != 0) || !std::isfinite(n[w])) return;
  const int a = (w + 1) % 3, b = (w + 2) % 3;
  int f[3], l[3];
  for (int k = 0; k < 3; ++k)
    if (!cell_range(g, k, std::min({v0[k], v1[k], v2[k]}), std::max({v0[k], v1[k], v2[k]}), f[k], l[k])) return;
  const Vec3d v[3] = {v0, v1, v2};
  for (int j = f[b]; j <= l[b]; ++j)
    for (int i = f[a]; i <= l[a]; ++i) {
      const double pa = g.origin[a] + (i + 0.5) * g.cell, pb = g.origin[b] + (j + 0.5) * g.cell;
      // Column centre inside the projected triangle (same sign for all three 2D edge functions).
      double s[3];
      for (int k = 0; k < 3; ++k) {
        const Vec3d& p = v[k];
        const Vec3d& q = v[(k + 1) % 3];
        s[k] = (q[a] - p[a]) * (pb - p[b]) - (q[b] - p[b]) * (pa - p[a]);
      }
      if (!((s[0] >= 0 && s[1] >= 0 && s[2] >= 0) || (s[0] <= 0 && s[1] <= 0 && s[2] <= 0))) continue;
      const double pw = v0[w] - (n[a] * (pa - v0[a]) + n[b] * (pb - v0[b])) / n[w];
      const double cw = std::floor((pw - g.origin[w]) / g.cell);
      if (!(cw >= 0 && cw < g.resolution)) continue;
      uint32_t c[3];
      c[a] = uint32_t(i), c[b] = uint32_t(j), c[w] = uint32_t(cw);
      g.set(c[0], c[1], c[2]);
    }
}

}  // namespace rtp::voxel
