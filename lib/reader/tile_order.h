#pragma once
// The order an image's primary rays are traced in: 4x4 pixel tiles along a Hilbert curve, and the
// pixels of a tile along the 4x4 Hilbert curve, so any run of 4, 8 or 16 consecutive rays of an aligned
// tile is a 2x2, 2x4 or 4x4 block of pixels (a tight packet), and consecutive packets are neighbours.
#include <cstdint>
#include <vector>

namespace rtp {

inline constexpr int kTileSide = 4;  // pixels per tile side: 16 rays, the largest packet

// The position of cell (x, y) along the Hilbert curve over an n x n grid, n a power of two, x, y < n;
// consecutive positions are cells that share a side.
uint64_t hilbert_index(uint32_t n, uint32_t x, uint32_t y);

// Pixel indices (y * width + x, row-major as camera rays are) in tracing order: every pixel once. Whole
// tiles come first, so every run of 4, 8, 16 from a multiple of its length within them is a 2x2, 2x4 or 4x4
// block; then the tiles cut by the right or bottom edge, each with its pixels inside the image in the same
// order. width, height > 0.
std::vector<uint32_t> hilbert_tile_order(int width, int height);

}  // namespace rtp
