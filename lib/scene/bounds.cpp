// Exact world bounds of instanced meshes without transforming every vertex of every instance:
// the extreme of a linear function over a point set, found by branch and bound on a point tree.
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <limits>
#include <memory>
#include <mutex>
#include <numeric>

#include "scene/scene.h"

namespace rtp {

Aabb Mesh::local_bounds() const {
  Aabb b;
  for (uint32_t i : indices) b.grow(to_d(positions[i]));
  return b;
}

uint64_t Scene::unique_triangles() const {
  uint64_t n = 0;
  for (const Mesh& m : meshes) n += m.triangle_count();
  return n;
}

uint64_t Scene::instanced_triangles() const {
  uint64_t n = 0;
  for (const Instance& i : instances) n += meshes[i.mesh].triangle_count();
  return n;
}

namespace {

// The vertices a mesh's triangles use, searched for the extreme of a linear function. The first
// kScansBeforeTree searches scan every point; after that a median-split tree (leaves of <= 16 points,
// built once, over its own copy of the points) prunes by box bounds. A tree costs about as many passes
// over the points as kScansBeforeTree scans, so the few meshes searched often get one and the rest
// never pay for it: FlightHelmet's six meshes (one instance each) and forest-2k's twelve (of which only
// the instances on the scene's faces are searched) had spent 4 % and 11 % of their converts building
// trees up front. Scan or tree, the answer is the same exact maximum (+0 for a zero, whichever sign
// the maximizing product had), so it does not depend on which one a thread happened to use.
class PointSet {
 public:
  explicit PointSet(const Mesh& m) {
    std::vector<uint8_t> used(m.positions.size(), 0);
    for (uint32_t i : m.indices) used[i] = 1;
    for (size_t i = 0; i < used.size(); ++i)
      if (used[i]) pts_.push_back(to_d(m.positions[i])), box_.grow(pts_.back());
  }
  bool empty() const { return pts_.empty(); }
  const Aabb& box() const { return box_; }
  // max over the box of dot(r, p), evaluated in dot()'s order: rounding is monotone, so it never
  // undercuts a point of the box.
  static double box_bound(const Vec3d& r, const Aabb& b) {
    return std::max(r.x * b.lo.x, r.x * b.hi.x) + std::max(r.y * b.lo.y, r.y * b.hi.y) + std::max(r.z * b.lo.z, r.z * b.hi.z);
  }
  // max over the points of dot(r, p): exact.
  double support(const Vec3d& r) const {
    if (!tree_ready_.load(std::memory_order_acquire)) {
      if (scans_.fetch_add(1, std::memory_order_relaxed) < kScansBeforeTree) {
        double best = -std::numeric_limits<double>::infinity();
        for (const Vec3d& p : pts_) best = std::max(best, dot(r, p));
        return best + 0.0;
      }
      std::call_once(once_, [this] {
        tree_pts_ = pts_;
        build(0, uint32_t(tree_pts_.size()));
        tree_ready_.store(true, std::memory_order_release);
      });
    }
    double best = -std::numeric_limits<double>::infinity();
    uint32_t stack[128];
    int sp = 0;
    stack[sp++] = 0;
    while (sp) {
      const Node& n = nodes_[stack[--sp]];
      if (box_bound(r, n.box) <= best) continue;
      if (!n.left) {
        for (uint32_t i = n.begin; i < n.end; ++i) best = std::max(best, dot(r, tree_pts_[i]));
      } else {
        stack[sp++] = n.right;
        stack[sp++] = n.left;
      }
    }
    return best + 0.0;
  }

 private:
  static constexpr uint32_t kScansBeforeTree = 32;
  struct Node {
    Aabb box;
    uint32_t begin, end, left, right;
  };                                              // left = 0: leaf
  uint32_t build(uint32_t b, uint32_t e) const {  // once, under once_
    const uint32_t id = uint32_t(nodes_.size());
    nodes_.push_back({Aabb{}, b, e, 0, 0});
    Aabb box;
    for (uint32_t i = b; i < e; ++i) box.grow(tree_pts_[i]);
    nodes_[id].box = box;
    if (e - b > 16) {
      const Vec3d ext = box.extent();
      const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
      const uint32_t mid = b + (e - b) / 2;
      std::nth_element(tree_pts_.begin() + b, tree_pts_.begin() + mid, tree_pts_.begin() + e,
                       [axis](const Vec3d& p, const Vec3d& q) { return p[axis] < q[axis]; });
      const uint32_t l = build(b, mid), r = build(mid, e);
      nodes_[id].left = l;
      nodes_[id].right = r;
    }
    return id;
  }
  std::vector<Vec3d> pts_;
  Aabb box_;
  mutable std::atomic<uint32_t> scans_{0};
  mutable std::atomic<bool> tree_ready_{false};
  mutable std::once_flag once_;
  mutable std::vector<Node> nodes_;
  mutable std::vector<Vec3d> tree_pts_;
};

// World bounds of one instance of the mesh whose point tree is `t`.
Aabb instance_bounds(const PointSet& t, const Instance& inst) {
  Aabb acc;
  if (t.empty()) return acc;
  for (int row = 0; row < 3; ++row) {
    const Vec3d w{inst.transform(row, 0), inst.transform(row, 1), inst.transform(row, 2)};
    const double tr = inst.transform(row, 3);
    acc.hi[row] = t.support(w) + tr;
    acc.lo[row] = -t.support(w * -1.0) + tr;
  }
  return acc;
}

// One face of an instance's world box, as a maximum: side 0..2 = hi[row], 3..5 = -lo[row]. `exact`
// runs the branch and bound; otherwise the root box's bound, which is never below the exact value
// (same evaluation order, monotone rounding).
double side_value(const PointSet& t, const Instance& inst, int side, bool exact) {
  const int row = side % 3;
  const double sign = side < 3 ? 1.0 : -1.0;
  const Vec3d w = Vec3d{inst.transform(row, 0), inst.transform(row, 1), inst.transform(row, 2)} * sign;
  const double tr = inst.transform(row, 3);
  const double s = exact ? t.support(w) : PointSet::box_bound(w, t.box());
  // hi = support(w) + tr; lo = -support(-w) + tr, so -lo = support(-w) - tr (negation is exact).
  return side < 3 ? s + tr : s - tr;
}

}  // namespace

Aabb compute_instance_world_bounds(const Scene& scene, size_t instance) {
  const Instance& inst = scene.instances[instance];
  return instance_bounds(PointSet(scene.meshes[inst.mesh]), inst);
}

Aabb compute_world_bounds(const Scene& scene, const std::function<void(uint64_t, uint64_t)>& progress) {
  // One point set per mesh, made in parallel (each is independent).
  std::vector<std::unique_ptr<PointSet>> trees(scene.meshes.size());
  tbb::parallel_for(size_t(0), scene.meshes.size(), [&](size_t m) { trees[m] = std::make_unique<PointSet>(scene.meshes[m]); });
  const size_t n = scene.instances.size();
  auto usable = [&](size_t i) { return !trees[scene.instances[i].mesh]->empty(); };
  constexpr double kNone = -std::numeric_limits<double>::infinity();
  // Branch and bound over the instances too, for the six faces of the scene box at once: the scene's
  // face is the maximum of the instances' exact faces, and an instance whose root-box bound does not
  // exceed an exact face already found cannot raise it. So only the instances near the scene's
  // boundary run the point-tree search; the result is the same maximum as evaluating every instance,
  // for any thread count. Two passes over the instances (a face at a time made twelve: 10^6 instances
  // of 128 bytes each, most of the import of a 10^6-instance forest).
  using Faces = std::array<double, 6>;
  // Seeds: per face, the exact face of the instance with the largest bound (ties: lowest index).
  struct Seeds {
    Faces v;
    std::array<size_t, 6> i;
  };
  Seeds none;
  none.v.fill(kNone);
  none.i.fill(n);
  const Seeds seed = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, n, 4096), none,
      [&](const tbb::blocked_range<size_t>& r, Seeds b) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          if (!usable(i)) continue;
          const PointSet& t = *trees[scene.instances[i].mesh];
          for (int side = 0; side < 6; ++side) {
            const double v = side_value(t, scene.instances[i], side, false);
            if (v > b.v[side] || (v == b.v[side] && i < b.i[side])) b.v[side] = v, b.i[side] = i;
          }
        }
        return b;
      },
      [](Seeds a, const Seeds& b) {
        for (int side = 0; side < 6; ++side)
          if (b.v[side] > a.v[side] || (b.v[side] == a.v[side] && b.i[side] < a.i[side]))
            a.v[side] = b.v[side], a.i[side] = b.i[side];
        return a;
      });
  if (seed.i[0] == n) return Aabb{};  // no instance has a vertex
  if (progress) progress(n / 2, n);
  Faces start;
  for (int side = 0; side < 6; ++side)
    start[side] = side_value(*trees[scene.instances[seed.i[side]].mesh], scene.instances[seed.i[side]], side, true);
  const Faces face = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, n, 1024), start,
      [&](const tbb::blocked_range<size_t>& r, Faces best) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          if (!usable(i)) continue;
          const PointSet& t = *trees[scene.instances[i].mesh];
          for (int side = 0; side < 6; ++side)
            if (side_value(t, scene.instances[i], side, false) > best[side])
              best[side] = std::max(best[side], side_value(t, scene.instances[i], side, true));
        }
        return best;
      },
      [](Faces a, const Faces& b) {
        for (int side = 0; side < 6; ++side) a[side] = std::max(a[side], b[side]);
        return a;
      });
  if (progress) progress(n, n);
  Aabb all;
  for (int row = 0; row < 3; ++row) {
    all.hi[row] = face[row];
    all.lo[row] = -face[row + 3];
  }
  return all;
}

}  // namespace rtp
