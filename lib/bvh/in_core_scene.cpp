// The two levels in core (Molenaar 2019 §4.1): one BVH per mesh in local space, built in parallel
// over meshes, and a W-wide instance BVH over the world bounds of the instances.
#include <oneapi/tbb/parallel_for.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstring>

#include "bvh/build_internal.h"
#include "core/error.h"

namespace rtp {
namespace {

// Boxes whose union contains the mesh: the root's lane boxes (tighter under rotation than the root
// box), or the vertex bounds of a mesh whose root is a leaf.
template <int W, int B>
std::vector<Box3f> local_boxes(const MeshBvh<W, B>& bvh) {
  std::vector<Box3f> out;
  const uint32_t root = bvh.root;
  if (fmt::ChildRef::is_empty(root)) return out;
  if (!fmt::ChildRef::is_leaf(root)) {
    const fmt::WideNode<W>& n = bvh.nodes[fmt::ChildRef::node_index(root)];
    for (int i = 0; i < W && !fmt::ChildRef::is_empty(n.child[i]); ++i) {
      Box3f b;
      for (int a = 0; a < 3; ++a) {
        b.lo[a] = n.lo[a][i];
        b.hi[a] = n.hi[a][i];
      }
      out.push_back(b);
    }
    return out;
  }
  Box3f b;
  const uint32_t first = fmt::ChildRef::first_block(root), count = fmt::ChildRef::block_count(root);
  for (uint32_t k = first; k < first + count; ++k)
    for (int l = 0; l < B; ++l) {
      const fmt::LeafBlock<B>& blk = bvh.blocks[k];
      const float v[3][3] = {{blk.v0[0][l], blk.v0[1][l], blk.v0[2][l]},
                             {blk.v1[0][l], blk.v1[1][l], blk.v1[2][l]},
                             {blk.v2[0][l], blk.v2[1][l], blk.v2[2][l]}};
      for (const auto& p : v) bvh::grow_point(b, p);
    }
  out.push_back(b);
  return out;
}

std::string instance_label(size_t i, const Instance& inst) {
  std::string s = "instance " + std::to_string(i);
  if (inst.node != kNoIndex) s += " (/nodes/" + std::to_string(inst.node);
  if (inst.node != kNoIndex && inst.gpu_instance != kNoIndex) s += ", GPU instance " + std::to_string(inst.gpu_instance);
  if (inst.node != kNoIndex) s += ")";
  return s;
}

// The same words whether the scene is merged or not (tests compare the warnings of both builds).
std::string no_triangles_warning(size_t i, const Instance& inst) {
  return instance_label(i, inst) + ": mesh " + std::to_string(inst.mesh) + " has no triangles, left out of the instance BVH";
}

// The fields of a record that move a ray (SPEC §2.4): T, L^-1 and the mirrored flag.
bool same_move(const fmt::InstanceRecord& a, const fmt::InstanceRecord& b) {
  return std::memcmp(a.translation, b.translation, sizeof a.translation) == 0 &&
         std::memcmp(a.inverse_linear, b.inverse_linear, sizeof a.inverse_linear) == 0 && a.flags == b.flags;
}

// Issue 11 ("single-instance (or identity) scenes and meshes skip the instance level"): two or more
// instances whose records move a ray alike (all the identity, as FlightHelmet's six parts, or one
// root transform over every mesh node), each of a mesh no other instance uses, the transform invertible,
// every mesh well formed (else the per-mesh build names the bad one), between 1 and 2^31 - 1 triangles.
// With `any_move`, the instances' records may differ, each invertible (flattenable checks the rest).
bool mergeable(const Scene& scene, bool any_move = false) {
  if (scene.instances.size() < 2) return false;
  const fmt::InstanceRecord first = make_instance_record(scene.instances[0]);
  if (!record_invertible(first)) return false;
  std::vector<char> used(scene.meshes.size(), 0);
  uint64_t triangles = 0;
  for (const Instance& in : scene.instances) {
    if (in.mesh >= scene.meshes.size() || used[in.mesh]) return false;
    used[in.mesh] = 1;
    const fmt::InstanceRecord rec = make_instance_record(in);
    if (any_move ? !record_invertible(rec) : !same_move(rec, first)) return false;
    const Mesh& m = scene.meshes[in.mesh];
    if (m.indices.size() % 3 != 0) return false;
    for (uint32_t v : m.indices)
      if (v >= m.positions.size() || !is_finite(m.positions[v])) return false;
    triangles += m.triangle_count();
  }
  return triangles > 0 && triangles < (uint64_t(1) << 31);
}

// A vertex moved to world space as the flattened merge stores it: the instance's double transform,
// rounded to float once. flattenable() checked the vertices triangles use; a vertex no triangle uses
// may leave float range (then ±inf or NaN, never an out-of-range conversion).
Vec3f to_world(const Affine3x4& t, const Vec3f& q) {
  const Vec3d w = t.apply(to_d(q));
  const auto f = [](double x) {
    return std::fabs(x) <= double(FLT_MAX) ? static_cast<float>(x) : x > 0 ? INFINITY : x < 0 ? -INFINITY : NAN;
  };
  return {f(w.x), f(w.y), f(w.z)};
}

// Issue 11 (accuracy far from the origin): world-space float vertices are rounded to 2^-24 of their
// magnitude; an instance far from the origin relative to its own size (geospatial coordinates, a
// small part in a large scene) would lose its shape. Each instance with triangles must have
// max |world coordinate| <= 128 x its world extent (rounding <= 2^-17 of the extent) and finite
// float world coordinates; a mergeable(scene, true) scene is assumed.
bool flattenable(const Scene& scene) {
  for (const Instance& in : scene.instances) {
    const Mesh& m = scene.meshes[in.mesh];
    if (m.triangle_count() == 0) continue;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t v : m.indices) {
      const Vec3d w = in.transform.apply(to_d(m.positions[v]));
      for (int r = 0; r < 3; ++r) lo[r] = std::min(lo[r], w[r]), hi[r] = std::max(hi[r], w[r]);
    }
    double extent = 0, mag = 0;
    for (int r = 0; r < 3; ++r) {
      if (!(std::fabs(lo[r]) < double(FLT_MAX) && std::fabs(hi[r]) < double(FLT_MAX))) return false;
      extent = std::max(extent, hi[r] - lo[r]);
      mag = std::max({mag, std::fabs(lo[r]), std::fabs(hi[r])});
    }
    if (!(extent > 0) || mag > 128.0 * extent) return false;
  }
  return true;
}

}  // namespace

template <int W, int B>
InCoreScene<W, B> InCoreScene<W, B>::build(const Scene& scene, const BuildOptions& options) {
  bvh::check_options(options);
  if (options.merge_instances && mergeable(scene)) {
    InCoreScene merged = build_merged(scene, options, false);
    if (merged.merged()) return merged;  // else: world bounds out of range, named by the build below
  } else if (options.merge_instances && options.flatten_instances && mergeable(scene, true) && flattenable(scene)) {
    InCoreScene merged = build_merged(scene, options, true);
    if (merged.merged()) return merged;
  }
  InCoreScene out;
  const size_t nm = scene.meshes.size();
  out.meshes_.resize(nm);
  tbb::parallel_for(size_t(0), nm, [&](size_t i) {
    const Mesh& m = scene.meshes[i];
    out.meshes_[i] = build_mesh_bvh<W, B>(m, options, "mesh " + std::to_string(i) + " ('" + m.name + "')");
  });
  out.views_.reserve(nm);
  for (const auto& m : out.meshes_) out.views_.push_back(m.view());

  std::vector<std::vector<Box3f>> local(nm);
  for (size_t i = 0; i < nm; ++i) local[i] = local_boxes(out.meshes_[i]);

  std::vector<Box3f> boxes;
  std::vector<uint32_t> ids;
  out.records_.reserve(scene.instances.size());
  for (size_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    if (inst.mesh >= nm)
      throw Error(ExitCode::kInputInvalid, instance_label(i, inst) + ": mesh " + std::to_string(inst.mesh) + " does not exist");
    out.records_.push_back(make_instance_record(inst));
    const fmt::InstanceRecord& rec = out.records_.back();
    if (local[inst.mesh].empty()) {
      out.warnings_.push_back(no_triangles_warning(i, inst));
      continue;
    }
    if (!record_invertible(rec)) {
      out.warnings_.push_back(instance_label(i, inst) + ": singular transform, left out of the instance BVH");
      continue;
    }
    const Box3f box = transform_bounds(inst.transform, local[inst.mesh].data(), local[inst.mesh].size());
    for (int a = 0; a < 3; ++a)
      if (!std::isfinite(box.lo[a]) || !std::isfinite(box.hi[a]))
        throw Error(ExitCode::kInputInvalid, instance_label(i, inst) + ": world bounds exceed the float range");
    boxes.push_back(box);
    ids.push_back(uint32_t(i));
  }
  out.moves_ = axis_moves(out.records_.data(), out.records_.size());
  out.top_ = build_box_bvh<W>(boxes, options, "instance BVH");
  for (uint32_t& item : out.top_.items) item = ids[item];
  return out;
}

// The instances' meshes as one mesh in their shared local space (with `flatten`: in world space, each
// moved by its own transform), in instance order: one BVH, one more record with the shared transform
// (flattened: the identity), the merged instance, and the parts table that
// gives hits their original names (SceneView::part_first). Instances of meshes without triangles are
// left out with the warning the per-mesh build gives.
template <int W, int B>
InCoreScene<W, B> InCoreScene<W, B>::build_merged(const Scene& scene, const BuildOptions& options, bool flatten) {
  InCoreScene out;
  out.flattened_ = flatten;
  const size_t nm = scene.meshes.size(), ni = scene.instances.size();
  Mesh merged;
  merged.name = "merged instances";
  for (size_t i = 0; i < ni; ++i) {
    const Instance& inst = scene.instances[i];
    const Mesh& m = scene.meshes[inst.mesh];
    out.records_.push_back(make_instance_record(inst));
    if (m.triangle_count() == 0) {
      out.warnings_.push_back(no_triangles_warning(i, inst));
      continue;
    }
    const uint32_t base = uint32_t(merged.positions.size());
    out.part_first_.push_back(uint32_t(merged.indices.size() / 3));
    out.part_instance_.push_back(uint32_t(i));
    if (flatten)
      for (const Vec3f& q : m.positions) merged.positions.push_back(to_world(inst.transform, q));
    else
      merged.positions.insert(merged.positions.end(), m.positions.begin(), m.positions.end());
    for (uint32_t v : m.indices) merged.indices.push_back(base + v);
  }
  out.meshes_.resize(nm + 1);  // the scene's meshes (no BVH) and the merged one
  out.meshes_[nm] = build_mesh_bvh<W, B>(merged, options, "the merged instances");
  out.views_.reserve(nm + 1);
  for (const auto& m : out.meshes_) out.views_.push_back(m.view());
  Instance all = scene.instances[0];  // the transform every instance shares
  all.mesh = uint32_t(nm);
  if (flatten) all.transform = Affine3x4{}, all.mirrored = false;  // the vertices are in world space
  out.records_.push_back(make_instance_record(all));
  out.moves_ = axis_moves(out.records_.data(), out.records_.size());
  // The instance BVH holds the merged instance alone: walked as any instance when the shared transform
  // moves rays, skipped through SceneView::direct when it is the identity.
  std::vector<Box3f> boxes;
  const std::vector<Box3f> local = local_boxes(out.meshes_[nm]);
  if (!local.empty()) boxes.push_back(transform_bounds(all.transform, local.data(), local.size()));
  for (const Box3f& b : boxes)
    for (int a = 0; a < 3; ++a)
      if (!std::isfinite(b.lo[a]) || !std::isfinite(b.hi[a])) return InCoreScene{};  // the caller builds per mesh
  out.top_ = build_box_bvh<W>(boxes, options, "instance BVH");
  for (uint32_t& item : out.top_.items) item = uint32_t(ni);
  return out;
}

template <int W, int B>
SceneView<W, B> InCoreScene<W, B>::view() const {
  SceneView<W, B> v;
  v.top_nodes = top_.nodes.data();
  v.top_root = top_.root;
  v.top_instances = top_.items.data();
  v.instances = records_.data();
  v.meshes = views_.data();
  v.direct = direct_instance(records_.data(), records_.size());
  v.moves = moves_.data();
  if (merged()) {
    // The merged instance: walked directly when its transform is the identity.
    v.direct = moves_.back().kind == AxisMove::kNone ? uint32_t(records_.size() - 1) : kNoDirectInstance;
    v.part_first = part_first_.data();
    v.part_instance = part_instance_.data();
    v.parts = uint32_t(part_first_.size());
  }
  return v;
}

template class InCoreScene<4, 4>;
template class InCoreScene<8, 8>;
template class InCoreScene<16, 16>;
template class InCoreScene<8, 4>;
template class InCoreScene<16, 8>;

}  // namespace rtp
