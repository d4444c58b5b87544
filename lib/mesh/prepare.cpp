// Scene-level mesh preparation: clean (OpenMesh) -> subdivide (OpenSubdiv) -> exact bounds.
#include "mesh/prepare.h"

#include <tbb/parallel_for.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>

#include "core/error.h"

namespace rtp {
namespace {

// Peak memory per refined triangle while subdividing: 5348 MiB (5.61e9 bytes) for the 62.9 M triangles
// of `rtpack-convert samples/generated/gallery.glb --subdivide 6 --dry-run -v` (indices, positions,
// source map, OpenSubdiv's refinement tables and the previous level together).
constexpr double kSubdivideBytesPerTriangle = 89;

std::string gib(double bytes) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f GiB", bytes / double(uint64_t(1) << 30));
  return b;
}

// A uniform subdivision that cannot fit in this machine's memory is refused before any work:
// `--subdivide 8` of a 15k-triangle scene asked for 10^9 triangles and ran for minutes, silent,
// towards the out-of-memory killer.
void check_uniform_memory(const Scene& scene, int levels, uint64_t memory_bytes) {
  const double before = double(scene.unique_triangles()), after = before * std::pow(4.0, levels);
  const double need = after * kSubdivideBytesPerTriangle;
  const uint64_t have = memory_bytes ? memory_bytes : machine_memory_bytes();
  if (have == 0 || need <= double(have)) return;  // unknown: let it try
  char tris[64], per[32];
  std::snprintf(tris, sizeof tris, "%.0f", after);
  std::snprintf(per, sizeof per, "%.0f", kSubdivideBytesPerTriangle);
  throw Error(ExitCode::kUsage, "--subdivide " + std::to_string(levels) + ": would make " + tris + " triangles from " +
                                    std::to_string(scene.unique_triangles()) + ", about " + gib(need) + " while refining (" +
                                    per + " bytes per triangle), more than the " + gib(double(have)) +
                                    " of memory here; use fewer levels or --subdivide-to LENGTH");
}

}  // namespace

uint64_t machine_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  uint64_t have = pages > 0 && page > 0 ? uint64_t(pages) * uint64_t(page) : 0;
  // A container's limit (cgroup v2): "max" or a byte count.
  if (std::FILE* f = std::fopen("/sys/fs/cgroup/memory.max", "r")) {
    unsigned long long limit = 0;
    if (std::fscanf(f, "%llu", &limit) == 1 && limit > 0 && (have == 0 || limit < have)) have = limit;
    std::fclose(f);
  }
  return have;
}

PrepareReport prepare_scene(Scene& scene, const PrepareOptions& opt) {
  PrepareReport rep;
  rep.triangles_before = scene.unique_triangles();
  std::vector<CleanReport> per(scene.meshes.size());
  tbb::parallel_for(size_t(0), scene.meshes.size(), [&](size_t m) { per[m] = clean_mesh(scene.meshes[m], opt.clean); });
  rep.clean.topology_analysed = opt.clean.topology;
  for (const CleanReport& c : per) {
    rep.clean.degenerate_removed += c.degenerate_removed;
    rep.clean.nonfinite_removed += c.nonfinite_removed;
    rep.clean.welded_vertices += c.welded_vertices;
    rep.clean.nonmanifold_edges += c.nonmanifold_edges;
    rep.clean.nonmanifold_faces += c.nonmanifold_faces;
    rep.clean.nonmanifold_vertices += c.nonmanifold_vertices;
    rep.clean.boundary_edges += c.boundary_edges;
    rep.clean.unused_vertices_removed += c.unused_vertices_removed;
  }
  // Drop meshes that cleaning emptied, remapping instances.
  std::vector<uint32_t> remap(scene.meshes.size(), kNoIndex);
  std::vector<Mesh> kept;
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    if (scene.meshes[m].triangle_count() == 0) {
      ++rep.meshes_emptied;
      scene.warnings.push_back("mesh '" + scene.meshes[m].name +
                               "': no triangle left after clean-up; dropped with its instances");
      continue;
    }
    remap[m] = uint32_t(kept.size());
    kept.push_back(std::move(scene.meshes[m]));
  }
  scene.meshes = std::move(kept);
  // In place, and not at all when no mesh was dropped: a copy of 10^6 instances is ~0.4 s of page
  // faults and memmove on the forest.
  if (rep.meshes_emptied) {
    size_t out = 0;
    for (Instance& i : scene.instances)
      if ((i.mesh = remap[i.mesh]) != kNoIndex) scene.instances[out++] = i;
    scene.instances.resize(out);
  }

  if (opt.subdivide_levels > 0 && opt.subdivide_to > 0)
    throw Error(ExitCode::kUsage, "--subdivide and --subdivide-to exclude each other");
  if (opt.subdivide_levels > 0) {
    check_uniform_memory(scene, opt.subdivide_levels, opt.memory_bytes);
    rep.uniform_levels = opt.subdivide_levels;
    std::vector<uint8_t> fb(scene.meshes.size(), 0);
    tbb::parallel_for(size_t(0), scene.meshes.size(),
                      [&](size_t m) { fb[m] = subdivide_uniform(scene.meshes[m], opt.subdivide_levels).used_fallback; });
    for (uint8_t f : fb) rep.uniform_fallbacks += f;
  } else if (opt.subdivide_to > 0) {
    rep.adaptive = true;
    rep.subdivide = subdivide_to_length(scene, opt.subdivide_to, opt.subdivide_max_levels);
  }
  rep.triangles_after = scene.unique_triangles();
  // Bounds change only if geometry did: removed triangles, moved (welded) vertices, refinement.
  const bool changed = rep.triangles_after != rep.triangles_before || rep.clean.degenerate_removed ||
                       rep.clean.nonfinite_removed || rep.clean.welded_vertices || rep.meshes_emptied;
  if (changed) scene.bounds = compute_world_bounds(scene);
  return rep;
}

namespace {
nlohmann::json analysed_or_null(const PrepareReport& r, uint64_t count) {
  return r.clean.topology_analysed ? nlohmann::json(count) : nlohmann::json(nullptr);
}
}  // namespace

nlohmann::json prepare_report_json(const PrepareReport& r) {
  nlohmann::json j = {{"degenerate_removed", r.clean.degenerate_removed},
                      {"nonfinite_removed", r.clean.nonfinite_removed},
                      {"welded_vertices", r.clean.welded_vertices},
                      {"unused_vertices_removed", r.clean.unused_vertices_removed},
                      {"nonmanifold_edges", r.clean.nonmanifold_edges},
                      // null: not analysed (rtpack-convert --topology)
                      {"nonmanifold_faces", analysed_or_null(r, r.clean.nonmanifold_faces)},
                      {"nonmanifold_vertices", analysed_or_null(r, r.clean.nonmanifold_vertices)},
                      {"boundary_edges", r.clean.boundary_edges},
                      {"meshes_emptied", r.meshes_emptied},
                      {"uniform_levels", r.uniform_levels},
                      {"uniform_fallbacks", r.uniform_fallbacks},
                      {"triangles_before", r.triangles_before},
                      {"triangles_after", r.triangles_after}};
  if (r.adaptive) {
    nlohmann::json per = nlohmann::json::array();
    for (const auto& m : r.subdivide.meshes)
      per.push_back({{"mesh", m.mesh},
                     {"levels", m.levels},
                     {"hit_cap", m.hit_cap},
                     {"max_scale", m.max_scale},
                     {"triangles_before", m.triangles_before},
                     {"triangles_after", m.triangles_after},
                     {"longest_world_edge_before", m.longest_world_edge_before},
                     {"longest_world_edge_after", m.longest_world_edge_after}});
    j["adaptive"] = {
        {"meshes_subdivided", r.subdivide.meshes_subdivided}, {"meshes_at_cap", r.subdivide.meshes_at_cap}, {"per_mesh", per}};
  }
  return j;
}

std::string prepare_report_text(const PrepareReport& r) {
  using std::to_string;
  std::string o = "preparation\n";
  o += "  removed              " + to_string(r.clean.degenerate_removed) + " degenerate, " +
       to_string(r.clean.nonfinite_removed) + " non-finite triangles\n";
  o += "  vertices             " + to_string(r.clean.welded_vertices) + " welded, " + to_string(r.clean.unused_vertices_removed) +
       " unused removed\n";
  o += "  topology             " + to_string(r.clean.nonmanifold_edges) + " non-manifold edges, " +
       to_string(r.clean.boundary_edges) + " boundary edges (reported, kept)\n";
  if (r.clean.topology_analysed)
    o += "  half-edge topology   " + to_string(r.clean.nonmanifold_faces) + " faces OpenMesh refuses, " +
         to_string(r.clean.nonmanifold_vertices) + " non-manifold vertices\n";
  if (r.uniform_levels)
    o += "  subdivision          uniform Loop x" + to_string(r.uniform_levels) +
         (r.uniform_fallbacks ? " (" + to_string(r.uniform_fallbacks) + " meshes used the midpoint fallback)" : "") + "\n";
  if (r.adaptive)
    o += "  subdivision          adaptive: " + to_string(r.subdivide.meshes_subdivided) + " meshes refined, " +
         to_string(r.subdivide.meshes_at_cap) + " at the level cap\n";
  o += "  unique triangles     " + to_string(r.triangles_before) + " -> " + to_string(r.triangles_after) + "\n";
  return o;
}

}  // namespace rtp
