// Batching points: objects (world-space pieces of unique meshes, instances of instanced meshes)
// clustered top-down by binned SAH and cut where a subtree fits the chunk target (Molenaar 2019 §3.1).
#include "cluster/cluster.h"

#include <tbb/concurrent_vector.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <array>
#include <limits>

#include "core/error.h"
#include "core/parallel.h"
#include "mesh/mesh.h"

namespace rtp {
namespace {

// 64 bytes, one cache line (the centroid is the box's centre, computed where it is used): the cut reads
// every object once per level.
struct Object {
  Aabb box;
  uint64_t weight = 0;
  uint32_t piece = kNoIndex;     // a unique piece, or
  uint32_t instance = kNoIndex;  // an instance of an instanced mesh
};
static_assert(sizeof(Object) == 64);

// Binary cluster tree over objects, as collapse_top reads it (laid out from the Cutter's tree).
struct BinNode {
  Aabb box;
  uint32_t left = kNoIndex, right = kNoIndex;  // inner node children
  uint32_t point = kNoIndex;                   // leaf: batching point index
};

Aabb instance_bounds(const Scene& s, const Instance& in, const Aabb& local) {
  Aabb b;
  for (int c = 0; c < 8; ++c)
    b.grow(in.transform.apply(
        {(c & 1) ? local.hi.x : local.lo.x, (c & 2) ? local.hi.y : local.lo.y, (c & 4) ? local.hi.z : local.lo.z}));
  (void)s;
  return b;
}

// Ranges of at least this many objects are binned and partitioned in parallel (a 10^6-instance scene's
// first levels); smaller ones serially. Every reduction here is a min/max of boxes or an integer sum,
// so the result does not depend on how TBB splits the range.
constexpr size_t kParallelObjects = size_t(1) << 15;
constexpr int kBins = 16;

// Aabb::grow(b), inline (as calls, with the binning's three per object, they were most of the cut's
// instructions): an empty box adds nothing, and a box with lo <= hi grows acc by lo and hi alike.
[[gnu::always_inline]] inline void grow_box(Aabb& acc, const Aabb& b) {
  if (b.empty()) return;
  for (int i = 0; i < 3; ++i) acc.lo[i] = std::min(acc.lo[i], b.lo[i]), acc.hi[i] = std::max(acc.hi[i], b.hi[i]);
}

// Per axis and bin: the objects' boxes, weights and counts (Molenaar 2019 §3.1, after Embree's binning).
struct Bins {
  std::array<std::array<Aabb, kBins>, 3> box{};
  std::array<std::array<uint64_t, kBins>, 3> w{};
  std::array<std::array<size_t, kBins>, 3> n{};
  void join(const Bins& o) {
    for (int a = 0; a < 3; ++a)
      for (int k = 0; k < kBins; ++k) {
        box[size_t(a)][size_t(k)].grow(o.box[size_t(a)][size_t(k)]);
        w[size_t(a)][size_t(k)] += o.w[size_t(a)][size_t(k)];
        n[size_t(a)][size_t(k)] += o.n[size_t(a)][size_t(k)];
      }
  }
};

double centroid(const Object& o, int axis) { return (o.box.lo[axis] + o.box.hi[axis]) * 0.5; }  // = box.center()

int bin_of(double c, double lo, double ext) { return std::min(kBins - 1, int((c - lo) / ext * kBins)); }

// Reduces f(objects[i], acc) over [b, e), in parallel for large ranges; join merges two accumulators.
template <class Acc, class F, class J>
Acc reduce_objects(const std::vector<Object>& objs, size_t b, size_t e, const F& f, const J& join) {
  auto run = [&](size_t lo, size_t hi, Acc acc) {
    for (size_t i = lo; i < hi; ++i) f(objs[i], acc);
    return acc;
  };
  if (e - b < kParallelObjects) return run(b, e, Acc{});
  return tbb::parallel_reduce(
      tbb::blocked_range<size_t>(b, e, 4096), Acc{},
      [&](const tbb::blocked_range<size_t>& r, Acc acc) { return run(r.begin(), r.end(), std::move(acc)); },
      [&](Acc x, const Acc& y) {
        join(x, y);
        return x;
      });
}

// A node's objects summed in one pass: their box, their centroids' box and their weight.
struct BoxWeight {
  Aabb box, centroids;
  uint64_t weight = 0;
  // Inline: as Aabb::grow calls these were 5 % of a 10^6-instance convert's samples.
  [[gnu::always_inline]] void add(const Object& o) {
    grow_box(box, o.box);
    const Vec3d c = o.box.center();
    for (int i = 0; i < 3; ++i)
      centroids.lo[i] = std::min(centroids.lo[i], c[i]), centroids.hi[i] = std::max(centroids.hi[i], c[i]);
    weight += o.weight;
  }
  void join(const BoxWeight& y) {
    box.grow(y.box);
    centroids.grow(y.centroids);
    weight += y.weight;
  }
};

// A stable partition of [b, e) by `left` that sums each side's BoxWeight on the way (the children's
// bounds without another pass over their objects: on a 10^6-instance scene each pass is 64 MB per
// level). Left objects move down in place, right ones through scratch[b, e); large ranges in parallel
// by blocks (flags, per-block counts and sums, a prefix, a scatter), keeping the serial order exactly.
// Sums are min/max and integer additions: the same whatever the blocks. `scratch` is as long as objs,
// shared by every range (ranges cut in parallel are disjoint).
template <class P>
size_t stable_partition_objects(std::vector<Object>& objs, std::vector<Object>& scratch, size_t b, size_t e, const P& left,
                                BoxWeight& lw, BoxWeight& rw) {
  if (scratch.size() < objs.size())
    throw Error(ExitCode::kInternal, "stable_partition_objects: scratch shorter than the objects");
  if (e - b < kParallelObjects) {
    // Without a branch on the side (which side is data: half the objects would mispredict).
    size_t w = b, r = b;
    BoxWeight* sums[2] = {&rw, &lw};
    Object* to[2] = {scratch.data(), objs.data()};
    for (size_t i = b; i < e; ++i) {
      const Object o = objs[i];
      const size_t l = left(o) ? 1 : 0;
      sums[l]->add(o);
      to[l][l ? w : r] = o;  // w <= i: a slot already read
      w += l;
      r += 1 - l;
    }
    std::copy(scratch.begin() + long(b), scratch.begin() + long(r), objs.begin() + long(w));
    return w;
  }
  constexpr size_t kBlock = 8192;
  const size_t n = e - b, blocks = (n + kBlock - 1) / kBlock;
  std::vector<uint8_t> flag(n);
  std::vector<size_t> lefts(blocks + 1, 0);
  std::vector<BoxWeight> lsum(blocks), rsum(blocks);
  tbb::parallel_for(size_t(0), blocks, [&](size_t k) {
    size_t c = 0;
    for (size_t i = k * kBlock; i < std::min(n, (k + 1) * kBlock); ++i) {
      const Object& o = objs[b + i];
      const bool l = left(o);
      flag[i] = l ? 1 : 0;
      c += l ? 1 : 0;
      (l ? lsum[k] : rsum[k]).add(o);
    }
    lefts[k + 1] = c;
  });
  for (size_t k = 0; k < blocks; ++k) {
    lefts[k + 1] += lefts[k];
    lw.join(lsum[k]);
    rw.join(rsum[k]);
  }
  const size_t total_left = lefts[blocks];
  Object* out = scratch.data() + b;
  tbb::parallel_for(size_t(0), blocks, [&](size_t k) {
    size_t l = lefts[k], r = total_left + k * kBlock - lefts[k];
    for (size_t i = k * kBlock; i < std::min(n, (k + 1) * kBlock); ++i) out[flag[i] ? l++ : r++] = objs[b + i];
  });
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kBlock), [&](const tbb::blocked_range<size_t>& r) {
    std::copy(out + r.begin(), out + r.end(), objs.begin() + long(b + r.begin()));
  });
  return b + total_left;
}

// Molenaar 2019 §3.1 (after Embree's binned SAH): split objects[b,e) by the best of 3 axes × 16 bins
// on centroids, cost Σ SA(child) · weight(child); median split when every centroid is equal.
// `cb`: the bounds of the objects' centroids; lw, rw: the two sides' sums.
size_t split_objects(std::vector<Object>& objs, std::vector<Object>& scratch, size_t b, size_t e, const Aabb& cb, BoxWeight& lw,
                     BoxWeight& rw) {
  std::array<double, 3> lo{}, ext{};
  for (int a = 0; a < 3; ++a) lo[size_t(a)] = cb.lo[a], ext[size_t(a)] = cb.hi[a] - cb.lo[a];
  const Bins bins = reduce_objects<Bins>(
      objs, b, e,
      [&](const Object& o, Bins& acc) {
        for (int a = 0; a < 3; ++a) {
          if (!(ext[size_t(a)] > 0)) continue;
          const size_t k = size_t(bin_of(centroid(o, a), lo[size_t(a)], ext[size_t(a)]));
          grow_box(acc.box[size_t(a)][k], o.box);
          acc.w[size_t(a)][k] += o.weight + 1;
          ++acc.n[size_t(a)][k];
        }
      },
      [](Bins& x, const Bins& y) { x.join(y); });
  double best_cost = std::numeric_limits<double>::infinity();
  int best_axis = -1, best_bin = 0;
  for (int axis = 0; axis < 3; ++axis) {
    if (!(ext[size_t(axis)] > 0)) continue;
    const auto& box = bins.box[size_t(axis)];
    const auto& w = bins.w[size_t(axis)];
    const auto& n = bins.n[size_t(axis)];
    std::array<double, kBins> right_cost{};
    Aabb acc;
    uint64_t wa = 0;
    for (int k = kBins - 1; k > 0; --k) {
      acc.grow(box[size_t(k)]);
      wa += w[size_t(k)];
      right_cost[size_t(k)] = acc.surface_area() * double(wa);
    }
    acc = Aabb{};
    wa = 0;
    size_t na = 0;
    for (int k = 0; k < kBins - 1; ++k) {
      acc.grow(box[size_t(k)]);
      wa += w[size_t(k)];
      na += n[size_t(k)];
      if (na == 0 || na == e - b) continue;
      const double cost = acc.surface_area() * double(wa) + right_cost[size_t(k) + 1];
      if (cost < best_cost) {
        best_cost = cost;
        best_axis = axis;
        best_bin = k;
      }
    }
  }
  if (best_axis < 0) {  // all centroids equal: split by index
    const size_t mid = b + (e - b) / 2;
    for (size_t i = b; i < e; ++i) (i < mid ? lw : rw).add(objs[i]);
    return mid;
  }
  const double blo = lo[size_t(best_axis)], bext = ext[size_t(best_axis)];
  return stable_partition_objects(
      objs, scratch, b, e, [&](const Object& o) { return bin_of(centroid(o, best_axis), blo, bext) <= best_bin; }, lw, rw);
}

// Collapses the binary cluster tree into the 4-wide top level: each node takes up to 4 descendants,
// always opening the child with the largest surface area (Benthin 2008 §4.2 style pull-up).
std::vector<fmt::TopNode> collapse_top(const std::vector<BinNode>& bin) {
  std::vector<fmt::TopNode> top;
  if (bin.empty()) return top;
  struct Item {
    uint32_t bin_node, parent, slot, depth;
  };
  std::vector<Item> queue = {{0, fmt::TopNode::kEmpty, 0, 0}};
  for (size_t q = 0; q < queue.size(); ++q) {
    const Item it = queue[q];
    const uint32_t id = uint32_t(top.size());
    top.emplace_back();
    fmt::TopNode& node = top.back();
    node.parent = it.parent;
    node.slot = it.slot;
    node.depth = it.depth;
    node.reserved = 0;
    if (it.parent != fmt::TopNode::kEmpty) top[it.parent].child[it.slot] = id;
    std::vector<uint32_t> kids;
    const BinNode& root = bin[it.bin_node];
    if (root.point != kNoIndex)
      kids = {it.bin_node};
    else
      kids = {root.left, root.right};
    while (kids.size() < 4) {
      int open = -1;
      double sa = -1;
      for (size_t k = 0; k < kids.size(); ++k)
        if (bin[kids[k]].point == kNoIndex && bin[kids[k]].box.surface_area() > sa) {
          sa = bin[kids[k]].box.surface_area();
          open = int(k);
        }
      if (open < 0) break;
      const BinNode& o = bin[kids[size_t(open)]];
      kids[size_t(open)] = o.left;
      kids.insert(kids.begin() + open + 1, o.right);
    }
    for (int l = 0; l < 4; ++l) {
      for (int a = 0; a < 3; ++a) {
        node.lo[a][l] = std::numeric_limits<float>::infinity();
        node.hi[a][l] = -std::numeric_limits<float>::infinity();
      }
      node.child[l] = fmt::TopNode::kEmpty;
    }
    for (size_t l = 0; l < kids.size(); ++l) {
      const BinNode& k = bin[kids[l]];
      for (int a = 0; a < 3; ++a) {  // round outward so the float box contains the double box
        node.lo[a][l] = std::nextafter(float(k.box.lo[a]), -std::numeric_limits<float>::infinity());
        node.hi[a][l] = std::nextafter(float(k.box.hi[a]), std::numeric_limits<float>::infinity());
      }
      if (k.point != kNoIndex)
        node.child[l] = fmt::TopNode::kLeafBit | k.point;
      else
        queue.push_back({kids[l], id, uint32_t(l), it.depth + 1});
    }
  }
  return top;
}

// One node of the cluster tree while it is cut: an inner node's two children, or a leaf's point.
struct CutNode {
  Aabb box;
  uint32_t kid[2] = {kNoIndex, kNoIndex};
  BatchingPoint point;
};

// Molenaar 2019 §3.1: the top-down cut where a subtree's weight fits the target. Each task follows the
// larger child itself and hands the smaller one to another task when it is big enough to be worth one
// (so neither the call stack nor a task chain grows with a lopsided split).
struct Cutter {
  const Scene& scene;
  const Plan& plan;
  std::vector<Object>& objs;
  std::vector<Object> scratch;  // stable_partition_objects' copies, one array for every range
  tbb::concurrent_vector<CutNode> nodes;
  tbb::task_group tasks;
  static constexpr size_t kTaskObjects = 1024;

  Cutter(const Scene& s, const Plan& p, std::vector<Object>& o) : scene(s), plan(p), objs(o) {}

  void run() {
    scratch.resize(objs.size());  // stable_partition_objects' right sides
    nodes.grow_by(1);
    const BoxWeight root = reduce_objects<BoxWeight>(
        objs, 0, objs.size(), [](const Object& o, BoxWeight& acc) { acc.add(o); },
        [](BoxWeight& x, const BoxWeight& y) { x.join(y); });
    cut(0, objs.size(), 0, root);
    tasks.wait();
  }

  // [b0, e0) with its sums bw0 (the parent's partition made them: no pass of its own).
  void cut(size_t b0, size_t e0, uint32_t id0, const BoxWeight& bw0) {
    struct Range {
      size_t b, e;
      uint32_t node;
      BoxWeight bw;
    };
    std::vector<Range> stack = {{b0, e0, id0, bw0}};
    while (!stack.empty()) {
      const Range t = stack.back();
      stack.pop_back();
      const BoxWeight& bw = t.bw;
      CutNode& node = nodes[t.node];
      node.box = bw.box;
      if (bw.weight <= plan.chunk_target || t.e - t.b == 1) {
        BatchingPoint& bp = node.point;
        bp.bounds = bw.box;
        for (size_t i = t.b; i < t.e; ++i) {
          if (objs[i].piece != kNoIndex) {
            bp.pieces.push_back(objs[i].piece);
            bp.unique_triangles += plan.pieces[objs[i].piece].mesh.triangle_count();
          } else {
            bp.instances.push_back(objs[i].instance);
            bp.instanced_triangles += scene.meshes[scene.instances[objs[i].instance].mesh].triangle_count();
          }
        }
        std::sort(bp.pieces.begin(), bp.pieces.end());
        std::sort(bp.instances.begin(), bp.instances.end());
        continue;
      }
      BoxWeight lw, rw;
      const size_t mid = split_objects(objs, scratch, t.b, t.e, bw.centroids, lw, rw);
      const uint32_t l = uint32_t(nodes.grow_by(2) - nodes.begin()), r = l + 1;
      node.kid[0] = l;
      node.kid[1] = r;
      const Range left{t.b, mid, l, lw}, right{mid, t.e, r, rw};
      const bool left_smaller = mid - t.b < t.e - mid;
      const Range small = left_smaller ? left : right, large = left_smaller ? right : left;
      if (small.e - small.b >= kTaskObjects)
        tasks.run([this, small] { cut(small.b, small.e, small.node, small.bw); });
      else
        stack.push_back(small);
      stack.push_back(large);
    }
  }
};

uint64_t target_for(uint64_t total_triangles) {
  return std::clamp<uint64_t>(total_triangles / 64, uint64_t(1) << 16, uint64_t(1) << 22);
}

}  // namespace

uint64_t default_chunk_target(const Scene& scene, ChunkBy by) {
  return target_for(by == ChunkBy::kInstanced ? scene.instanced_triangles() : scene.unique_triangles());
}

Plan plan_batching_points(const Scene& scene, const ClusterOptions& opt) {
  Plan plan;
  plan.chunk_by = opt.chunk_by;
  // One pass over the instances for both the uses and the instanced total (each pass over 10^6
  // instances of 120 B costs this VM ~0.1-0.2 s).
  std::vector<uint32_t> uses(scene.meshes.size(), 0);
  for (const Instance& in : scene.instances) ++uses[in.mesh];
  uint64_t instanced = 0;
  for (size_t m = 0; m < uses.size(); ++m) instanced += uint64_t(uses[m]) * scene.meshes[m].triangle_count();
  plan.chunk_target = opt.chunk_target ? opt.chunk_target
                                       : target_for(opt.chunk_by == ChunkBy::kInstanced ? instanced : scene.unique_triangles());
  plan.mesh_instanced.resize(scene.meshes.size());
  for (size_t m = 0; m < uses.size(); ++m) plan.mesh_instanced[m] = uses[m] >= 2;

  // Mesh segments: instanced meshes in mesh order, packed up to the segment target. By default the
  // target is derived from what the segments hold (their unique triangles), not from the instanced
  // total that sizes batching points: forest-2k's 12 trees (205k triangles) were one 12.8 MB segment,
  // loaded whole for any one tree and compressed by one thread while the other waited.
  uint64_t segment_triangles = 0;
  for (size_t m = 0; m < uses.size(); ++m)
    if (plan.mesh_instanced[m]) segment_triangles += scene.meshes[m].triangle_count();
  const uint64_t seg_target =
      opt.segment_target ? opt.segment_target : std::min(plan.chunk_target, target_for(segment_triangles));
  plan.mesh_segment.assign(scene.meshes.size(), kNoIndex);
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    if (!plan.mesh_instanced[m]) continue;
    const uint64_t t = scene.meshes[m].triangle_count();
    if (plan.segments.empty() || (plan.segments.back().triangles + t > seg_target && !plan.segments.back().meshes.empty()))
      plan.segments.emplace_back();
    plan.segments.back().meshes.push_back(uint32_t(m));
    plan.segments.back().triangles += t;
    plan.mesh_segment[m] = uint32_t(plan.segments.size() - 1);
  }

  // Objects, in instance order: an instance of an instanced mesh is one object (the boxes computed in
  // parallel below), the single instance of a unique mesh one per piece. The unique meshes are split
  // in parallel (each on its own), then their pieces are numbered serially in instance order.
  // Local bounds once per instanced mesh (a unique mesh's are its pieces'); the converter reads them.
  std::vector<Aabb>& local = plan.mesh_bounds;
  local.assign(scene.meshes.size(), Aabb{});
  tbb::parallel_for(size_t(0), scene.meshes.size(), [&](size_t m) {
    if (plan.mesh_instanced[m]) local[m] = scene.meshes[m].local_bounds();
  });
  const uint64_t piece_max = std::max<uint64_t>(1, uint64_t(double(plan.chunk_target) * opt.piece_fraction));
  const size_t n_inst = scene.instances.size();
  std::vector<size_t> first(n_inst + 1, 0);  // instance i's objects: [first[i], first[i + 1])
  std::vector<size_t> unique_inst;
  for (size_t i = 0; i < n_inst; ++i)
    if (!plan.mesh_instanced[scene.instances[i].mesh]) unique_inst.push_back(i);
  std::vector<std::vector<UniquePiece>> split(unique_inst.size());
  parallel_for_lowest_error(unique_inst.size(), [&](size_t u) {  // errors: the first instance's, as in a serial loop
    const size_t i = unique_inst[u];
    const Instance& in = scene.instances[i];
    const Mesh& src = scene.meshes[in.mesh];
    // The single instance of a unique mesh, split into pieces that stay in the mesh's local space
    // (with the instance's transform: no precision lost far from the origin). The source map
    // temporarily carries the original triangle index through split_mesh.
    Mesh local_copy = src;
    for (size_t t = 0; t < local_copy.source.size(); ++t) local_copy.source[t] = {0, uint32_t(t)};
    std::vector<Mesh> parts;
    if (local_copy.triangle_count() > piece_max)
      parts = split_mesh(local_copy, uint32_t(std::min<uint64_t>(piece_max, 0xffffffffu)));
    else
      parts.push_back(std::move(local_copy));
    for (Mesh& part : parts) {
      UniquePiece piece;
      piece.instance = uint32_t(i);
      piece.prim.resize(part.source.size());
      for (size_t t = 0; t < part.source.size(); ++t) {
        piece.prim[t] = part.source[t].triangle;
        part.source[t] = src.source[piece.prim[t]];
      }
      piece.mesh = std::move(part);
      piece.bounds = piece.mesh.local_bounds();
      split[u].push_back(std::move(piece));
    }
  });
  std::vector<std::pair<size_t, std::vector<Object>>> unique_objs;
  for (size_t i = 0, u = 0; i < n_inst; ++i) {
    if (plan.mesh_instanced[scene.instances[i].mesh]) {
      first[i + 1] = first[i] + 1;
      continue;
    }
    std::vector<Object> mine;
    for (UniquePiece& piece : split[u]) {
      Object o;
      o.box = instance_bounds(scene, scene.instances[i], piece.bounds);
      o.weight = piece.mesh.triangle_count();
      o.piece = uint32_t(plan.pieces.size());
      plan.pieces.push_back(std::move(piece));
      mine.push_back(o);
    }
    ++u;
    first[i + 1] = first[i] + mine.size();
    unique_objs.emplace_back(i, std::move(mine));
  }
  std::vector<Object> objs(first[n_inst]);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n_inst, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const Instance& in = scene.instances[i];
      if (!plan.mesh_instanced[in.mesh]) continue;
      Object& o = objs[first[i]];
      o.box = instance_bounds(scene, in, local[in.mesh]);
      o.weight = opt.chunk_by == ChunkBy::kInstanced ? scene.meshes[in.mesh].triangle_count() : 1;
      o.instance = uint32_t(i);
    }
  });
  for (auto& [i, mine] : unique_objs) std::copy(mine.begin(), mine.end(), objs.begin() + long(first[i]));
  if (objs.empty()) return plan;

  // Top-down SAH cut at the target, subtrees in parallel (Cutter); then the leaves numbered left to
  // right, as the serial cut numbered them, whatever order the tasks ran in.
  Cutter cut(scene, plan, objs);
  cut.run();
  std::vector<BinNode> bin(cut.nodes.size());
  std::vector<uint32_t> stack = {0};
  while (!stack.empty()) {
    const uint32_t id = stack.back();
    stack.pop_back();
    CutNode& c = cut.nodes[id];
    bin[id].box = c.box;
    if (c.kid[0] == kNoIndex) {
      bin[id].point = uint32_t(plan.points.size());
      plan.points.push_back(std::move(c.point));
      continue;
    }
    bin[id].left = c.kid[0];
    bin[id].right = c.kid[1];
    stack.push_back(c.kid[1]);
    stack.push_back(c.kid[0]);
  }
  plan.top = collapse_top(bin);
  return plan;
}

}  // namespace rtp
