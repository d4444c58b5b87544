// rtpack-inspect --verify: every triangle of a batching point lies in set cells of its voxel grid
// (formats/SPEC.md §4.5), walked from the DAG's root with an independent triangle/box test.
#include "inspect/dag_coverage.h"

#include <algorithm>
#include <bit>
#include <cmath>

#include "core/math.h"

namespace rtp {
namespace {

// The shrink of every cell box: a quarter of the grid's margin, in cells.
double cell_shrink(const fmt::DagGrid& grid) { return 0.25 * double(grid.margin) / double(grid.cell); }

// A world-space box in grid units: covered when every cell it meets is set (enough for all it contains).
struct BoxShape {
  double lo[3], hi[3], eps;
  bool meets(const double clo[3], double size) const {
    for (int a = 0; a < 3; ++a)
      if (lo[a] > clo[a] + size - eps || hi[a] < clo[a] + eps) return false;
    return true;
  }
  // The 4x4x4 block at clo: every cell the box meets set in `mask`. Bit x + 4y + 16z (formats/dag.h).
  bool leaf_covered(uint64_t mask, const double clo[3]) const {
    int first[3], last[3];
    for (int a = 0; a < 3; ++a) {
      first[a] = std::max(0, int(std::floor(lo[a] - clo[a] + eps)));
      last[a] = std::min(3, int(std::ceil(hi[a] - clo[a] - eps)) - 1);
      if (first[a] > last[a]) return true;
    }
    uint64_t row = 0;  // cells first[0]..last[0] of one row
    for (int x = first[0]; x <= last[0]; ++x) row |= uint64_t(1) << x;
    for (int z = first[2]; z <= last[2]; ++z)
      for (int y = first[1]; y <= last[1]; ++y) {
        const uint64_t need = row << (4 * y + 16 * z);
        if ((mask & need) != need) return false;
      }
    return true;
  }
};

// One triangle in grid units (cell (0,0,0) is [0,1]^3).
struct TriShape {
  double v[3][3];
  BoxShape box;  // the triangle's bounds
  // Akenine-Möller 2001, "Fast 3D Triangle-Box Overlap Testing" §3: the 13 separating axes (box normals,
  // triangle normal, the 9 edge x axis products), for the box [clo + eps, clo + size - eps]^3.
  bool meets(const double clo[3], double size) const {
    if (!box.meets(clo, size)) return false;  // box normals
    const double h = 0.5 * size - box.eps;
    double c[3], p[3][3], e[3][3];
    for (int a = 0; a < 3; ++a) c[a] = clo[a] + 0.5 * size;
    for (int i = 0; i < 3; ++i)
      for (int a = 0; a < 3; ++a) p[i][a] = v[i][a] - c[a];
    for (int a = 0; a < 3; ++a) e[0][a] = p[1][a] - p[0][a], e[1][a] = p[2][a] - p[1][a], e[2][a] = p[0][a] - p[2][a];
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) {
        double axis[3] = {0, 0, 0};  // e_j x unit axis k
        const int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
        axis[k1] = e[j][k2];
        axis[k2] = -e[j][k1];
        double pmin = INFINITY, pmax = -INFINITY;
        for (int i = 0; i < 3; ++i) {
          const double d = axis[0] * p[i][0] + axis[1] * p[i][1] + axis[2] * p[i][2];
          pmin = std::min(pmin, d), pmax = std::max(pmax, d);
        }
        const double r = h * (std::fabs(axis[0]) + std::fabs(axis[1]) + std::fabs(axis[2]));
        if (pmin > r || pmax < -r) return false;
      }
    const double n[3] = {e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
                         e[0][0] * e[1][1] - e[0][1] * e[1][0]};
    const double r = h * (std::fabs(n[0]) + std::fabs(n[1]) + std::fabs(n[2]));
    return std::fabs(n[0] * p[0][0] + n[1] * p[0][1] + n[2] * p[0][2]) <= r;  // the triangle's plane
  }
  // Only the block's unset cells need the exact test.
  bool leaf_covered(uint64_t mask, const double clo[3]) const {
    if (box.leaf_covered(mask, clo)) return true;
    for (int z = 0; z < 4; ++z)
      for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x) {
          const double cell[3] = {clo[0] + x, clo[1] + y, clo[2] + z};
          if (!(mask >> (x + 4 * y + 16 * z) & 1) && meets(cell, 1.0)) return false;
        }
    return true;
  }
};

// The node (or leaf, level 0) `ref` covering [lo, lo + 4·2^level)^3: every cell of it the shape meets is set.
template <class Shape>
bool node_covers(const voxel::DagView& pool, const Shape& s, uint32_t ref, int level, const double lo[3]) {
  if (ref == fmt::kDagFull) return true;
  if (ref == fmt::kDagEmpty) return false;
  if (level == 0) return s.leaf_covered(pool.leaves[ref], lo);
  const uint32_t word = pool.words[ref];
  const double half = double(2u << level);
  for (uint32_t c = 0; c < 8; ++c) {
    const double clo[3] = {lo[0] + half * (c & 1), lo[1] + half * (c >> 1 & 1), lo[2] + half * (c >> 2)};
    if (fmt::dag_full_mask(word) >> c & 1 || !s.meets(clo, half)) continue;
    if (!(fmt::dag_child_mask(word) >> c & 1)) return false;
    const uint64_t slot = uint64_t(ref) + 1 + fmt::dag_child_slot(word, c);
    if (fmt::dag_inline_mask(word) >> c & 1) {
      if (!s.leaf_covered(uint64_t(pool.words[slot]) | uint64_t(pool.words[slot + 1]) << 32, clo)) return false;
    } else if (!node_covers(pool, s, pool.words[slot], level - 1, clo)) {
      return false;
    }
  }
  return true;
}

// The shape (grid units) inside the grid and every cell it meets set.
template <class Shape>
bool grid_covers(const fmt::DagGrid& grid, const voxel::DagView& pool, const Shape& s, const BoxShape& bounds) {
  const double r = grid.resolution;
  for (int a = 0; a < 3; ++a)
    if (bounds.lo[a] < -bounds.eps || bounds.hi[a] > r + bounds.eps) return false;  // reaches outside the grid
  const double lo[3] = {0, 0, 0};
  return node_covers(pool, s, grid.root, std::countr_zero(grid.resolution) - 2, lo);
}

// Local -> grid units: g = A·v + b, A = L / cell, b = (T - origin) / cell (SPEC §4.5: Minv = [L | T]).
struct ToGrid {
  double a[9], b[3], eps;
  ToGrid(const fmt::DagGrid& grid, const double l[9], const double t[3]) : eps(cell_shrink(grid)) {
    for (int k = 0; k < 9; ++k) a[k] = l[k] / double(grid.cell);
    for (int r = 0; r < 3; ++r) b[r] = (t[r] - double(grid.origin[r])) / double(grid.cell);
  }
  void point(const float v[3], double g[3]) const {
    for (int r = 0; r < 3; ++r) g[r] = a[3 * r] * v[0] + a[3 * r + 1] * v[1] + a[3 * r + 2] * v[2] + b[r];
  }
  // A triangle (9 floats); false when a coordinate is not finite (never hit).
  bool triangle(const float* xyz, TriShape& t) const {
    t.box = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}, eps};
    for (int i = 0; i < 3; ++i) {
      point(xyz + 3 * i, t.v[i]);
      for (int k = 0; k < 3; ++k) {
        if (!std::isfinite(t.v[i][k])) return false;
        t.box.lo[k] = std::min(t.box.lo[k], t.v[i][k]), t.box.hi[k] = std::max(t.box.hi[k], t.v[i][k]);
      }
    }
    return true;
  }
  // The bounds of a local box's image (its eight corners).
  BoxShape box(const float lo[3], const float hi[3]) const {
    BoxShape out{{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}, eps};
    for (int c = 0; c < 8; ++c) {
      const float v[3] = {c & 1 ? hi[0] : lo[0], c & 2 ? hi[1] : lo[1], c & 4 ? hi[2] : lo[2]};
      double g[3];
      point(v, g);
      for (int k = 0; k < 3; ++k) out.lo[k] = std::min(out.lo[k], g[k]), out.hi[k] = std::max(out.hi[k], g[k]);
    }
    return out;
  }
};

}  // namespace

bool dag_covers_triangle(const fmt::DagGrid& grid, const voxel::DagView& pool, const double tri[3][3]) {
  const double identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, zero[3] = {0, 0, 0};
  const ToGrid to(grid, identity, zero);
  TriShape t;
  t.box = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}, to.eps};
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) {
      t.v[i][k] = (tri[i][k] - double(grid.origin[k])) / double(grid.cell);
      if (!std::isfinite(t.v[i][k])) return true;  // never hit
      t.box.lo[k] = std::min(t.box.lo[k], t.v[i][k]), t.box.hi[k] = std::max(t.box.hi[k], t.v[i][k]);
    }
  return grid_covers(grid, pool, t.box, t.box) || grid_covers(grid, pool, t, t.box);
}

template <int B>
void append_triangles(const fmt::LeafBlock<B>* blocks, uint64_t count, MeshTriangles& out) {
  for (uint64_t b = 0; b < count; ++b)
    for (int l = 0; l < B; ++l) {
      for (const auto* v : {blocks[b].v0, blocks[b].v1, blocks[b].v2})
        for (int a = 0; a < 3; ++a) out.xyz.push_back(v[a][l]);
      out.prim.push_back(blocks[b].prim[l]);
    }
  out.group_box.clear();  // the bounds of every kGroup triangles (non-finite coordinates skipped)
  for (size_t first = 0; first < out.prim.size(); first += MeshTriangles::kGroup) {
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t k = 9 * first; k < std::min(out.xyz.size(), 9 * (first + MeshTriangles::kGroup)); ++k)
      if (std::isfinite(out.xyz[k])) lo[k % 3] = std::min(lo[k % 3], out.xyz[k]), hi[k % 3] = std::max(hi[k % 3], out.xyz[k]);
    out.group_box.insert(out.group_box.end(), {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]});
  }
}
template void append_triangles<4>(const fmt::LeafBlock<4>*, uint64_t, MeshTriangles&);
template void append_triangles<8>(const fmt::LeafBlock<8>*, uint64_t, MeshTriangles&);
template void append_triangles<16>(const fmt::LeafBlock<16>*, uint64_t, MeshTriangles&);

std::string point_coverage_problem(const fmt::DagGrid& grid, const voxel::DagView& pool, const fmt::InstanceRecord* records,
                                   uint64_t n_records, const uint32_t* slots, uint64_t n_slots,
                                   const std::vector<MeshTriangles>& pieces, const std::map<uint32_t, MeshTriangles>& meshes) {
  if (grid.resolution == fmt::kDagBoxes) return {};
  for (uint64_t k = 0; k < n_records; ++k) {
    const fmt::InstanceRecord& rec = records[k];
    if (rec.mesh >= n_slots) continue;  // decode_point refuses it
    const uint32_t slot = slots[rec.mesh];
    const MeshTriangles* tris = nullptr;
    std::string what;
    if (slot & fmt::kPieceBit) {
      const uint32_t entry = slot & ~fmt::kPieceBit;
      if (entry < pieces.size()) tris = &pieces[entry];
      what = "piece entry " + std::to_string(entry);
    } else if (const auto it = meshes.find(slot); it != meshes.end()) {
      tris = &it->second;
      what = "mesh " + std::to_string(slot);
    }
    double l[9];  // SPEC §4.5: the voxelizer places v by Minv = [L | T], L the inverse of the stored L^-1
    if (!tris || !inverse3_of(rec.inverse_linear, l)) continue;  // singular: never hit
    const ToGrid to(grid, l, rec.translation);
    // Hierarchically: when every cell a group's bounds meet is set, so is every cell each of its triangles
    // meets. 64 triangles (their local bounds placed), then 8 (their placed vertices), then each alone by
    // its bounds and exactly.
    TriShape sub[8];
    bool finite[8];
    for (size_t g = 0; g * MeshTriangles::kGroup < tris->prim.size(); ++g) {
      const float* gb = &tris->group_box[6 * g];
      if (!(gb[0] <= gb[3]) || grid_covers(grid, pool, to.box(gb, gb + 3), to.box(gb, gb + 3))) continue;
      const size_t end = std::min(tris->prim.size(), (g + 1) * MeshTriangles::kGroup);
      for (size_t first = g * MeshTriangles::kGroup; first < end; first += 8) {
        const size_t n = std::min<size_t>(8, end - first);
        BoxShape bounds{{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}, to.eps};
        for (size_t t = 0; t < n; ++t) {
          finite[t] = to.triangle(&tris->xyz[9 * (first + t)], sub[t]);
          if (!finite[t]) continue;
          for (int k = 0; k < 3; ++k)
            bounds.lo[k] = std::min(bounds.lo[k], sub[t].box.lo[k]), bounds.hi[k] = std::max(bounds.hi[k], sub[t].box.hi[k]);
        }
        if (grid_covers(grid, pool, bounds, bounds)) continue;
        for (size_t t = 0; t < n; ++t)
          if (finite[t] && !grid_covers(grid, pool, sub[t].box, sub[t].box) && !grid_covers(grid, pool, sub[t], sub[t].box))
            return "local instance " + std::to_string(k) + " (" + what + "): triangle " + std::to_string(tris->prim[first + t]) +
                   " meets cells its voxel grid does not set (culling would drop its hits)";
      }
    }
  }
  return {};
}

}  // namespace rtp
