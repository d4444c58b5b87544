// One mesh's wide BVH: input validation, triangle boxes, the chosen builder, layout.
#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/parallel_reduce.h>

#include <cmath>

#include "bvh/build_internal.h"
#include "core/error.h"

namespace rtp {

const char* method_name(BuildMethod method) { return method == BuildMethod::kCollapse ? "collapse" : "split"; }

namespace bvh {

void check_options(const BuildOptions& o) {
  auto bad = [](const std::string& m) { throw Error(ExitCode::kUsage, "BVH build options: " + m); };
  if (o.method != BuildMethod::kCollapse && o.method != BuildMethod::kSplit) bad("unknown method");
  if (o.bins < 2 || o.bins > kMaxBins) bad("bins must be in [2, " + std::to_string(kMaxBins) + "]");
  if (o.max_depth < 1 || o.max_depth > 256) bad("max_depth must be in [1, 256]");
  if (o.top_leaf_size < 1 || o.top_leaf_size > fmt::ChildRef::kMaxBlocksPerLeaf) bad("top_leaf_size must be in [1, 16]");
}

template <int W>
WideTree<W> build_wide(std::vector<PrimRef>& prims, const BuildParams& params, BuildMethod method, const std::string& label) {
  if (prims.size() >= (size_t(1) << 31))
    throw Error(ExitCode::kInputInvalid, label + ": " + std::to_string(prims.size()) + " primitives, at most 2^31 - 1 per BVH");
  const uint32_t n = uint32_t(prims.size());
  const uint32_t levels = median_levels(n, params.leaf_size);
  if (levels > params.max_depth)
    throw Error(ExitCode::kInputInvalid, label + ": " + std::to_string(n) + " primitives in leaves of " +
                                             std::to_string(params.leaf_size) + " need depth " + std::to_string(levels) +
                                             " > max_depth " + std::to_string(params.max_depth));
  // Scratch for the parallel (stable) partition; small inputs partition in place.
  std::vector<PrimRef> scratch(n >= params.parallel_threshold ? n : 0);
  Splitter splitter(prims.data(), scratch.empty() ? nullptr : scratch.data(), params);
  if (method == BuildMethod::kCollapse) return collapse_binary<W>(build_binary(splitter, n), params);
  return split_build<W>(splitter, n);
}

template WideTree<4> build_wide<4>(std::vector<PrimRef>&, const BuildParams&, BuildMethod, const std::string&);
template WideTree<8> build_wide<8>(std::vector<PrimRef>&, const BuildParams&, BuildMethod, const std::string&);
template WideTree<16> build_wide<16>(std::vector<PrimRef>&, const BuildParams&, BuildMethod, const std::string&);

}  // namespace bvh

template <int W, int B>
MeshBvh<W, B> build_mesh_bvh(const Mesh& mesh, const BuildOptions& options, std::string_view label_in) {
  using namespace bvh;
  check_options(options);
  const std::string label = label_in.empty() ? "mesh '" + mesh.name + "'" : std::string(label_in);
  BuildParams p;
  p.bins = options.bins;
  p.max_depth = options.max_depth;
  p.block = B;
  p.max_leaf = fmt::ChildRef::kMaxBlocksPerLeaf * B;
  p.leaf_size = options.leaf_size ? options.leaf_size : W;
  p.task_threshold = options.task_threshold;
  p.parallel_threshold = options.parallel_threshold;
  if (p.leaf_size > p.max_leaf)
    throw Error(ExitCode::kUsage, "BVH build options: leaf_size " + std::to_string(p.leaf_size) + " exceeds 16 blocks of " +
                                      std::to_string(B) + " triangles");

  if (mesh.indices.size() % 3 != 0)
    throw Error(ExitCode::kInputInvalid,
                label + ": index count " + std::to_string(mesh.indices.size()) + " is not a multiple of 3");
  const size_t tris = mesh.indices.size() / 3;
  if (tris >= (size_t(1) << 31))
    throw Error(ExitCode::kInputInvalid, label + ": " + std::to_string(tris) + " triangles, at most 2^31 - 1 per BVH");

  // Triangle boxes; the first bad triangle (index out of range, non-finite vertex) is reported.
  std::vector<PrimRef> prims(tris);
  const size_t nv = mesh.positions.size();
  const Vec3f* pos = mesh.positions.data();
  const uint32_t* idx = mesh.indices.data();
  const size_t first_bad = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, tris, 4096), tris,
      [&](const tbb::blocked_range<size_t>& r, size_t bad) {
        for (size_t t = r.begin(); t != r.end(); ++t) {
          PrimRef& pr = prims[t];
          pr.id = uint32_t(t);
          pr.unused = 0;
          bool ok = true;
          for (int a = 0; a < 3; ++a) {
            pr.lo[a] = std::numeric_limits<float>::infinity();
            pr.hi[a] = -std::numeric_limits<float>::infinity();
          }
          for (int k = 0; k < 3; ++k) {
            const uint32_t v = idx[3 * t + size_t(k)];
            if (v >= nv || !is_finite(pos[v])) {
              ok = false;
              break;
            }
            for (int a = 0; a < 3; ++a) {
              const float c = no_negative_zero(pos[v][a]);
              pr.lo[a] = std::min(pr.lo[a], c);
              pr.hi[a] = std::max(pr.hi[a], c);
            }
          }
          if (!ok) bad = std::min(bad, t);
        }
        return bad;
      },
      [](size_t a, size_t b) { return std::min(a, b); });
  if (first_bad < tris) {
    std::string why = "a non-finite vertex";
    for (int k = 0; k < 3; ++k)
      if (idx[3 * first_bad + size_t(k)] >= nv)
        why = "vertex index " + std::to_string(idx[3 * first_bad + size_t(k)]) + " out of range";
    throw Error(ExitCode::kInputInvalid, label + ": triangle " + std::to_string(first_bad) + " has " + why);
  }

  const WideTree<W> tree = build_wide<W>(prims, p, options.method, label);
  MeshBvh<W, B> out;
  emit_mesh<W, B>(tree, prims.data(), mesh, label, out);
  return out;
}

#define RTP_MESH_BVH(W, B) template MeshBvh<W, B> build_mesh_bvh<W, B>(const Mesh&, const BuildOptions&, std::string_view);
RTP_MESH_BVH(4, 4)
RTP_MESH_BVH(8, 8)
RTP_MESH_BVH(16, 16)
RTP_MESH_BVH(8, 4)
RTP_MESH_BVH(16, 8)
#undef RTP_MESH_BVH

}  // namespace rtp
