// Binary binned SAH builder over primitive boxes (triangles or instance bounds), the first stage of
// Benthin 2008 §4.1 ("an existing high-quality BVH builder (based on SAH-based binning)"), with the
// binning of Wald 2007 ("On fast Construction of SAH-based Bounding Volume Hierarchies").
//
// At each range the centroids are binned into `bins` bins on each of the 3 axes and the plane with the
// least SA(left)·N(left) + SA(right)·N(right) is taken. When no plane separates the centroids (all equal
// on every axis) or the depth budget is used up, the range is split at its median centroid along the
// widest axis, ties broken by primitive id: with all centroids equal that is a median on object index.
// Ranges of at most leaf_size primitives become leaves (Benthin §4.2 a-priori collapse: stopping the
// binary build there gives the same leaves as collapsing those subtrees afterwards).
//
// Parallelism: large ranges bin with tbb::parallel_reduce (bins merge by exact min/max and integer
// sums) and partition with a stable chunked scatter; halves of large ranges build as TBB tasks into
// node slots reserved by range. Every decision depends on primitive counts only, so the tree is the
// same for any thread count.
#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/parallel_invoke.h>
#include <oneapi/tbb/parallel_reduce.h>

#include <immintrin.h>

#include <array>
#include <bit>
#include <limits>

#include "bvh/build_internal.h"
#include "core/error.h"

namespace rtp::bvh {
namespace {

constexpr uint32_t kChunk = 8192;  // primitives per parallel work unit (fixed, not per thread)

// SSE (part of the x86-64 baseline) on PrimRef halves {lo.x, lo.y, lo.z, id} and {hi.x, hi.y, hi.z, 0}.
// Lane 3 is cleared (the id's bits would be a denormal float: slow microcode assists) and never read.
// With no NaN and no -0 in the input, _mm_min_ps/_mm_max_ps give the same bits as std::min/std::max,
// in any order.
inline __m128 xyz(__m128 v) { return _mm_and_ps(v, _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1))); }
inline __m128 load_lo(const PrimRef& p) { return xyz(_mm_loadu_ps(p.lo)); }
inline __m128 load_hi(const PrimRef& p) { return xyz(_mm_loadu_ps(p.hi)); }
// Same operations, same order as PrimRef::centroid.
inline __m128 centroid(__m128 lo, __m128 hi) {
  const __m128 half = _mm_set1_ps(0.5f);
  return _mm_add_ps(_mm_add_ps(_mm_mul_ps(half, lo), _mm_mul_ps(half, hi)), _mm_setzero_ps());
}

struct VBox {
  __m128 lo = _mm_set1_ps(std::numeric_limits<float>::infinity());
  __m128 hi = _mm_set1_ps(-std::numeric_limits<float>::infinity());
  void add(__m128 l, __m128 h) {
    lo = _mm_min_ps(lo, l);
    hi = _mm_max_ps(hi, h);
  }
  void add(const VBox& o) { add(o.lo, o.hi); }
  Box3f box() const {
    float l[4], h[4];
    _mm_storeu_ps(l, lo);
    _mm_storeu_ps(h, hi);
    Box3f b;
    for (int a = 0; a < 3; ++a) {
      b.lo[a] = l[a];
      b.hi[a] = h[a];
    }
    return b;
  }
};

// half_area(Box3f) of a non-empty SSE box without the round trip through memory: the same double
// arithmetic. (The sweeps' boxes hold at least one primitive each: half_area's test for an empty box
// would always pass.)
inline double half_area_sse(__m128 lo, __m128 hi) {
  const __m128d exy = _mm_sub_pd(_mm_cvtps_pd(hi), _mm_cvtps_pd(lo));
  const __m128d ez = _mm_sub_sd(_mm_cvtps_pd(_mm_movehl_ps(hi, hi)), _mm_cvtps_pd(_mm_movehl_ps(lo, lo)));
  const double x = _mm_cvtsd_f64(exy), y = _mm_cvtsd_f64(_mm_unpackhi_pd(exy, exy)), z = _mm_cvtsd_f64(ez);
  return x * y + y * z + z * x;
}

// Bounds (box and centroid box) of a set of primitives.
struct Bounds {
  VBox box, cbox;
  void add(const PrimRef& p) {
    const __m128 lo = load_lo(p), hi = load_hi(p), c = centroid(lo, hi);
    box.add(lo, hi);
    cbox.add(c, c);
  }
  void add(const Bounds& o) {
    box.add(o.box);
    cbox.add(o.cbox);
  }
};

Bounds bounds_of(const PrimRef* p, uint32_t begin, uint32_t end, uint32_t parallel_threshold) {
  if (end - begin < parallel_threshold) {
    Bounds b;
    for (uint32_t i = begin; i < end; ++i) b.add(p[i]);
    return b;
  }
  return tbb::parallel_reduce(
      tbb::blocked_range<uint32_t>(begin, end, kChunk), Bounds{},
      [&](const tbb::blocked_range<uint32_t>& r, Bounds b) {
        for (uint32_t i = r.begin(); i != r.end(); ++i) b.add(p[i]);
        return b;
      },
      [](Bounds a, const Bounds& b) {
        a.add(b);
        return a;
      });
}

// The mapping of centroids to bins for one range: bin = trunc(clamp((c − lo)·scale, 0, bins − 1)),
// in float, the same function (bins_of) for binning and partitioning.
struct BinMap {
  uint32_t bins = 0;
  bool usable[3] = {false, false, false};  // the centroids spread along this axis
  __m128 lo, scale, top;

  BinMap(const Box3f& cbox, uint32_t n_bins) : bins(n_bins) {
    float l[4] = {0, 0, 0, 0}, s[4] = {0, 0, 0, 0};
    for (int a = 0; a < 3; ++a) {
      const double extent = double(cbox.hi[a]) - double(cbox.lo[a]);
      const float sc = extent > 0 ? float(double(bins) / extent) : 0.0f;
      usable[a] = sc > 0 && sc < std::numeric_limits<float>::infinity();
      l[a] = cbox.lo[a];
      s[a] = usable[a] ? sc : 0.0f;
    }
    lo = _mm_loadu_ps(l);
    scale = _mm_loadu_ps(s);
    top = _mm_set1_ps(float(bins - 1));
  }
  // Bin per axis (unusable axes: 0). NaN/overflow clamp to a valid bin.
  void bins_of(__m128 c, int out[4]) const {
    __m128 t = _mm_mul_ps(_mm_sub_ps(c, lo), scale);
    t = _mm_min_ps(_mm_max_ps(t, _mm_setzero_ps()), top);  // max(NaN, 0) = 0
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out), _mm_cvttps_epi32(t));
  }
  int bin(const PrimRef& p, int axis) const {
    int k[4];
    bins_of(centroid(load_lo(p), load_hi(p)), k);
    return k[axis];
  }
};

struct Bins {
  // Only the first `bins` entries are initialized and used.
  struct Box {
    __m128 lo, hi;
  } box[3][kMaxBins];
  uint32_t count[3][kMaxBins];
  uint64_t used[3] = {0, 0, 0};  // per axis: bit i set when bin i holds a primitive (set_used, bin_small)
  // All `bins` bins empty; Bins(0) initializes none (bin_small writes the ones it uses).
  explicit Bins(uint32_t bins) {
    const VBox empty;
    for (int a = 0; a < 3; ++a)
      for (uint32_t i = 0; i < bins; ++i) {
        box[a][i] = {empty.lo, empty.hi};
        count[a][i] = 0;
      }
  }
  // `used` from the counts of all `bins` bins: four counts per SSE2 compare.
  void set_used(uint32_t bins) {
    for (int a = 0; a < 3; ++a) {
      uint64_t m = 0;
      uint32_t i = 0;
      for (; i + 4 <= bins; i += 4) {
        const __m128i c = _mm_loadu_si128(reinterpret_cast<const __m128i*>(&count[a][i]));
        const int empty = _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(c, _mm_setzero_si128())));
        m |= uint64_t(~empty & 0xF) << i;
      }
      for (; i < bins; ++i) m |= uint64_t(count[a][i] != 0) << i;
      used[a] = m;
    }
  }
  void add(const Bins& o, uint32_t bins) {
    for (int a = 0; a < 3; ++a)
      for (uint32_t i = 0; i < bins; ++i) {
        box[a][i].lo = _mm_min_ps(box[a][i].lo, o.box[a][i].lo);
        box[a][i].hi = _mm_max_ps(box[a][i].hi, o.box[a][i].hi);
        count[a][i] += o.count[a][i];
      }
  }
};

void bin_into(const PrimRef* p, uint32_t begin, uint32_t end, const BinMap& map, Bins& bins) {
  int k[4];
  for (uint32_t i = begin; i < end; ++i) {
    const __m128 lo = load_lo(p[i]), hi = load_hi(p[i]);
    map.bins_of(centroid(lo, hi), k);
    for (int a = 0; a < 3; ++a) {
      Bins::Box& b = bins.box[a][k[a]];
      b.lo = _mm_min_ps(b.lo, lo);
      b.hi = _mm_max_ps(b.hi, hi);
      ++bins.count[a][k[a]];
    }
  }
}

// Ranges of at most kSmallRange primitives (most calls: the ranges near the leaves, and every range
// of a batching point's instance BVH of ~250 instances): the bins each primitive falls in first, then
// only those bins set empty and filled — the same boxes and counts as bin_into over all bins set
// empty, without writing 3 x `bins` empty bins for a handful of primitives, and without a branch on
// whether a bin was touched before.
constexpr uint32_t kSmallRange = 32;
void bin_small(const PrimRef* p, uint32_t begin, uint32_t end, const BinMap& map, Bins& bins) {
  int k[kSmallRange][4];
  uint64_t used[3] = {0, 0, 0};
  const uint32_t n = end - begin;
  for (uint32_t j = 0; j < n; ++j) {
    map.bins_of(centroid(load_lo(p[begin + j]), load_hi(p[begin + j])), k[j]);
    for (int a = 0; a < 3; ++a) used[a] |= uint64_t(1) << k[j][a];
  }
  const VBox empty;
  for (int a = 0; a < 3; ++a) {
    for (uint64_t m = used[a]; m; m &= m - 1) {
      const int i = std::countr_zero(m);
      bins.box[a][i] = {empty.lo, empty.hi};
      bins.count[a][i] = 0;
    }
    bins.used[a] = used[a];
  }
  for (uint32_t j = 0; j < n; ++j) {
    const __m128 lo = load_lo(p[begin + j]), hi = load_hi(p[begin + j]);
    for (int a = 0; a < 3; ++a) {
      Bins::Box& b = bins.box[a][k[j][a]];
      b.lo = _mm_min_ps(b.lo, lo);
      b.hi = _mm_max_ps(b.hi, hi);
      ++bins.count[a][k[j][a]];
    }
  }
}

// tbb::parallel_reduce body: each split body bins its own ranges, joins merge exactly (min/max, sums).
// (A body rather than the functional form, so that no Bins is ever copied: only the first `bins`
// entries of a Bins are initialized.)
struct BinBody {
  const PrimRef* prims;
  const BinMap& map;
  uint32_t nb;
  Bins bins;
  BinBody(const PrimRef* p, const BinMap& m, uint32_t n) : prims(p), map(m), nb(n), bins(n) {}
  BinBody(BinBody& o, tbb::split) : prims(o.prims), map(o.map), nb(o.nb), bins(o.nb) {}
  void operator()(const tbb::blocked_range<uint32_t>& r) { bin_into(prims, r.begin(), r.end(), map, bins); }
  void join(const BinBody& o) { bins.add(o.bins, nb); }
};

// Large ranges: bins of chunks of kChunk primitives merged into `bins` (empty on entry: the merge with
// empty bins keeps the bits). Out of line, so that the many small ranges' calls to find() do not carry
// a second ~7 KiB Bins in their frame.
[[gnu::noinline]] void bin_parallel(const PrimRef* p, uint32_t begin, uint32_t end, const BinMap& map, Bins& bins) {
  BinBody body(p, map, map.bins);
  tbb::parallel_reduce(tbb::blocked_range<uint32_t>(begin, end, kChunk), body);
  bins.add(body.bins, map.bins);
}

}  // namespace

Range Splitter::make_range(uint32_t begin, uint32_t end, uint32_t depth) const {
  const Bounds b = bounds_of(prims_, begin, end, p_.parallel_threshold);
  Range r;
  r.begin = begin;
  r.end = end;
  r.box = b.box.box();
  r.cbox = b.cbox.box();
  r.depth = depth;
  return r;
}

// Wald 2007 binned SAH, as used for Benthin 2008 §4.1's binary BVH.
Split Splitter::find(const Range& r) const {
  Split best;  // median unless a plane is found
  const uint32_t n = r.size();
  // Depth budget: SAH only while a child could still be halved down to leaf_size within max_depth.
  if (uint64_t(r.depth) + 1 + median_levels(n, p_.leaf_size) > p_.max_depth) return best;
  const BinMap map(r.cbox, p_.bins);
  if (!map.usable[0] && !map.usable[1] && !map.usable[2]) return best;

  // Bins are ~7 KiB: on the stack only for the duration of this call, not across the recursion.
  const uint32_t nb = p_.bins;
  const bool small = n <= kSmallRange;
  Bins bins(small ? 0 : nb);
  if (small) {
    bin_small(prims_, r.begin, r.end, map, bins);
  } else {
    if (n < p_.parallel_threshold)
      bin_into(prims_, r.begin, r.end, map, bins);
    else
      bin_parallel(prims_, r.begin, r.end, map, bins);
    bins.set_used(nb);
  }

  // Sweep each axis over its non-empty bins: right-to-left suffix areas/counts, then left-to-right.
  // Planes between two non-empty bins all cost the same, and ties keep the first candidate (x before
  // y before z, lower plane first), so plane idx[j] + 1 stands for them: the same split as a sweep of
  // every bin, in at most n steps instead of `bins` for the many small ranges near the leaves. The
  // least cost is tracked without a branch (a mispredicted "new best" branch and its six stores were
  // the sweep's most expensive instructions); the winner's figures are read back after the sweeps.
  double best_cost = std::numeric_limits<double>::infinity();
  int best_axis = -1;
  uint32_t best_j = 0;
  // Written before read: no zeroing per call.
  std::array<std::array<double, kMaxBins>, 3> right_area, left_area;
  std::array<std::array<uint32_t, kMaxBins>, 3> right_count, left_count, idx;
  for (int a = 0; a < 3; ++a) {
    if (!map.usable[a]) continue;
    // The non-empty bins in order, from a mask: no branch per bin (which bins are empty is data; a
    // mispredicted branch per bin was 30 % of this function's samples on FlightHelmet).
    uint32_t m = 0;
    for (uint64_t used = bins.used[a]; used; used &= used - 1) idx[a][m++] = uint32_t(std::countr_zero(used));
    VBox acc;
    uint32_t cnt = 0;
    for (uint32_t j = m; j-- > 1;) {
      acc.add(bins.box[a][idx[a][j]].lo, bins.box[a][idx[a][j]].hi);
      cnt += bins.count[a][idx[a][j]];
      right_area[a][j] = half_area_sse(acc.lo, acc.hi);
      right_count[a][j] = cnt;
    }
    acc = VBox{};
    cnt = 0;
    __m128d least = _mm_set_sd(best_cost);
    for (uint32_t j = 1; j < m; ++j) {
      acc.add(bins.box[a][idx[a][j - 1]].lo, bins.box[a][idx[a][j - 1]].hi);
      cnt += bins.count[a][idx[a][j - 1]];
      const double la = half_area_sse(acc.lo, acc.hi);
      left_area[a][j] = la;
      left_count[a][j] = cnt;
      const double cost = la * cnt + right_area[a][j] * right_count[a][j];
      // cost < best (strict: ties keep the earlier plane), as a select.
      const bool better = cost < _mm_cvtsd_f64(least);
      least = _mm_min_sd(_mm_set_sd(cost), least);  // cost < least ? cost : least
      best_j = better ? j : best_j;
      best_axis = better ? a : best_axis;
    }
    best_cost = _mm_cvtsd_f64(least);
  }
  if (best_axis >= 0) {
    const int a = best_axis;
    const uint32_t j = best_j;
    best.median = false;
    best.axis = a;
    best.bin = idx[a][j - 1] + 1;
    best.left_area = left_area[a][j];
    best.right_area = right_area[a][j];
    best.left_count = left_count[a][j];
    best.right_count = right_count[a][j];
  }
  return best;
}

void Splitter::apply(const Range& r, const Split& s, Range& left, Range& right) const {
  if (s.median) {
    partition_median(r, left, right);
  } else {
    partition_sah(r, s, left, right);
  }
}

void Splitter::partition_median(const Range& r, Range& left, Range& right) const {
  int axis = 0;
  double widest = -1;
  for (int a = 0; a < 3; ++a) {
    const double e = double(r.cbox.hi[a]) - double(r.cbox.lo[a]);
    if (e > widest) {
      widest = e;
      axis = a;
    }
  }
  const uint32_t mid = r.begin + r.size() / 2;
  // (centroid, id) is a strict total order: the halves are the same sets whatever the input order.
  std::nth_element(prims_ + r.begin, prims_ + mid, prims_ + r.end, [axis](const PrimRef& a, const PrimRef& b) {
    const float ca = a.centroid(axis), cb = b.centroid(axis);
    return ca < cb || (ca == cb && a.id < b.id);
  });
  left = make_range(r.begin, mid, r.depth + 1);
  right = make_range(mid, r.end, r.depth + 1);
}

void Splitter::partition_sah(const Range& r, const Split& s, Range& left, Range& right) const {
  const BinMap map(r.cbox, p_.bins);
  const int axis = s.axis;
  const uint32_t split_bin = s.bin;
  auto is_left = [&](const PrimRef& p) { return uint32_t(map.bin(p, axis)) < split_bin; };
  Bounds lb, rb;
  uint32_t mid = 0;

  if (r.size() < p_.parallel_threshold || scratch_ == nullptr) {
    // In place, two-sided; every primitive is classified exactly once.
    uint32_t i = r.begin, j = r.end;
    for (;;) {
      while (i < j && is_left(prims_[i])) lb.add(prims_[i++]);
      while (i < j && !is_left(prims_[j - 1])) rb.add(prims_[--j]);
      if (i >= j) break;
      std::swap(prims_[i], prims_[j - 1]);
      lb.add(prims_[i++]);
      rb.add(prims_[--j]);
    }
    mid = i;
  } else {
    // Stable chunked partition: count per chunk, prefix offsets, scatter into scratch, copy back.
    const uint32_t chunks = (r.size() + kChunk - 1) / kChunk;
    struct Chunk {
      uint32_t left = 0, left_offset = 0, right_offset = 0;
      Bounds lb, rb;
    };
    std::vector<Chunk> c(chunks);
    auto chunk_range = [&](uint32_t k) {
      const uint32_t b = r.begin + k * kChunk;
      return std::pair<uint32_t, uint32_t>(b, std::min(r.end, b + kChunk));
    };
    tbb::parallel_for(uint32_t(0), chunks, [&](uint32_t k) {
      const auto [b, e] = chunk_range(k);
      for (uint32_t i = b; i < e; ++i) {
        if (is_left(prims_[i])) {
          ++c[k].left;
          c[k].lb.add(prims_[i]);
        } else {
          c[k].rb.add(prims_[i]);
        }
      }
    });
    uint32_t total_left = 0;
    for (uint32_t k = 0; k < chunks; ++k) {
      c[k].left_offset = total_left;
      total_left += c[k].left;
      lb.add(c[k].lb);
      rb.add(c[k].rb);
    }
    uint32_t right_seen = 0;
    for (uint32_t k = 0; k < chunks; ++k) {
      const auto [b, e] = chunk_range(k);
      c[k].right_offset = total_left + right_seen;
      right_seen += (e - b) - c[k].left;
    }
    tbb::parallel_for(uint32_t(0), chunks, [&](uint32_t k) {
      const auto [b, e] = chunk_range(k);
      uint32_t lo = r.begin + c[k].left_offset, ro = r.begin + c[k].right_offset;
      for (uint32_t i = b; i < e; ++i) scratch_[is_left(prims_[i]) ? lo++ : ro++] = prims_[i];
    });
    tbb::parallel_for(uint32_t(0), chunks, [&](uint32_t k) {
      const auto [b, e] = chunk_range(k);
      std::copy(scratch_ + b, scratch_ + e, prims_ + b);
    });
    mid = r.begin + total_left;
  }
  if (mid == r.begin || mid == r.end)  // cannot happen: the plane had primitives on both sides
    throw Error(ExitCode::kInternal, "binned SAH: empty side after partition");
  left.begin = r.begin;
  left.end = mid;
  left.box = lb.box.box();
  left.cbox = lb.cbox.box();
  left.depth = r.depth + 1;
  right.begin = mid;
  right.end = r.end;
  right.box = rb.box.box();
  right.cbox = rb.cbox.box();
  right.depth = r.depth + 1;
}

namespace {

void build_node(const Splitter& sp, BinaryTree& tree, const Range& r, uint32_t index) {
  BinaryNode& node = tree.nodes[index];
  node.box = r.box;
  node.begin = r.begin;
  node.count = r.size();
  node.right = kNone;
  if (r.size() <= sp.params().leaf_size) return;
  Range left, right;
  sp.apply(r, sp.find(r), left, right);
  // The subtree over [begin, end) owns slots [index, index + 2·size − 1): left from index + 1,
  // right from index + 2·left.size().
  const uint32_t li = index + 1, ri = index + 2 * left.size();
  node.right = ri;
  if (r.size() >= sp.params().task_threshold) {
    tbb::parallel_invoke([&] { build_node(sp, tree, left, li); }, [&] { build_node(sp, tree, right, ri); });
  } else {
    build_node(sp, tree, left, li);
    build_node(sp, tree, right, ri);
  }
}

}  // namespace

BinaryTree build_binary(Splitter& splitter, uint32_t n) {
  BinaryTree tree;
  if (n == 0) return tree;
  tree.nodes.resize(size_t(2) * n - 1);
  build_node(splitter, tree, splitter.make_range(0, n, 0), 0);
  return tree;
}

}  // namespace rtp::bvh
