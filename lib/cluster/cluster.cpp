// Batching points: objects (world-space pieces of unique meshes, instances of instanced meshes)
// clustered top-down by binned SAH and cut where a subtree fits the chunk target (Molenaar 2019 §3.1).
#include "cluster/cluster.h"

#include <algorithm>
#include <array>
#include <limits>

#include "core/error.h"
#include "mesh/mesh.h"

namespace rtp {
namespace {

struct Object {
  Aabb box;
  Vec3d centroid;
  uint64_t weight = 0;
  uint32_t piece = kNoIndex;     // a unique piece, or
  uint32_t instance = kNoIndex;  // an instance of an instanced mesh
};

// Binary cluster tree over objects, built top-down (explicit stack: no recursion depth limit).
struct BinNode {
  Aabb box;
  uint32_t left = kNoIndex, right = kNoIndex;  // inner node children
  uint32_t point = kNoIndex;                   // leaf: batching point index
};

Aabb instance_bounds(const Scene& s, const Instance& in, const Aabb& local) {
  Aabb b;
  for (int c = 0; c < 8; ++c)
    b.grow(in.transform.apply({(c & 1) ? local.hi.x : local.lo.x, (c & 2) ? local.hi.y : local.lo.y,
                               (c & 4) ? local.hi.z : local.lo.z}));
  (void)s;
  return b;
}

// Molenaar 2019 §3.1 (after Embree's binned SAH): split objects[b,e) by the best of 3 axes × 16 bins
// on centroids, cost Σ SA(child) · weight(child); median split when every centroid is equal.
size_t split_objects(std::vector<Object>& objs, size_t b, size_t e) {
  constexpr int kBins = 16;
  Aabb cb;
  for (size_t i = b; i < e; ++i) cb.grow(objs[i].centroid);
  double best_cost = std::numeric_limits<double>::infinity();
  int best_axis = -1, best_bin = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const double lo = cb.lo[axis], ext = cb.hi[axis] - cb.lo[axis];
    if (!(ext > 0)) continue;
    std::array<Aabb, kBins> box;
    std::array<uint64_t, kBins> w{};
    std::array<size_t, kBins> n{};
    for (size_t i = b; i < e; ++i) {
      const int k = std::min(kBins - 1, int((objs[i].centroid[axis] - lo) / ext * kBins));
      box[size_t(k)].grow(objs[i].box);
      w[size_t(k)] += objs[i].weight + 1;
      ++n[size_t(k)];
    }
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
      const double cost = acc.surface_area() * double(wa) + right_cost[size_t(k + 1)];
      if (cost < best_cost) {
        best_cost = cost;
        best_axis = axis;
        best_bin = k;
      }
    }
  }
  if (best_axis < 0) return b + (e - b) / 2;  // all centroids equal: split by index
  const double lo = cb.lo[best_axis], ext = cb.hi[best_axis] - cb.lo[best_axis];
  auto mid = std::stable_partition(objs.begin() + long(b), objs.begin() + long(e), [&](const Object& o) {
    return std::min(kBins - 1, int((o.centroid[best_axis] - lo) / ext * kBins)) <= best_bin;
  });
  return size_t(mid - objs.begin());
}

// Collapses the binary cluster tree into the 4-wide top level: each node takes up to 4 descendants,
// always opening the child with the largest surface area (Benthin 2008 §4.2 style pull-up).
std::vector<fmt::TopNode> collapse_top(const std::vector<BinNode>& bin) {
  std::vector<fmt::TopNode> top;
  if (bin.empty()) return top;
  struct Item { uint32_t bin_node, parent, slot, depth; };
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
    if (root.point != kNoIndex) kids = {it.bin_node};
    else kids = {root.left, root.right};
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
      if (k.point != kNoIndex) node.child[l] = fmt::TopNode::kLeafBit | k.point;
      else queue.push_back({kids[l], id, uint32_t(l), it.depth + 1});
    }
  }
  return top;
}

}  // namespace

uint64_t default_chunk_target(const Scene& scene, ChunkBy by) {
  const uint64_t total = by == ChunkBy::kInstanced ? scene.instanced_triangles() : scene.unique_triangles();
  return std::clamp<uint64_t>(total / 64, uint64_t(1) << 16, uint64_t(1) << 22);
}

Plan plan_batching_points(const Scene& scene, const ClusterOptions& opt) {
  Plan plan;
  plan.chunk_by = opt.chunk_by;
  plan.chunk_target = opt.chunk_target ? opt.chunk_target : default_chunk_target(scene, opt.chunk_by);
  std::vector<uint32_t> uses(scene.meshes.size(), 0);
  for (const Instance& in : scene.instances) ++uses[in.mesh];
  plan.mesh_instanced.resize(scene.meshes.size());
  for (size_t m = 0; m < uses.size(); ++m) plan.mesh_instanced[m] = uses[m] >= 2;

  // Mesh segments: instanced meshes in mesh order, packed up to the segment target.
  const uint64_t seg_target = opt.segment_target ? opt.segment_target : plan.chunk_target;
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

  // Objects.
  std::vector<Aabb> local(scene.meshes.size());
  for (size_t m = 0; m < scene.meshes.size(); ++m) local[m] = scene.meshes[m].local_bounds();
  const uint64_t piece_max = std::max<uint64_t>(1, uint64_t(double(plan.chunk_target) * opt.piece_fraction));
  std::vector<Object> objs;
  for (size_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& in = scene.instances[i];
    const Mesh& src = scene.meshes[in.mesh];
    if (plan.mesh_instanced[in.mesh]) {
      Object o;
      o.box = instance_bounds(scene, in, local[in.mesh]);
      o.centroid = o.box.center();
      o.weight = opt.chunk_by == ChunkBy::kInstanced ? src.triangle_count() : 1;
      o.instance = uint32_t(i);
      objs.push_back(o);
      continue;
    }
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
      Object o;
      o.box = instance_bounds(scene, in, piece.mesh.local_bounds());
      o.centroid = o.box.center();
      o.weight = piece.mesh.triangle_count();
      o.piece = uint32_t(plan.pieces.size());
      plan.pieces.push_back(std::move(piece));
      objs.push_back(o);
    }
  }
  if (objs.empty()) return plan;

  // Top-down SAH cut at the target (explicit stack, left subtree first: deterministic order).
  std::vector<BinNode> bin(1);
  struct Task { size_t b, e; uint32_t node; };
  std::vector<Task> stack = {{0, objs.size(), 0}};
  while (!stack.empty()) {
    const Task t = stack.back();
    stack.pop_back();
    Aabb box;
    uint64_t weight = 0;
    for (size_t i = t.b; i < t.e; ++i) {
      box.grow(objs[i].box);
      weight += objs[i].weight;
    }
    bin[t.node].box = box;
    if (weight <= plan.chunk_target || t.e - t.b == 1) {
      BatchingPoint bp;
      bp.bounds = box;
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
      bin[t.node].point = uint32_t(plan.points.size());
      plan.points.push_back(std::move(bp));
      continue;
    }
    const size_t mid = split_objects(objs, t.b, t.e);
    const uint32_t l = uint32_t(bin.size()), r = l + 1;
    bin.resize(bin.size() + 2);
    bin[t.node].left = l;
    bin[t.node].right = r;
    stack.push_back({mid, t.e, r});
    stack.push_back({t.b, mid, l});
  }
  plan.top = collapse_top(bin);
  return plan;
}

}  // namespace rtp
