#include "reader/tile_order.h"

#include <algorithm>
#include <utility>

namespace rtp {

// Wu 2016 §3.4.1: primary rays generated from pixels in Hilbert curve order (after Zhang et al.): each
// level picks the quadrant, then turns (x, y) so the quadrant's sub-curve is the standard one.
uint64_t hilbert_index(uint32_t n, uint32_t x, uint32_t y) {
  uint64_t d = 0;
  for (uint32_t s = n / 2; s > 0; s /= 2) {
    const uint32_t rx = (x & s) ? 1u : 0u, ry = (y & s) ? 1u : 0u;
    d += uint64_t(s) * s * ((3u * rx) ^ ry);
    if (ry == 0) {
      if (rx == 1) x = n - 1 - x, y = n - 1 - y;
      std::swap(x, y);
    }
  }
  return d;
}

std::vector<uint32_t> hilbert_tile_order(int width, int height) {
  std::vector<uint32_t> order;
  if (width <= 0 || height <= 0) return order;
  const uint32_t w = uint32_t(width), h = uint32_t(height);
  const uint32_t tiles_x = (w + kTileSide - 1) / kTileSide, tiles_y = (h + kTileSide - 1) / kTileSide;
  uint32_t n = 1;
  while (n < tiles_x || n < tiles_y) n *= 2;
  // The tiles sorted by their place on the curve over the smallest power-of-two grid that holds them.
  std::vector<std::pair<uint64_t, uint32_t>> tiles;
  tiles.reserve(size_t(tiles_x) * tiles_y);
  for (uint32_t ty = 0; ty < tiles_y; ++ty)
    for (uint32_t tx = 0; tx < tiles_x; ++tx) tiles.push_back({hilbert_index(n, tx, ty), ty * tiles_x + tx});
  std::sort(tiles.begin(), tiles.end());
  // Whole tiles first, then the tiles the right or bottom edge cuts (each in curve order): a cut tile has
  // fewer than 16 pixels, so one in the middle would shift every later tile off the multiples of 16 that
  // packets of 4, 8 and 16 start at (a 1366x768 image: every tile after the first right-edge tile).
  std::stable_partition(tiles.begin(), tiles.end(), [&](const std::pair<uint64_t, uint32_t>& t) {
    return (t.second % tiles_x + 1) * kTileSide <= w && (t.second / tiles_x + 1) * kTileSide <= h;
  });
  // Within a tile: the 4x4 curve, as (x, y) offsets by position.
  uint32_t cell[kTileSide * kTileSide];
  for (uint32_t y = 0; y < kTileSide; ++y)
    for (uint32_t x = 0; x < kTileSide; ++x) cell[hilbert_index(kTileSide, x, y)] = y * kTileSide + x;
  order.reserve(size_t(w) * h);
  for (const auto& t : tiles) {
    const uint32_t x0 = (t.second % tiles_x) * kTileSide, y0 = (t.second / tiles_x) * kTileSide;
    for (uint32_t c : cell) {
      const uint32_t x = x0 + c % kTileSide, y = y0 + c / kTileSide;
      if (x < w && y < h) order.push_back(y * w + x);
    }
  }
  return order;
}

}  // namespace rtp
