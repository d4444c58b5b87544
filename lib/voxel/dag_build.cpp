// Sparse voxel octree -> DAG, bottom-up with hashing (Kämpe et al. 2013; Molenaar 2019 §3.3
// Algorithm 1), and the package-wide pool whose one hash table is shared by every batching point.
#include <bit>
#include <string>
#include <unordered_map>

#include "voxel/voxel.h"

namespace rtp::voxel {
namespace {

constexpr uint32_t kNone = fmt::kDagEmpty;  // "empty" while building (never stored as a child)

struct Builder {
  const Grid& g;
  LocalDag out;
  std::unordered_map<uint64_t, uint32_t> leaf_index;
  std::unordered_map<std::u32string, uint32_t> node_index;  // (level, words...) -> offset

  uint32_t leaf(uint32_t bx, uint32_t by, uint32_t bz) {
    const uint64_t m = g.block(bx, by, bz);
    if (m == 0) return kNone;
    if (m == ~uint64_t(0)) return fmt::kDagFull;
    auto [it, fresh] = leaf_index.emplace(m, uint32_t(out.leaves.size()));
    if (fresh) out.leaves.push_back(m);
    return it->second;
  }
  // Node at `level` (>= 1) whose block-space corner is (x, y, z) * 2^level.
  uint32_t node(int level, uint32_t x, uint32_t y, uint32_t z) {
    if (g.region_empty(x << level, y << level, z << level, 1u << level)) return kNone;  // no brick: skip
    uint32_t refs[8], child_mask = 0, full_mask = 0;
    for (uint32_t c = 0; c < 8; ++c) {
      const uint32_t cx = 2 * x + (c & 1), cy = 2 * y + ((c >> 1) & 1), cz = 2 * z + (c >> 2);
      refs[c] = level == 1 ? leaf(cx, cy, cz) : node(level - 1, cx, cy, cz);
      if (refs[c] == kNone) continue;
      child_mask |= 1u << c;
      if (refs[c] == fmt::kDagFull) full_mask |= 1u << c;
    }
    if (child_mask == 0) return kNone;
    if (full_mask == 0xFF) return fmt::kDagFull;
    std::u32string w;  // the level first: the same words at another level are other children
    w.push_back(char32_t(level));
    w.push_back(char32_t(child_mask | full_mask << 8));
    for (uint32_t c = 0; c < 8; ++c)
      if ((child_mask & ~full_mask) >> c & 1) w.push_back(char32_t(refs[c]));
    auto [it, fresh] = node_index.emplace(w, uint32_t(out.words.size()));
    if (fresh) {
      out.node_offsets.push_back(uint32_t(out.words.size()));
      out.node_levels.push_back(uint8_t(level));
      out.words.insert(out.words.end(), w.begin() + 1, w.end());
    }
    return it->second;
  }
};

}  // namespace

LocalDag build_dag(const Grid& g) {
  Builder b{g, {}, {}, {}};
  const int levels = std::countr_zero(g.resolution / 4);
  const uint32_t root = levels == 0 ? b.leaf(0, 0, 0) : b.node(levels, 0, 0, 0);
  b.out.root = root;  // kNone == kDagEmpty
  return std::move(b.out);
}

uint32_t DagPool::add(const LocalDag& dag) {
  std::vector<uint32_t> leaf_map(dag.leaves.size());
  for (size_t i = 0; i < dag.leaves.size(); ++i) {
    auto [it, fresh] = leaf_index_.emplace(dag.leaves[i], uint32_t(leaves_.size()));
    if (fresh) leaves_.push_back(dag.leaves[i]);
    leaf_map[i] = it->second;
  }
  std::unordered_map<uint32_t, uint32_t> node_map;  // local offset -> pool offset
  for (size_t k = 0; k < dag.node_offsets.size(); ++k) {
    const uint32_t off = dag.node_offsets[k];
    const uint32_t head = dag.words[off];
    const int n = std::popcount(fmt::dag_child_mask(head) & ~fmt::dag_full_mask(head));
    std::u32string w;
    w.push_back(char32_t(head));
    for (int i = 0; i < n; ++i) {
      const uint32_t r = dag.words[off + 1 + size_t(i)];
      w.push_back(char32_t(dag.node_levels[k] == 1 ? leaf_map[r] : node_map.at(r)));
    }
    // Identical words are identical subtrees at whatever level they are read (references are
    // interpreted by the level of the node that holds them), so the pool shares them across levels.
    auto [it, fresh] = node_index_.emplace(w, uint32_t(words_.size()));
    if (fresh)
      for (char32_t v : w) words_.push_back(uint32_t(v));
    node_map[off] = it->second;
  }
  if (dag.root == fmt::kDagEmpty || dag.root == fmt::kDagFull) return dag.root;
  return dag.node_offsets.empty() ? leaf_map.at(dag.root) : node_map.at(dag.root);
}

}  // namespace rtp::voxel
