#pragma once
// Occlusion-culling proxies (Molenaar 2019 §3.2–3.3, §4.2): conservative voxel grids of batching
// points, sparse voxel DAGs in one shared pool, and the interval-clipped ray/DAG test.
#include <cstdint>
#include <string>
#include <vector>

#include "core/math.h"
#include "formats/dag.h"
#include "voxel/hash_index.h"
#include "core/isa.h"
#include "layout/dag_query.h"  // DagView, DagHit, check_dag(s), dag_first_entry

namespace rtp::voxel {

// A cubic grid of R^3 cells (R a power of two >= 4) in 4x4x4 blocks of one uint64 each (bit
// x + 4y + 16z), stored sparsely: bricks of 8^3 blocks (32^3 cells) are allocated when first written,
// so memory and time follow the cells a batching point's geometry touches, not R^3 (a 512^3 grid of a
// few trees costs a few bricks, not 16 MiB).
class Grid {
 public:
  Vec3d origin;
  double cell = 1;
  uint32_t resolution = 4;

  Grid() = default;
  Grid(const Vec3d& origin_, double cell_, uint32_t resolution_);
  uint32_t blocks_per_axis() const { return resolution / 4; }
  uint64_t block(uint32_t bx, uint32_t by, uint32_t bz) const {
    const uint32_t b = brick_[brick_index(bx, by, bz)];
    return b ? store_[size_t(b - 1) * brick_blocks_ + local_index(bx, by, bz)] : 0;
  }
  // The 2x2x2 blocks at (bx, by, bz) + (c & 1, c >> 1 & 1, c >> 2) in out[c], for even bx, by, bz:
  // one brick lookup for the eight (a brick's edge is even when the grid has more than one block).
  void block_octet(uint32_t bx, uint32_t by, uint32_t bz, uint64_t out[8]) const {
    if (edge_ < 2) {
      for (uint32_t c = 0; c < 8; ++c) out[c] = block(bx + (c & 1), by + (c >> 1 & 1), bz + (c >> 2));
      return;
    }
    const uint32_t b = brick_[brick_index(bx, by, bz)];
    if (!b) {
      for (uint32_t c = 0; c < 8; ++c) out[c] = 0;
      return;
    }
    const uint64_t* p = store_.data() + size_t(b - 1) * brick_blocks_ + local_index(bx, by, bz);
    const size_t e = edge_, e2 = size_t(edge_) * edge_;
    out[0] = p[0], out[1] = p[1], out[2] = p[e], out[3] = p[e + 1];
    out[4] = p[e2], out[5] = p[e2 + 1], out[6] = p[e2 + e], out[7] = p[e2 + e + 1];
  }
  void set_block(uint32_t bx, uint32_t by, uint32_t bz, uint64_t mask) {
    if (mask || brick_[brick_index(bx, by, bz)]) block_ref(bx, by, bz) = mask;
  }
  bool get(uint32_t x, uint32_t y, uint32_t z) const {
    return (block(x >> 2, y >> 2, z >> 2) >> ((x & 3) + 4 * (y & 3) + 16 * (z & 3))) & 1u;
  }
  void set(uint32_t x, uint32_t y, uint32_t z) {
    block_ref(x >> 2, y >> 2, z >> 2) |= uint64_t(1) << ((x & 3) + 4 * (y & 3) + 16 * (z & 3));
  }
  void or_block(uint32_t bx, uint32_t by, uint32_t bz, uint64_t mask) { block_ref(bx, by, bz) |= mask; }
  uint64_t count() const;
  // True when no brick overlapping the block region [b, b + size)^3 is allocated (then it is empty).
  bool region_empty(uint32_t bx, uint32_t by, uint32_t bz, uint32_t size) const;
  // Every block, x fastest ((R/4)^3 entries; tests and small grids only).
  std::vector<uint64_t> dense() const;
  uint64_t allocated_bytes() const { return store_.size() * 8; }
  // Every cell overlapping the closed box [lo, hi] (clamped to the grid).
  void mark_box(const Vec3d& lo, const Vec3d& hi);
  // Every cell (x, y, z) with first[k] <= its k-th index <= last[k] (inside the grid, first <= last).
  void mark_cells(const int first[3], const int last[3]);
  // Sets every cell set in `other`, a grid of the same origin, cell and resolution.
  void merge(const Grid& other);

 private:
  size_t brick_index(uint32_t bx, uint32_t by, uint32_t bz) const {
    return (bx >> shift_) + bricks_ * ((by >> shift_) + size_t(bricks_) * (bz >> shift_));
  }
  size_t local_index(uint32_t bx, uint32_t by, uint32_t bz) const {
    const uint32_t m = edge_ - 1;
    return (bx & m) + edge_ * ((by & m) + size_t(edge_) * (bz & m));
  }
  uint64_t& block_ref(uint32_t bx, uint32_t by, uint32_t bz) {
    uint32_t& b = brick_[brick_index(bx, by, bz)];
    if (!b) [[unlikely]]
      allocate_brick(b);
    return store_[size_t(b - 1) * brick_blocks_ + local_index(bx, by, bz)];
  }
  void allocate_brick(uint32_t& slot);          // a zeroed brick for an absent one
  uint32_t edge_ = 1, shift_ = 0, bricks_ = 1;  // blocks per brick edge (min(8, R/4)), log2, bricks per axis
  size_t brick_blocks_ = 1;
  std::vector<uint32_t> brick_{0};  // per brick: 0 = absent, else 1 + its slot in store_
  std::vector<uint64_t> store_;
};

// Conservative (26-separating) voxelization, Schwarz & Seidel 2010 §3.1 (Molenaar 2019 §4.2): sets
// every cell whose box, grown by `margin` on every side, touches the triangle (plane test and the
// three projected edge tests with critical points), in double precision. A triangle of zero area
// sets every cell its grown bounding box overlaps.
// Small boxes of cells are tested with AVX2 where the CPU has it (same cells: tests compare the ISAs).
void voxelize_triangle(Grid& grid, const Vec3d& a, const Vec3d& b, const Vec3d& c, double margin);
void voxelize_triangle(Grid& grid, const Vec3d& a, const Vec3d& b, const Vec3d& c, double margin, Isa isa);
// Thin (6-separating) voxelization, only a test foil: along the dominant normal axis, the cell
// holding the plane at each covered column centre. Leaves gaps that rays can pass through.
void voxelize_triangle_thin(Grid& grid, const Vec3d& a, const Vec3d& b, const Vec3d& c);

// A sparse voxel DAG of one grid before it joins the pool: nodes deduplicated by (level, words).
struct LocalDag {
  std::vector<uint32_t> words;         // formats/dag.h node layout, children before parents
  std::vector<uint32_t> node_offsets;  // start of each node in `words`, creation order
  std::vector<uint8_t> node_levels;    // its level (>= 1)
  std::vector<uint64_t> leaves;        // unique leaf masks
  uint32_t root = fmt::kDagEmpty;      // at level log2(R / 4): a leaf index (R = 4), a word offset, or kDagEmpty/kDagFull
  uint64_t bytes() const { return words.size() * 4 + leaves.size() * 8; }
};

// SVO -> DAG bottom-up (Kämpe et al. 2013; Molenaar 2019 §3.3 Algorithm 1): identical subtrees once.
LocalDag build_dag(const Grid& grid);

// The package's DAG pool: one hash table shared by every batching point, so identical subtrees
// anywhere in the package are stored once. Deterministic: the same adds in the same order give the
// same bytes.
class DagPool {
 public:
  // Adds a grid's DAG; returns its root reference in the pool.
  uint32_t add(const LocalDag& dag);
  const std::vector<uint32_t>& words() const { return words_; }
  const std::vector<uint64_t>& leaves() const { return leaves_; }
  uint64_t bytes() const { return words_.size() * 4 + leaves_.size() * 8; }

 private:
  std::vector<uint32_t> words_;
  std::vector<uint64_t> leaves_;
  HashIndex node_index_;  // words -> offset in words_
  HashIndex leaf_index_;  // mask -> index in leaves_
};

// Decodes a grid's DAG into a dense grid (tests, inspection).
Grid decode_dag(const fmt::DagGrid& grid, const DagView& pool);

// Scalar reference: every set cell of a dense grid tested on its own (slow; tests only).
DagHit grid_first_entry_reference(const Grid& dense, double growth, const double org[3], const double dir[3], double tnear,
                                  double tfar);

}  // namespace rtp::voxel
