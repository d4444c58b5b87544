// SAH statistics in the style of Benthin 2008 Table 1: for W ∈ {4, 8, 16} (B = W) and both build
// methods, the §4 costs C_box and C_tri, their sum, branching factor, leaf fill, depth and memory.
#include <chrono>
#include <cstdio>
#include <filesystem>

#include "bvh/bvh.h"
#include "scene/import.h"

namespace rtp {

Mesh flatten_scene(const Scene& scene) {
  Mesh out;
  out.name = scene.source_path;
  out.primitives.push_back({kNoIndex, kNoIndex});
  size_t vertices = 0, indices = 0;
  for (const Instance& inst : scene.instances) {
    vertices += scene.meshes.at(inst.mesh).positions.size();
    indices += scene.meshes.at(inst.mesh).indices.size();
  }
  out.positions.reserve(vertices);
  out.indices.reserve(indices);
  out.source.reserve(indices / 3);
  for (const Instance& inst : scene.instances) {
    const Mesh& m = scene.meshes[inst.mesh];
    const uint32_t base = uint32_t(out.positions.size());
    for (const Vec3f& p : m.positions) {
      const Vec3d w = inst.transform.apply(to_d(p));
      out.positions.push_back({float(w.x), float(w.y), float(w.z)});
    }
    for (uint32_t i : m.indices) out.indices.push_back(base + i);
    for (size_t t = 0; t < m.triangle_count(); ++t) out.source.push_back({0, uint32_t(out.source.size())});
  }
  return out;
}

namespace {

template <int W, int B>
BvhStatsRow measure(const std::string& model, const Mesh& mesh, BuildOptions options, BuildMethod method) {
  options.method = method;
  const auto t0 = std::chrono::steady_clock::now();
  const MeshBvh<W, B> bvh = build_mesh_bvh<W, B>(mesh, options, model);
  const auto t1 = std::chrono::steady_clock::now();
  BvhStatsRow row;
  row.model = model;
  row.width = W;
  row.block = B;
  row.method = method;
  row.stats = bvh.stats;
  row.build_seconds = std::chrono::duration<double>(t1 - t0).count();
  return row;
}

}  // namespace

std::vector<BvhStatsRow> bvh_stats_rows(const std::string& model, const Mesh& mesh, const BuildOptions& options) {
  std::vector<BvhStatsRow> rows;
  for (BuildMethod m : {BuildMethod::kCollapse, BuildMethod::kSplit}) {
    rows.push_back(measure<4, 4>(model, mesh, options, m));
    rows.push_back(measure<8, 8>(model, mesh, options, m));
    rows.push_back(measure<16, 16>(model, mesh, options, m));
  }
  return rows;
}

std::string bvh_stats_table(const std::vector<BvhStatsRow>& rows) {
  std::string out;
  char line[320];
  std::snprintf(line, sizeof line, "%-16s %9s %3s %3s %-8s %9s %9s %9s %7s %6s %6s %9s %9s %9s\n", "model", "tris", "W", "B",
                "method", "C_box", "C_tri", "SAH", "branch", "fill", "depth", "nodes", "leaves", "bytes/tri");
  out += line;
  for (const BvhStatsRow& r : rows) {
    const BvhStats& s = r.stats;
    const double per_tri = s.primitives ? double(s.node_bytes + s.block_bytes) / double(s.primitives) : 0;
    std::snprintf(line, sizeof line, "%-16s %9llu %3d %3d %-8s %9.2f %9.2f %9.2f %7.2f %6.3f %6u %9llu %9llu %9.1f\n",
                  r.model.substr(0, 16).c_str(), static_cast<unsigned long long>(s.primitives), r.width, r.block,
                  method_name(r.method), s.c_box, s.c_tri, s.sah, s.branching, s.leaf_fill, s.max_depth,
                  static_cast<unsigned long long>(s.nodes), static_cast<unsigned long long>(s.leaves), per_tri);
    out += line;
  }
  return out;
}

std::string bvh_stats_table(const std::vector<std::string>& gltf_paths, const BuildOptions& options) {
  std::vector<BvhStatsRow> rows;
  for (const std::string& path : gltf_paths) {
    const Mesh mesh = flatten_scene(import_gltf(path));
    const std::vector<BvhStatsRow> r = bvh_stats_rows(std::filesystem::path(path).stem().string(), mesh, options);
    rows.insert(rows.end(), r.begin(), r.end());
  }
  return bvh_stats_table(rows);
}

}  // namespace rtp
