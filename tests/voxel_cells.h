#pragma once
// Walking the set cells of a voxel grid (the lib/voxel unit tests: test_voxel_instances.cpp,
// test_voxel_spans.cpp).
#include <bit>
#include <cstdint>

#include "voxel/voxel.h"

namespace rtp::test {

// Every set cell of a grid, as (x, y, z), block by block.
template <class F>
void for_each_cell(const voxel::Grid& g, F&& f) {
  const uint32_t nb = g.blocks_per_axis();
  for (uint32_t bz = 0; bz < nb; ++bz)
    for (uint32_t by = 0; by < nb; ++by)
      for (uint32_t bx = 0; bx < nb; ++bx)
        for (uint64_t m = g.block(bx, by, bz); m; m &= m - 1) {
          const uint32_t b = uint32_t(std::countr_zero(m));
          f(4 * bx + (b & 3), 4 * by + (b >> 2 & 3), 4 * bz + (b >> 4));
        }
}

}  // namespace rtp::test
