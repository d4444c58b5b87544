// The instance level (Molenaar 2019 §4.1 two-level BVH): instance records (SPEC §2.4), world bounds of
// instances, and the W-wide BVH over boxes that the instance level uses (same builders as meshes,
// leaf cost per instance instead of per block).
#include <tbb/parallel_for.h>

#include <cmath>

#include "bvh/build_internal.h"
#include "core/error.h"

namespace rtp {

bool invert_affine(const Affine3x4& m, double inv[12]) {
  double a[3][3], t[3];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) a[r][c] = m(r, c);
    t[r] = m(r, 3);
  }
  // Adjugate / determinant in double.
  double adj[3][3];
  adj[0][0] = a[1][1] * a[2][2] - a[1][2] * a[2][1];
  adj[0][1] = a[0][2] * a[2][1] - a[0][1] * a[2][2];
  adj[0][2] = a[0][1] * a[1][2] - a[0][2] * a[1][1];
  adj[1][0] = a[1][2] * a[2][0] - a[1][0] * a[2][2];
  adj[1][1] = a[0][0] * a[2][2] - a[0][2] * a[2][0];
  adj[1][2] = a[0][2] * a[1][0] - a[0][0] * a[1][2];
  adj[2][0] = a[1][0] * a[2][1] - a[1][1] * a[2][0];
  adj[2][1] = a[0][1] * a[2][0] - a[0][0] * a[2][1];
  adj[2][2] = a[0][0] * a[1][1] - a[0][1] * a[1][0];
  const double det = a[0][0] * adj[0][0] + a[0][1] * adj[1][0] + a[0][2] * adj[2][0];
  if (!(std::abs(det) > 0) || !std::isfinite(det)) return false;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) inv[r * 4 + c] = adj[r][c] / det;
    inv[r * 4 + 3] = -(inv[r * 4 + 0] * t[0] + inv[r * 4 + 1] * t[1] + inv[r * 4 + 2] * t[2]);
  }
  for (int i = 0; i < 12; ++i)
    if (!std::isfinite(inv[i])) return false;
  return true;
}

fmt::InstanceRecord make_instance_record(const Instance& instance) {
  fmt::InstanceRecord rec{};
  const Affine3x4& m = instance.transform;
  for (int r = 0; r < 3; ++r) rec.translation[r] = m(r, 3);
  double inv[12];
  if (invert_affine(m, inv)) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) rec.inverse_linear[3 * r + c] = float(inv[4 * r + c]);
  }
  rec.mesh = instance.mesh;
  rec.flags = det3_of(rec.inverse_linear) < 0 ? 1u : 0u;  // of what is stored, as a reader checks it
  return rec;
}

void make_instance_records(const std::vector<Instance>& instances, fmt::InstanceRecord* out) {
  tbb::parallel_for(tbb::blocked_range<size_t>(0, instances.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) out[i] = make_instance_record(instances[i]);
  });
}

std::vector<fmt::InstanceRecord> make_instance_records(const std::vector<Instance>& instances) {
  std::vector<fmt::InstanceRecord> out(instances.size());
  make_instance_records(instances, out.data());
  return out;
}

bool record_invertible(const fmt::InstanceRecord& rec) {
  bool nonzero = false, finite = true;
  for (float v : rec.inverse_linear) nonzero |= v != 0, finite &= std::isfinite(v);
  return nonzero && finite;
}

Box3f transform_bounds(const Affine3x4& m, const Box3f* local, size_t count) {
  const double inf = std::numeric_limits<double>::infinity();
  double lo[3] = {inf, inf, inf}, hi[3] = {-inf, -inf, -inf};
  for (size_t b = 0; b < count; ++b) {
    if (bvh::is_empty(local[b])) continue;
    // The eight corners' m.apply(q) per axis, ((m0 x + m1 y) + m2 z) + m3 as Affine3x4::apply adds them
    // (the same bits), from the six products and four partial sums a corner shares with the others.
    for (int a = 0; a < 3; ++a) {
      double px[2], py[2], pz[2];
      for (int i = 0; i < 2; ++i) {
        px[i] = m(a, 0) * double(i ? local[b].hi[0] : local[b].lo[0]);
        py[i] = m(a, 1) * double(i ? local[b].hi[1] : local[b].lo[1]);
        pz[i] = m(a, 2) * double(i ? local[b].hi[2] : local[b].lo[2]);
      }
      for (int c = 0; c < 8; ++c) {
        const double w = px[c & 1] + py[c >> 1 & 1] + pz[c >> 2 & 1] + m(a, 3);
        lo[a] = std::min(lo[a], w);
        hi[a] = std::max(hi[a], w);
      }
    }
  }
  Box3f out;
  if (!(lo[0] <= hi[0])) return out;  // nothing to bound
  for (int a = 0; a < 3; ++a) {
    // Round outward, then one more float step for the error of the double transform.
    float l = float(lo[a]), h = float(hi[a]);
    if (double(l) > lo[a]) l = float_down(l);
    if (double(h) < hi[a]) h = float_up(h);
    out.lo[a] = bvh::no_negative_zero(float_down(l));
    out.hi[a] = bvh::no_negative_zero(float_up(h));
  }
  return out;
}

template <int W>
BoxBvh<W> build_box_bvh(const std::vector<Box3f>& boxes, const BuildOptions& options, std::string_view label_in) {
  using namespace bvh;
  check_options(options);
  const std::string label(label_in);
  BuildParams p;
  p.bins = options.bins;
  p.max_depth = options.max_depth;
  p.block = 1;  // every instance in a leaf costs a traversal of its own BVH
  p.max_leaf = fmt::ChildRef::kMaxBlocksPerLeaf;
  p.leaf_size = options.top_leaf_size;
  p.task_threshold = options.task_threshold;
  p.parallel_threshold = options.parallel_threshold;

  std::vector<PrimRef> prims(boxes.size());
  for (size_t i = 0; i < boxes.size(); ++i) {
    const Box3f& b = boxes[i];
    for (int a = 0; a < 3; ++a) {
      if (!std::isfinite(b.lo[a]) || !std::isfinite(b.hi[a]) || !(b.lo[a] <= b.hi[a]))
        throw Error(ExitCode::kInputInvalid, label + ": box " + std::to_string(i) + " is empty or not finite");
      prims[i].lo[a] = no_negative_zero(b.lo[a]);
      prims[i].hi[a] = no_negative_zero(b.hi[a]);
    }
    prims[i].id = uint32_t(i);
    prims[i].unused = 0;
  }
  const WideTree<W> tree = build_wide<W>(prims, p, options.method, label);
  BoxBvh<W> out;
  emit_boxes<W>(tree, prims.data(), label, out);
  return out;
}

template BoxBvh<4> build_box_bvh<4>(const std::vector<Box3f>&, const BuildOptions&, std::string_view);
template BoxBvh<8> build_box_bvh<8>(const std::vector<Box3f>&, const BuildOptions&, std::string_view);
template BoxBvh<16> build_box_bvh<16>(const std::vector<Box3f>&, const BuildOptions&, std::string_view);

}  // namespace rtp
