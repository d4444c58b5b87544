// Sparse voxel octree -> DAG, bottom-up with hashing (Kämpe et al. 2013; Molenaar 2019 §3.3
// Algorithm 1), and the package-wide pool whose one hash table is shared by every batching point.
#include <algorithm>
#include <bit>

#include "voxel/hash_index.h"
#include "voxel/voxel.h"

namespace rtp::voxel {
namespace {

constexpr uint32_t kNone = fmt::kDagEmpty;  // "empty" while building (never stored as a child)

struct Builder {
  const Grid& g;
  LocalDag out;
  HashIndex leaf_index;  // mask -> index into out.leaves
  HashIndex node_index;  // (level, words...) -> index into out.node_offsets

  uint32_t leaf(uint32_t bx, uint32_t by, uint32_t bz) { return leaf_of(g.block(bx, by, bz)); }
  uint32_t leaf_of(uint64_t m) {
    if (m == 0) return kNone;
    if (m == ~uint64_t(0)) return fmt::kDagFull;
    const auto [index, fresh] = leaf_index.find_or_insert(
        mix64(m), [&](uint32_t v) { return out.leaves[v] == m; }, uint32_t(out.leaves.size()));
    if (fresh) out.leaves.push_back(m);
    return index;
  }
  // Node at `level` (>= 1) whose block-space corner is (x, y, z) * 2^level.
  uint32_t node(int level, uint32_t x, uint32_t y, uint32_t z) {
    if (g.region_empty(x << level, y << level, z << level, 1u << level)) return kNone;  // no brick: skip
    uint32_t refs[8], child_mask = 0, full_mask = 0;
    uint64_t blocks[8];  // level 1: the eight leaf blocks, one brick lookup
    if (level == 1) g.block_octet(2 * x, 2 * y, 2 * z, blocks);
    for (uint32_t c = 0; c < 8; ++c) {
      const uint32_t cx = 2 * x + (c & 1), cy = 2 * y + ((c >> 1) & 1), cz = 2 * z + (c >> 2);
      refs[c] = level == 1 ? leaf_of(blocks[c]) : node(level - 1, cx, cy, cz);
      if (refs[c] == kNone) continue;
      child_mask |= 1u << c;
      if (refs[c] == fmt::kDagFull) full_mask |= 1u << c;
    }
    if (child_mask == 0) return kNone;
    if (full_mask == 0xFF) return fmt::kDagFull;
    // The key is (level, words): the same words at another level are other children.
    uint32_t w[9], n = 0;
    w[n++] = child_mask | full_mask << 8;
    for (uint32_t c = 0; c < 8; ++c)
      if ((child_mask & ~full_mask) >> c & 1) w[n++] = refs[c];
    const auto same = [&](uint32_t k) {  // equal heads: equal lengths
      return out.node_levels[k] == level && out.words[out.node_offsets[k]] == w[0] &&
             std::equal(w, w + n, out.words.begin() + out.node_offsets[k]);
    };
    const auto [k, fresh] = node_index.find_or_insert(hash_words(w, n, uint64_t(level)), same, uint32_t(out.node_offsets.size()));
    if (fresh) {
      out.node_offsets.push_back(uint32_t(out.words.size()));
      out.node_levels.push_back(uint8_t(level));
      out.words.insert(out.words.end(), w, w + n);
    }
    return out.node_offsets[k];
  }
};

// formats/dag.h (version 3.0): a leaf that one level-1 node alone references is stored in that node
// (8 bytes instead of a 4-byte reference plus an 8-byte pooled mask); leaves shared by several nodes
// stay pooled. Nodes were built children first, so one pass in creation order remaps every offset.
void inline_single_use_leaves(LocalDag& d) {
  std::vector<uint32_t> uses(d.leaves.size(), 0);
  for (size_t k = 0; k < d.node_offsets.size(); ++k) {
    if (d.node_levels[k] != 1) continue;
    const uint32_t off = d.node_offsets[k], n = fmt::dag_node_words(d.words[off]) - 1;
    for (uint32_t i = 0; i < n; ++i) ++uses[d.words[off + 1 + i]];
  }
  std::vector<uint32_t> leaf_map(d.leaves.size(), kNone);
  std::vector<uint64_t> leaves;
  for (size_t i = 0; i < d.leaves.size(); ++i)
    if (uses[i] != 1) {
      leaf_map[i] = uint32_t(leaves.size());
      leaves.push_back(d.leaves[i]);
    }
  std::vector<uint32_t> words, node_map(d.words.size(), kNone);
  std::vector<uint32_t> offsets;
  for (size_t k = 0; k < d.node_offsets.size(); ++k) {
    const uint32_t off = d.node_offsets[k], head = d.words[off];
    const uint32_t refs = fmt::dag_child_mask(head) & ~fmt::dag_full_mask(head);
    node_map[off] = uint32_t(words.size());
    offsets.push_back(uint32_t(words.size()));
    const size_t head_at = words.size();
    words.push_back(head);
    uint32_t i = 0, inl = 0;
    for (uint32_t c = 0; c < 8; ++c) {
      if (!(refs >> c & 1)) continue;
      const uint32_t r = d.words[off + 1 + i++];
      if (d.node_levels[k] != 1) {
        words.push_back(node_map[r]);
      } else if (uses[r] == 1) {
        inl |= 1u << c;
        words.push_back(uint32_t(d.leaves[r]));
        words.push_back(uint32_t(d.leaves[r] >> 32));
      } else {
        words.push_back(leaf_map[r]);
      }
    }
    words[head_at] |= inl << 16;
  }
  const bool root_is_node = !d.node_offsets.empty() && d.root != kNone && d.root != fmt::kDagFull;
  if (root_is_node)
    d.root = node_map[d.root];
  else if (d.root != kNone && d.root != fmt::kDagFull)
    d.root = leaf_map[d.root];  // R = 4: the root is a leaf
  d.words = std::move(words);
  d.node_offsets = std::move(offsets);
  d.leaves = std::move(leaves);
}

}  // namespace

LocalDag build_dag(const Grid& g) {
  Builder b{g, {}, {}, {}};
  const int levels = std::countr_zero(g.resolution / 4);
  const uint32_t root = levels == 0 ? b.leaf(0, 0, 0) : b.node(levels, 0, 0, 0);
  b.out.root = root;  // kNone == kDagEmpty
  inline_single_use_leaves(b.out);
  return std::move(b.out);
}

uint32_t DagPool::add(const LocalDag& dag) {
  std::vector<uint32_t> leaf_map(dag.leaves.size());
  for (size_t i = 0; i < dag.leaves.size(); ++i) {
    const uint64_t m = dag.leaves[i];
    const auto [index, fresh] = leaf_index_.find_or_insert(
        mix64(m), [&](uint32_t v) { return leaves_[v] == m; }, uint32_t(leaves_.size()));
    if (fresh) leaves_.push_back(m);
    leaf_map[i] = index;
  }
  std::vector<uint32_t> node_map(dag.words.size(), fmt::kDagEmpty);  // local offset -> pool offset
  std::vector<uint32_t> w;
  for (size_t k = 0; k < dag.node_offsets.size(); ++k) {
    const uint32_t off = dag.node_offsets[k];
    const uint32_t head = dag.words[off];
    const uint32_t refs = fmt::dag_child_mask(head) & ~fmt::dag_full_mask(head), inl = fmt::dag_inline_mask(head);
    w.assign(1, head);
    for (uint32_t c = 0, i = 0; c < 8; ++c) {
      if (!(refs >> c & 1)) continue;
      const uint32_t r = dag.words[off + 1 + i++];
      if (inl >> c & 1) {  // an inline leaf: its two words as they are
        w.push_back(r);
        w.push_back(dag.words[off + 1 + i++]);
      } else {
        w.push_back(dag.node_levels[k] == 1 ? leaf_map[r] : node_map.at(r));
      }
    }
    // Identical words are identical subtrees at whatever level they are read (references are
    // interpreted by the level of the node that holds them), so the pool shares them across levels.
    const auto same = [&](uint32_t at) {  // equal heads: equal lengths
      return words_[at] == head && std::equal(w.begin(), w.end(), words_.begin() + at);
    };
    const auto [at, fresh] = node_index_.find_or_insert(hash_words(w.data(), w.size(), 0), same, uint32_t(words_.size()));
    if (fresh) words_.insert(words_.end(), w.begin(), w.end());
    node_map[off] = at;
  }
  if (dag.root == fmt::kDagEmpty || dag.root == fmt::kDagFull) return dag.root;
  return dag.node_offsets.empty() ? leaf_map.at(dag.root) : node_map.at(dag.root);
}

}  // namespace rtp::voxel
