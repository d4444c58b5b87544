// Decoding a DAG back into a grid, and the brute-force ray/grid reference (tests, inspection).
#include <bit>
#include <cmath>
#include <limits>
#include <vector>

#include "voxel/voxel.h"

namespace rtp::voxel {
namespace {

constexpr double kInfD = std::numeric_limits<double>::infinity();
int grid_levels(uint32_t resolution) { return std::countr_zero(resolution / 4); }

}  // namespace

Grid decode_dag(const fmt::DagGrid& g, const DagView& v) {
  Grid out({g.origin[0], g.origin[1], g.origin[2]}, g.cell, g.resolution);
  if (g.root == fmt::kDagEmpty) return out;
  const uint32_t nb = out.blocks_per_axis();
  auto fill = [&](uint32_t bx, uint32_t by, uint32_t bz, uint32_t size, uint64_t mask) {
    for (uint32_t z = bz; z < bz + size; ++z)
      for (uint32_t y = by; y < by + size; ++y)
        for (uint32_t x = bx; x < bx + size; ++x) out.set_block(x, y, z, mask);
  };
  if (g.root == fmt::kDagFull) {
    fill(0, 0, 0, nb, ~uint64_t(0));
    return out;
  }
  struct Item {
    uint32_t ref;
    int level;
    uint32_t x, y, z;
  };  // block coordinates of the corner
  std::vector<Item> pending{{g.root, grid_levels(g.resolution), 0, 0, 0}};
  while (!pending.empty()) {
    const Item it = pending.back();
    pending.pop_back();
    if (it.level == 0) {
      fill(it.x, it.y, it.z, 1, v.leaves[it.ref]);
      continue;
    }
    const uint32_t head = v.words[it.ref], cm = fmt::dag_child_mask(head), fm = fmt::dag_full_mask(head);
    const uint32_t im = fmt::dag_inline_mask(head), half = 1u << (it.level - 1);
    for (uint32_t c = 0; c < 8; ++c) {
      if (!(cm >> c & 1)) continue;
      const uint32_t x = it.x + (c & 1) * half, y = it.y + ((c >> 1) & 1) * half, z = it.z + (c >> 2) * half;
      const uint32_t* w = v.words + it.ref + 1 + fmt::dag_child_slot(head, c);
      if (fm >> c & 1)
        fill(x, y, z, half, ~uint64_t(0));
      else if (im >> c & 1)
        fill(x, y, z, 1, w[0] | uint64_t(w[1]) << 32);
      else
        pending.push_back({w[0], it.level - 1, x, y, z});
    }
  }
  return out;
}

DagHit grid_first_entry_reference(const Grid& g, double delta, const double org[3], const double dir[3], double tnear,
                                  double tfar) {
  DagHit out;
  double best = kInfD;
  for (uint32_t z = 0; z < g.resolution; ++z)
    for (uint32_t y = 0; y < g.resolution; ++y)
      for (uint32_t x = 0; x < g.resolution; ++x) {
        if (!g.get(x, y, z)) continue;
        double t0 = tnear, t1 = tfar;
        bool hit = true;
        const uint32_t c[3] = {x, y, z};
        for (int k = 0; k < 3 && hit; ++k) {
          const double lo = g.origin[k] + double(c[k]) * g.cell - delta, hi = g.origin[k] + double(c[k] + 1) * g.cell + delta;
          if (dir[k] == 0) {
            hit = org[k] >= lo && org[k] <= hi;
            continue;
          }
          const double a = (lo - org[k]) / dir[k], b = (hi - org[k]) / dir[k];
          t0 = std::max(t0, std::min(a, b));
          t1 = std::min(t1, std::max(a, b));
        }
        if (hit && t0 <= t1) best = std::min(best, t0);
      }
  if (best < kInfD) out = {false, best};
  return out;
}

}  // namespace rtp::voxel
