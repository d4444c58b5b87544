// Reading a DAG in a package: structural check, sizes, and the interval-clipped ray/DAG test (Molenaar
// 2019 §3.2). Needs only formats/dag.h: it is part of the reader library.
#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <xmmintrin.h>

#include <array>
#include <string>
#include <unordered_set>
#include <vector>

#include "formats/bvh_layout.h"
#include "formats/chunk.h"
#include "layout/dag_query.h"

namespace rtp::voxel {
namespace {

// Population count of an 8-bit mask (the library is built for baseline x86-64: no POPCNT).
constexpr std::array<uint8_t, 256> make_pop8() {
  std::array<uint8_t, 256> t{};
  for (int i = 0; i < 256; ++i)
    t[size_t(i)] =
        uint8_t((i & 1) + (i >> 1 & 1) + (i >> 2 & 1) + (i >> 3 & 1) + (i >> 4 & 1) + (i >> 5 & 1) + (i >> 6 & 1) + (i >> 7 & 1));
  return t;
}
constexpr std::array<uint8_t, 256> kPop8 = make_pop8();

int grid_levels(uint32_t resolution) { return std::countr_zero(resolution / 4); }

bool resolution_ok(uint32_t r) { return r >= fmt::kDagMinResolution && r <= fmt::kDagMaxResolution && std::has_single_bit(r); }

}  // namespace

namespace {

// SPEC §4.5 (7.0): an instance-box grid's nodes. `seen` is shared by the grids of one pool: no node
// may be reached twice (so a walk visits each node at most once), inner children only after their parent.
template <int W>
std::string check_boxes(const fmt::DagGrid& g, const DagView& v, std::vector<uint8_t>& seen) {
  const auto* nodes = static_cast<const fmt::CullNode<W>*>(v.cull);
  if (g.root >= v.cull_count)
    return "instance boxes: first node " + std::to_string(g.root) + " out of range (" + std::to_string(v.cull_count) + " nodes)";
  if (seen.size() != v.cull_count) seen.assign(v.cull_count, 0);
  std::vector<uint64_t> pending{g.root};
  while (!pending.empty()) {
    const uint64_t at = pending.back();
    pending.pop_back();
    if (seen[at]) return "instance boxes: node " + std::to_string(at) + " reached twice";
    seen[at] = 1;
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(nodes[at].origin[k]) || !(nodes[at].scale[k] >= 0) || !std::isfinite(nodes[at].scale[k]))
        return "instance boxes: node " + std::to_string(at) + " has a non-finite origin or a negative or non-finite scale";
    for (int l = 0; l < W; ++l) {
      const uint32_t c = nodes[at].child[l];
      if (fmt::ChildRef::is_empty(c) || fmt::ChildRef::is_leaf(c)) continue;
      const uint64_t child = uint64_t(g.root) + c;
      if (child <= at || child >= v.cull_count)
        return "instance boxes: node " + std::to_string(at) + " lane " + std::to_string(l) + " references node " +
               std::to_string(child) + " (not after it, or out of range)";
      pending.push_back(child);
    }
  }
  return "";
}

std::string check_one(const fmt::DagGrid& g, const DagView& v, std::vector<uint8_t>& seen, std::vector<uint8_t>& box_seen) {
  if (g.resolution == fmt::kDagBoxes) {
    if (g.origin[0] != 0 || g.origin[1] != 0 || g.origin[2] != 0 || g.cell != 0 || g.margin != 0 || g.ray_rel != 0)
      return "instance boxes: origin, cell, margin and ray_rel must be 0";
    switch (v.cull ? v.cull_width : 0) {
      case 4: return check_boxes<4>(g, v, box_seen);
      case 8: return check_boxes<8>(g, v, box_seen);
      case 16: return check_boxes<16>(g, v, box_seen);
      default:
        return "instance boxes but no instance-box nodes (section " + std::to_string(uint32_t(fmt::SectionType::kCullNodes)) +
               ")";
    }
  }
  if (!resolution_ok(g.resolution)) return "resolution " + std::to_string(g.resolution) + " is not a power of two in [4, 1024]";
  if (!(std::isfinite(g.cell) && g.cell > 0)) return "cell size is not a positive finite number";
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(g.origin[k])) return "origin is not finite";
  // The far corner in float, as the writer stores grid boxes (in double it could never overflow).
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(g.origin[k] + g.cell * float(g.resolution))) return "grid extent is not finite (in float)";
  if (!(g.margin >= 0 && std::isfinite(g.margin)) || !(g.ray_rel >= 0 && std::isfinite(g.ray_rel)))
    return "margin or ray_rel is negative or not finite";
  if (g.root == fmt::kDagEmpty || g.root == fmt::kDagFull) return "";
  const int levels = grid_levels(g.resolution);
  // Messages are built only on failure: this runs on every load (cost O(reachable nodes)).
  auto bad_leaf = [&](uint32_t ref) { return ref >= v.leaf_count || v.leaves[ref] == 0 || v.leaves[ref] == ~uint64_t(0); };
  auto leaf_error = [&](uint32_t ref) {
    return ref >= v.leaf_count ? "leaf " + std::to_string(ref) + " out of range (" + std::to_string(v.leaf_count) + " leaves)"
                               : "leaf " + std::to_string(ref) + " is empty or full";
  };
  if (levels == 0) return bad_leaf(g.root) ? leaf_error(g.root) : "";
  // `seen`: visited (offset, level) pairs, one bit per level per word (levels <= 8), shared by the
  // grids of one pool so a node reachable from many batching points is checked once.
  struct Item {
    uint32_t off;
    int level;
  };
  std::vector<Item> pending{{g.root, levels}};
  auto at = [](const Item& it) { return "node at word " + std::to_string(it.off) + " (level " + std::to_string(it.level) + ")"; };
  while (!pending.empty()) {
    const Item it = pending.back();
    pending.pop_back();
    if (it.off >= v.word_count) return at(it) + " out of range (" + std::to_string(v.word_count) + " words)";
    if (seen.empty()) seen.assign(v.word_count, 0);
    const uint8_t bit = uint8_t(1u << (it.level - 1));
    if (seen[it.off] & bit) continue;
    seen[it.off] |= bit;
    const uint32_t head = v.words[it.off];
    const uint32_t cm = fmt::dag_child_mask(head), fm = fmt::dag_full_mask(head), im = fmt::dag_inline_mask(head);
    if ((head >> 24) != 0 || cm == 0 || (fm & ~cm) != 0 || fm == 0xFF || (im & ~(cm & ~fm)) != 0)
      return at(it) + ": malformed masks";
    if (im != 0 && it.level != 1) return at(it) + ": inline leaves above level 1";
    const uint64_t n = kPop8[cm & ~fm] + kPop8[im];
    if (uint64_t(it.off) + 1 + n > v.word_count) return at(it) + ": child references run past the pool";
    for (uint32_t c = 0, i = 0; c < 8; ++c) {
      if (!((cm & ~fm) >> c & 1)) continue;
      const uint32_t ref = v.words[it.off + 1 + i++];
      if (im >> c & 1) {
        const uint64_t m = ref | uint64_t(v.words[it.off + 1 + i++]) << 32;
        if (m == 0 || m == ~uint64_t(0)) return at(it) + ": inline leaf of child " + std::to_string(c) + " is empty or full";
      } else if (it.level == 1) {
        if (bad_leaf(ref)) return at(it) + ": " + leaf_error(ref);
      } else {
        pending.push_back({ref, it.level - 1});
      }
    }
  }
  return "";
}

}  // namespace

std::string check_dag(const fmt::DagGrid& g, const DagView& v) {
  std::vector<uint8_t> seen, box_seen;
  return check_one(g, v, seen, box_seen);
}

std::string check_dags(const fmt::DagGrid* grids, uint64_t n, const DagView& v) {
  std::vector<uint8_t> seen, box_seen;
  for (uint64_t p = 0; p < n; ++p) {
    const std::string e = check_one(grids[p], v, seen, box_seen);
    if (!e.empty()) return "batching point " + std::to_string(p) + ": " + e;
  }
  return "";
}

uint64_t dag_reachable_bytes(const fmt::DagGrid& g, const DagView& v) {
  if (g.resolution == fmt::kDagBoxes) return 0;  // no DAG: instance boxes
  if (g.root == fmt::kDagEmpty || g.root == fmt::kDagFull) return 0;
  const int levels = grid_levels(g.resolution);
  if (levels == 0) return 8;
  std::unordered_set<uint32_t> nodes, leaves;
  std::unordered_set<uint64_t> seen;
  uint64_t bytes = 0;
  std::vector<std::pair<uint32_t, int>> pending{{g.root, levels}};
  while (!pending.empty()) {
    auto [off, level] = pending.back();
    pending.pop_back();
    if (!seen.insert(uint64_t(off) << 8 | uint64_t(level)).second) continue;
    const uint32_t head = v.words[off], refs = fmt::dag_child_mask(head) & ~fmt::dag_full_mask(head);
    const uint32_t im = fmt::dag_inline_mask(head);
    if (nodes.insert(off).second) bytes += 4 * uint64_t(fmt::dag_node_words(head));
    for (uint32_t c = 0; c < 8; ++c) {
      if (!(refs >> c & 1) || (im >> c & 1)) continue;  // inline leaves are counted in the node's words
      const uint32_t ref = v.words[off + 1 + fmt::dag_child_slot(head, c)];
      if (level == 1) {
        if (leaves.insert(ref).second) bytes += 8;
      } else {
        pending.push_back({ref, level - 1});
      }
    }
  }
  return bytes;
}

double dag_ray_growth(const fmt::DagGrid& g, const double org[3]) {
  double big = 0, om = 0;
  for (int k = 0; k < 3; ++k) {
    big = std::max({big, std::fabs(double(g.origin[k])), std::fabs(double(g.origin[k]) + double(g.cell) * g.resolution)});
    om = std::max(om, std::fabs(org[k]));
  }
  return double(g.ray_rel) * (om + big);
}

namespace {

// kOctantPerm[o][m]: bit i set when child i ^ o is in m (children renumbered in the octant order).
constexpr std::array<std::array<uint8_t, 256>, 8> make_perm() {
  std::array<std::array<uint8_t, 256>, 8> t{};
  for (uint32_t o = 0; o < 8; ++o)
    for (uint32_t m = 0; m < 256; ++m) {
      uint32_t p = 0;
      for (uint32_t i = 0; i < 8; ++i) p |= ((m >> (i ^ o)) & 1u) << i;
      t[o][m] = uint8_t(p);
    }
  return t;
}
constexpr std::array<std::array<uint8_t, 256>, 8> kOctantPerm = make_perm();

// Bits 0, 2, 8, 10, 32, 34, 40, 42 of m (the corners of the 2x2x2 sub-blocks) as bits 0..7.
inline uint32_t gather_corners(uint64_t m) {
  return uint32_t((m & 1) | (m >> 1 & 2) | (m >> 6 & 4) | (m >> 7 & 8) | (m >> 28 & 16) | (m >> 29 & 32) | (m >> 34 & 64) |
                  (m >> 35 & 128));
}

}  // namespace

// Molenaar 2019 §4.2 (after Laine & Karras 2011 / Kämpe 2013): depth-first SVDAG traversal, children
// in the ray's octant order (a linear extension of front to back), here on explicit child boxes grown
// by the ray's error bound and clipped to [tnear, tfar]. The ray is moved into grid units once (in
// double); the walk then runs in float, where every node plane is a small exact integer ± the growth,
// and the float rounding of (plane - org) * inv is added to the growth: at most 3u·(|org| + R) cells,
// counted as 8u·(|org| + R) + 2^-12 (u = 2^-24; 2^-12 covers rounding the grown planes near 1024).
// The eight children of a node take their slabs from a 2-entry table per axis (branch-free lanes).
namespace {

// SPEC §4.5 (7.0): is any instance box of the grid met within the ray's interval? In double, each box
// grown by 1e-5 of its coordinates' and the origin's magnitudes and the interval by 1e-5 of itself (the
// float kernels' rounding is ~1e-7 of those): every box the point's instance walk may hit is hit here.
// A NaN anywhere counts as a hit, and so does a tree deeper than the fixed stack (no allocation).
template <int W>
bool any_instance_box(const fmt::DagGrid& g, const DagView& v, const double o[3], const double d[3], double tnear, double tfar) {
  const auto* nodes = static_cast<const fmt::CullNode<W>*>(v.cull);
  const double tn = tnear - 1e-5 * std::fabs(tnear), tf = tfar + 1e-5 * std::fabs(tfar);
  constexpr int kStack = 64;
  uint64_t stack[kStack];
  int sp = 0;
  stack[sp++] = g.root;
  while (sp > 0) {
    const fmt::CullNode<W>& n = nodes[stack[--sp]];
    for (int l = 0; l < W; ++l) {
      const uint32_t c = n.child[l];
      if (fmt::ChildRef::is_empty(c)) continue;
      double t0 = tn, t1 = tf;
      bool miss = false;
      for (int k = 0; k < 3; ++k) {
        const double lo = fmt::cull_plane(n.origin[k], n.scale[k], n.lo[k][l]),
                     hi = fmt::cull_plane(n.origin[k], n.scale[k], n.hi[k][l]);
        const double pad = 1e-5 * (std::fabs(lo) + std::fabs(hi) + std::fabs(o[k]));
        if (d[k] == 0) {
          miss |= o[k] < lo - pad || o[k] > hi + pad;
          continue;
        }
        double a = (lo - pad - o[k]) / d[k], b = (hi + pad - o[k]) / d[k];
        if (a > b) std::swap(a, b);
        if (a > t0) t0 = a;
        if (b < t1) t1 = b;
      }
      if (miss || t0 > t1) continue;  // false for NaN: a hit
      if (fmt::ChildRef::is_leaf(c)) return true;
      if (sp == kStack) return true;
      stack[sp++] = uint64_t(g.root) + c;
    }
  }
  return false;
}

}  // namespace

DagHit dag_first_entry(const fmt::DagGrid& g, const DagView& v, const double org[3], const double dir[3], double tnear,
                       double tfar) {
  DagHit out;
  if (g.resolution == fmt::kDagBoxes) {  // 7.0: instance boxes, no entry distance (tnear as it is)
    bool any = true;                     // without nodes nothing is culled (check_dags refuses that package)
    switch (v.cull ? v.cull_width : 0) {
      case 4: any = any_instance_box<4>(g, v, org, dir, tnear, tfar); break;
      case 8: any = any_instance_box<8>(g, v, org, dir, tnear, tfar); break;
      case 16: any = any_instance_box<16>(g, v, org, dir, tnear, tfar); break;
      default: break;
    }
    return {!any, tnear};
  }
  if (g.root == fmt::kDagEmpty) return out;
  constexpr float kInfF = std::numeric_limits<float>::infinity();
  const __m128 kSigns = _mm_setr_ps(-1.0f, -1.0f, 1.0f, 1.0f);
  const double cell = g.cell, res = g.resolution;
  float og[3], inv[3];
  bool zero[3];
  uint32_t octant = 0;
  double omax = 0;
  for (int k = 0; k < 3; ++k) {
    const double o = (org[k] - double(g.origin[k])) / cell;
    og[k] = float(o);
    omax = std::max(omax, std::fabs(o));
    const double iv = cell / dir[k];
    inv[k] = float(iv);
    zero[k] = dir[k] == 0 || !std::isfinite(inv[k]);
    if (dir[k] < 0) octant |= 1u << k;
  }
  if (!(omax < 1e30)) return {false, tnear};  // beyond float grid units: not culled, no shortcut
  const float delta = float(dag_ray_growth(g, org) / cell + 8.0 / 16777216.0 * (omax + res) + 1.0 / 4096.0);
  const float tn = float(tnear), tf = float(tfar);
  // tnear/tfar are float in every caller (fmt::Ray); a double that is not gets the wider float.
  const float t_lo = double(tn) <= tnear ? tn : std::nextafter(tn, -kInfF);
  const float t_hi = double(tf) >= tfar ? tf : std::nextafter(tf, kInfF);
  enum Kind : uint8_t { kNode, kLeaf, kInline, kSub, kSet };
  struct Entry {
    uint32_t ref;         // node word offset, leaf index, inline leaf's word offset, or a sub-block's 8 cell bits
    uint16_t x, y, z;     // cell coordinates of the region's minimum corner
    uint8_t kind, level;  // level: DAG level of a kNode (>= 1); size = 4 << level cells
    float t;              // entry distance of the grown region
  };
  auto size_of = [](const Entry& e) -> uint32_t {
    return e.kind == kNode ? 4u << e.level : e.kind <= kInline ? 4u : e.kind == kSub ? 2u : 1u << e.level;
  };
  // Root region.
  float t_root = t_lo, t_root_far = t_hi;
  for (int k = 0; k < 3; ++k) {
    const float lo = -delta, hi = float(res) + delta;
    if (zero[k]) {
      if (!(og[k] >= lo && og[k] <= hi)) return out;
      continue;
    }
    const float a = (lo - og[k]) * inv[k], b = (hi - og[k]) * inv[k];
    t_root = std::max(t_root, std::min(a, b));
    t_root_far = std::min(t_root_far, std::max(a, b));
  }
  if (!(t_root <= t_root_far)) return out;
  Entry stack[96];
  int sp = 0;
  const int levels = grid_levels(g.resolution);
  if (g.root == fmt::kDagFull)
    stack[sp++] = {0, 0, 0, 0, kSet, uint8_t(levels + 2), t_root};
  else if (levels == 0)
    stack[sp++] = {g.root, 0, 0, 0, kLeaf, 0, t_root};
  else
    stack[sp++] = {g.root, 0, 0, 0, kNode, uint8_t(levels), t_root};
  while (sp > 0) {
    const Entry e = stack[--sp];
    if (e.kind == kSet) {
      // The first set region in octant order. A region still on the stack may be entered earlier
      // (the order is not by distance), so the answer is the smallest entry distance among this
      // region and every pending one: a lower bound on every set cell's entry.
      float best = e.t;
      for (int k = 0; k < sp; ++k) best = std::min(best, stack[k].t);
      return {false, double(best)};
    }
    const uint32_t size = size_of(e), half = size / 2;
    // The eight children's slabs at once (SSE, lanes = children 0..3 and 4..7): per axis the four
    // planes lo - d, mid - d, mid + d, hi + d give t = (plane - org) * inv; child bit 0 spans planes
    // (0, 2), bit 1 planes (1, 3), so min/max of (a0 a1 a2 a3) with (a2 a3 a0 a1) is (near0 near1
    // near0 near1) — the x pattern of the lanes; y and z are shuffles of it.
    const uint32_t c[3] = {e.x, e.y, e.z};
    __m128 n_lo = _mm_set1_ps(t_lo), n_hi = n_lo, f_lo = _mm_set1_ps(t_hi), f_hi = f_lo;
    for (int k = 0; k < 3; ++k) {
      const float mid = float(c[k] + half);
      const __m128 planes =
          _mm_add_ps(_mm_setr_ps(float(c[k]), mid, mid, float(c[k] + size)), _mm_mul_ps(_mm_set1_ps(delta), kSigns));
      __m128 mn, mx;
      if (zero[k]) {  // containment decides: (-inf, inf) or an empty slab
        const float o = og[k];
        alignas(16) float p[4];
        _mm_store_ps(p, planes);
        const bool in0 = o >= p[0] && o <= p[2], in1 = o >= p[1] && o <= p[3];
        mn = _mm_setr_ps(in0 ? -kInfF : kInfF, in1 ? -kInfF : kInfF, in0 ? -kInfF : kInfF, in1 ? -kInfF : kInfF);
        mx = _mm_setr_ps(in0 ? kInfF : -kInfF, in1 ? kInfF : -kInfF, in0 ? kInfF : -kInfF, in1 ? kInfF : -kInfF);
      } else {
        const __m128 a = _mm_mul_ps(_mm_sub_ps(planes, _mm_set1_ps(og[k])), _mm_set1_ps(inv[k]));
        const __m128 b = _mm_shuffle_ps(a, a, _MM_SHUFFLE(1, 0, 3, 2));
        mn = _mm_min_ps(a, b);  // (near0, near1, near0, near1)
        mx = _mm_max_ps(a, b);
      }
      __m128 lo_n, hi_n, lo_f, hi_f;  // lanes 0..3 and 4..7
      if (k == 0) {
        lo_n = hi_n = mn, lo_f = hi_f = mx;
      } else if (k == 1) {
        lo_n = hi_n = _mm_shuffle_ps(mn, mn, _MM_SHUFFLE(1, 1, 0, 0));
        lo_f = hi_f = _mm_shuffle_ps(mx, mx, _MM_SHUFFLE(1, 1, 0, 0));
      } else {
        lo_n = _mm_shuffle_ps(mn, mn, _MM_SHUFFLE(0, 0, 0, 0)), hi_n = _mm_shuffle_ps(mn, mn, _MM_SHUFFLE(1, 1, 1, 1));
        lo_f = _mm_shuffle_ps(mx, mx, _MM_SHUFFLE(0, 0, 0, 0)), hi_f = _mm_shuffle_ps(mx, mx, _MM_SHUFFLE(1, 1, 1, 1));
      }
      n_lo = _mm_max_ps(n_lo, lo_n), n_hi = _mm_max_ps(n_hi, hi_n);
      f_lo = _mm_min_ps(f_lo, lo_f), f_hi = _mm_min_ps(f_hi, hi_f);
    }
    const uint32_t hit = uint32_t(_mm_movemask_ps(_mm_cmple_ps(n_lo, f_lo))) | uint32_t(_mm_movemask_ps(_mm_cmple_ps(n_hi, f_hi)))
                                                                                   << 4;
    alignas(16) float tc[8];
    _mm_store_ps(tc, n_lo);
    _mm_store_ps(tc + 4, n_hi);
    // Which children exist (and how to reach them).
    uint32_t exist = 0, full = 0, inl = 0;
    uint64_t leaf_mask = 0;
    if (e.kind == kNode) {
      const uint32_t head = v.words[e.ref];
      exist = fmt::dag_child_mask(head);
      full = fmt::dag_full_mask(head);
      inl = fmt::dag_inline_mask(head);
    } else if (e.kind <= kInline) {
      // Sub-block c of the 4^3 leaf occupies bits (2cx + 8cy + 32cz) + {0, 1, 4, 5, 16, 17, 20, 21}:
      // OR (AND) the eight together in three shifts, then gather the eight corner bits.
      leaf_mask = e.kind == kLeaf ? v.leaves[e.ref] : v.words[e.ref] | uint64_t(v.words[e.ref + 1]) << 32;
      uint64_t any = leaf_mask | leaf_mask >> 1, all = leaf_mask & leaf_mask >> 1;
      any |= any >> 4, all &= all >> 4;
      any |= any >> 16, all &= all >> 16;
      exist = gather_corners(any);
      full = gather_corners(all);
    } else {  // kSub: single cells
      exist = full = e.ref;
    }
    // Push in reverse octant order (i ^ octant for i = 7 .. 0): the nearest ends on top.
    for (uint32_t pending = kOctantPerm[octant][exist & hit]; pending; pending &= ~(1u << (31 - __builtin_clz(pending)))) {
      const uint32_t ch = uint32_t(31 - __builtin_clz(pending)) ^ octant;
      const uint16_t x = uint16_t(e.x + (ch & 1) * half), y = uint16_t(e.y + ((ch >> 1) & 1) * half),
                     z = uint16_t(e.z + (ch >> 2) * half);
      if (full >> ch & 1) {
        // A whole set child: kSet, its size carried as log2 in `level`.
        stack[sp++] = {0, x, y, z, kSet, uint8_t(__builtin_ctz(half)), tc[ch]};
      } else if (e.kind == kNode) {
        const uint32_t below = (1u << ch) - 1, at = e.ref + 1 + kPop8[exist & ~full & below] + kPop8[inl & below];
        const uint8_t kind = e.level != 1 ? uint8_t(kNode) : (inl >> ch & 1) ? uint8_t(kInline) : uint8_t(kLeaf);
        stack[sp++] = {kind == kInline ? at : v.words[at], x, y, z, kind, uint8_t(e.level - 1), tc[ch]};
      } else {  // a partly set 2x2x2 sub-block of a leaf: its 8 cell bits, x fastest
        const uint64_t t = leaf_mask >> ((x & 3) + 4 * (y & 3) + 16 * (z & 3));
        const uint32_t bits = uint32_t((t & 0x3) | (t >> 2 & 0xC) | (t >> 12 & 0x30) | (t >> 14 & 0xC0));
        stack[sp++] = {bits, x, y, z, kSub, 0, tc[ch]};
      }
    }
  }
  return out;
}

bool dag_enter(const fmt::DagGrid& grid, const DagView& pool, fmt::Ray& ray) {
  const double org[3] = {ray.org[0], ray.org[1], ray.org[2]}, dir[3] = {ray.dir[0], ray.dir[1], ray.dir[2]};
  const DagHit h = dag_first_entry(grid, pool, org, dir, ray.tnear, ray.tfar);
  if (h.culled) return false;
  float t = float(h.t_entry);
  if (double(t) > h.t_entry) t = std::nextafter(t, -std::numeric_limits<float>::infinity());
  if (t > ray.tnear) ray.tnear = t;
  return true;
}

}  // namespace rtp::voxel
