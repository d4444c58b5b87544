// Triangle voxelization into a dense block grid: conservative (26-separating) as Schwarz & Seidel
// 2010 §3.1 define it, and thin (6-separating) as a test foil.
#include <algorithm>
#include <bit>
#include <cmath>

#include "voxel/voxel.h"

namespace rtp::voxel {

Grid::Grid(const Vec3d& origin_, double cell_, uint32_t resolution_)
    : origin(origin_), cell(cell_), resolution(resolution_) {
  const uint32_t nb = resolution / 4;
  edge_ = std::min<uint32_t>(8, nb);
  shift_ = uint32_t(std::countr_zero(edge_));
  bricks_ = nb / edge_;
  brick_blocks_ = size_t(edge_) * edge_ * edge_;
  brick_.assign(size_t(bricks_) * bricks_ * bricks_, 0);
}

uint64_t& Grid::block_ref(uint32_t bx, uint32_t by, uint32_t bz) {
  uint32_t& b = brick_[brick_index(bx, by, bz)];
  if (!b) {
    store_.resize(store_.size() + brick_blocks_, 0);
    b = uint32_t(store_.size() / brick_blocks_);
  }
  return store_[size_t(b - 1) * brick_blocks_ + local_index(bx, by, bz)];
}

uint64_t Grid::count() const {
  uint64_t n = 0;
  for (uint64_t b : store_) n += uint64_t(std::popcount(b));
  return n;
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
bool cell_range(const Grid& g, int axis, double lo, double hi, int& first, int& last) {
  // The quotients are rounded (relative 2^-53 each): pad by one cell only when one lies within 1e-9
  // (relative) of a cell plane; the exact tests decide. Most small triangles then test 1-8 cells, not 27.
  const double qa = (lo - g.origin[axis]) / g.cell, qb = (hi - g.origin[axis]) / g.cell;
  const double pa = 1e-9 * (std::fabs(qa) + 1), pb = 1e-9 * (std::fabs(qb) + 1);
  const double a = std::floor(qa - pa), b = std::floor(qb + pb);
  // A closed box touching the grid's upper face (qa == R) or lower face (qb == 0) still reaches the
  // boundary cell: the padding makes a == R - 1 or b == 0 there.
  if (!(b >= 0) || !(a <= double(g.resolution) - 1)) return false;  // also NaN
  first = int(std::max(a, 0.0));
  last = int(std::min(b, double(g.resolution) - 1));
  return first <= last;
}

}  // namespace

void Grid::mark_box(const Vec3d& lo, const Vec3d& hi) {
  int f[3], l[3];
  for (int k = 0; k < 3; ++k) {
    if (!cell_range(*this, k, lo[k], hi[k], f[k], l[k])) return;
    // Exact overlap on this axis: cell i spans [origin + i*cell, origin + (i+1)*cell].
    while (f[k] < l[k] && origin[k] + (f[k] + 1) * cell < lo[k]) ++f[k];
    while (l[k] > f[k] && origin[k] + l[k] * cell > hi[k]) --l[k];
  }
  for (int z = f[2]; z <= l[2]; ++z)
    for (int y = f[1]; y <= l[1]; ++y)
      for (int x = f[0]; x <= l[0]; ++x) set(uint32_t(x), uint32_t(y), uint32_t(z));
}

// Schwarz & Seidel 2010 §3.1: a triangle overlaps a box (corner p, size dp) iff their bounding boxes
// overlap, the plane separates the box's critical corners, and in each of the xy, yz, zx projections
// the critical corner of the box lies inside every edge function. The box here is the cell grown by
// `margin`, so a triangle within `margin` of a cell sets it.
void voxelize_triangle(Grid& g, const Vec3d& v0, const Vec3d& v1, const Vec3d& v2, double margin) {
  Vec3d lo, hi;
  for (int k = 0; k < 3; ++k) {
    lo[k] = std::min({v0[k], v1[k], v2[k]}) - margin;
    hi[k] = std::max({v0[k], v1[k], v2[k]}) + margin;
  }
  const Vec3d e0 = v1 - v0, e1 = v2 - v1, e2 = v0 - v2;
  const Vec3d n = cross(e0, e1);
  if (!(std::isfinite(n.x) && std::isfinite(n.y) && std::isfinite(n.z))) return;  // non-finite: never hit
  if (n.x == 0 && n.y == 0 && n.z == 0) {
    g.mark_box(lo, hi);  // zero area: the grown bounding box is a superset
    return;
  }
  int f[3], l[3];
  for (int k = 0; k < 3; ++k)
    if (!cell_range(g, k, lo[k], hi[k], f[k], l[k])) return;
  if (f[0] == l[0] && f[1] == l[1] && f[2] == l[2]) {
    // The grown bounding box meets one cell only: the triangle lies in the grid and touches no other
    // cell, so it touches this one (most triangles of a scan at the chosen resolution).
    bool inside = true;
    for (int k = 0; k < 3; ++k) {
      const double c0 = g.origin[k] + f[k] * g.cell;
      inside = inside && lo[k] + margin >= c0 - margin && hi[k] - margin <= c0 + g.cell + margin;
    }
    if (inside) {
      g.set(uint32_t(f[0]), uint32_t(f[1]), uint32_t(f[2]));
      return;
    }
  }
  const double dp = g.cell + 2 * margin;  // grown cell size; grown corner = origin + i*cell - margin
  // Plane: d1, d2 from the critical point c (dp where n > 0).
  Vec3d c{n.x > 0 ? dp : 0, n.y > 0 ? dp : 0, n.z > 0 ? dp : 0};
  const double d1 = dot(n, c - v0), d2 = dot(n, Vec3d{dp, dp, dp} - c - v0);
  // Projected edge functions per plane (a, b) = (x, y), (y, z), (z, x); the orientation follows the
  // normal's component on the third axis.
  struct Edge { double nx, ny, d; };
  Edge ed[3][3];
  const Vec3d e[3] = {e0, e1, e2}, v[3] = {v0, v1, v2};
  const int ax[3][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}};
  for (int p = 0; p < 3; ++p) {
    const int a = ax[p][0], b = ax[p][1], w = ax[p][2];
    const double s = n[w] >= 0 ? 1.0 : -1.0;
    for (int i = 0; i < 3; ++i) {
      const double nx = -e[i][b] * s, ny = e[i][a] * s;
      ed[p][i] = {nx, ny, -(nx * v[i][a] + ny * v[i][b]) + std::max(0.0, dp * nx) + std::max(0.0, dp * ny)};
    }
  }
  for (int z = f[2]; z <= l[2]; ++z) {
    const double pz = g.origin.z + z * g.cell - margin;
    for (int y = f[1]; y <= l[1]; ++y) {
      const double py = g.origin.y + y * g.cell - margin;
      for (int x = f[0]; x <= l[0]; ++x) {
        const double px = g.origin.x + x * g.cell - margin;
        const Vec3d p{px, py, pz};
        // Bounding boxes (the cell range is padded by one cell).
        if (px > hi.x - margin || px + dp < lo.x + margin || py > hi.y - margin || py + dp < lo.y + margin ||
            pz > hi.z - margin || pz + dp < lo.z + margin)
          continue;
        const double np = dot(n, p);
        if ((np + d1) * (np + d2) > 0) continue;
        bool inside = true;
        for (int q = 0; q < 3 && inside; ++q) {
          const double pa = p[ax[q][0]], pb = p[ax[q][1]];
          for (int i = 0; i < 3 && inside; ++i) inside = ed[q][i].nx * pa + ed[q][i].ny * pb + ed[q][i].d >= 0;
        }
        if (inside) g.set(uint32_t(x), uint32_t(y), uint32_t(z));
      }
    }
  }
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
