// One conversion: import -> prepare -> batching points (Molenaar 2019 §3.1) -> chunks.
#include "core/clock.h"
#include "package/convert.h"

#include <chrono>
#include <filesystem>

#include "core/error.h"
#include "core/input_file.h"
#include "core/progress.h"
#include "core/utf8.h"
#include "scene/import.h"

namespace rtp {
namespace {

StageCost cost_since(Clock::time_point t0) { return {std::chrono::duration<double>(Clock::now() - t0).count(), peak_rss_mib()}; }

}  // namespace

ConvertOutcome convert_scene(const ConvertSettings& s, const ConvertHooks& hooks) {
  const int leaf_width = s.leaf_width ? s.leaf_width : (s.width == 16 ? 8 : s.width);
  if (!supported_widths(s.width, leaf_width))
    throw Error(ExitCode::kUsage, "--bvh-width " + std::to_string(s.width) + " --leaf-width " + std::to_string(leaf_width) +
                                      " is not a supported pair (4/4, 8/8, 16/16, 8/4, 16/8)");
  auto stage = [&](const char* name, bool counts = true) {
    if (hooks.stage) hooks.stage(name, counts);
  };
  ConvertOutcome out;

  auto t0 = Clock::now();
  stage("import");
  ImportOptions opt;
  opt.scene = s.scene;
  opt.allowed_dirs = s.allow_paths;
  for (const std::string& a : s.attributes) (a == "normal" ? opt.normals : opt.uvs) = true;
  bool bounds_stage = false;  // instanced scenes spend most of the import on exact bounds: show it
  opt.on_progress = [&](uint64_t done, uint64_t total) {
    if (!bounds_stage) stage("import: exact bounds of instances");
    bounds_stage = true;
    if (hooks.progress) hooks.progress(done, total);
  };
  out.scene = import_gltf(s.input, opt);
  out.import_cost = cost_since(t0);
  Scene& scene = out.scene;
  // The glTF itself is checked before any work (rtpack-convert); its external buffers are known now.
  for (const std::string& b : scene.input.buffer_paths) check_not_same_file(b, s.output);
  for (const auto& [want, name] : {std::pair{opt.normals, "NORMAL"}, std::pair{opt.uvs, "TEXCOORD_0"}}) {
    bool any = false;
    for (const Mesh& m : scene.meshes) any |= !(name[0] == 'N' ? m.normals.empty() : m.uvs.empty());
    if (want && !any) scene.warnings.push_back(std::string("--attributes: no mesh has ") + name + "; none stored");
  }

  t0 = Clock::now();
  stage("prepare");
  PrepareOptions prep;
  prep.clean.weld_eps = s.weld;
  prep.clean.topology = s.topology;
  prep.subdivide_levels = s.subdivide;
  prep.subdivide_to = s.subdivide_to;
  out.prepare = prepare_scene(scene, prep);
  out.prepare_cost = cost_since(t0);
  if (hooks.prepared) hooks.prepared(scene, out.prepare);
  if (s.dry_run) return out;

  t0 = Clock::now();
  stage("batching points");
  ClusterOptions co;
  co.chunk_target = s.chunk_target;
  co.chunk_by = s.chunk_by == "unique" ? ChunkBy::kUnique : ChunkBy::kInstanced;
  out.plan = plan_batching_points(scene, co);
  out.plan_cost = cost_since(t0);

  t0 = Clock::now();
  stage("chunks", false);
  ConvertOptions cv;
  cv.width = s.width;
  cv.leaf_width = leaf_width;
  cv.bvh.method = s.bvh_build == "split" ? BuildMethod::kSplit : BuildMethod::kCollapse;
  cv.zstd_level = s.zstd_level;
  cv.zstd_raw_literals = s.zstd_raw_literals;
  cv.zstd_leaf_min_match = s.zstd_leaf_min_match;
  cv.dag = s.dag;
  cv.voxel.resolution = s.dag_resolution;
  cv.progress = hooks.progress;
  // The metadata chunk (SPEC §4.1): what made the package, from the settings alone.
  cv.metadata = {{"tool_version", "rtpack " RTP_VERSION},
                 {"source", utf8_display(std::filesystem::path(s.input).filename().string())},
                 {"options",
                  {{"bvh_width", s.width},
                   {"leaf_width", leaf_width},
                   {"bvh_build", s.bvh_build},
                   {"chunk_target", s.chunk_target},
                   {"chunk_by", s.chunk_by},
                   {"zstd_level", s.zstd_level},
                   {"zstd_raw_literals", s.zstd_raw_literals},
                   {"zstd_leaf_min_match", s.zstd_leaf_min_match},
                   {"subdivide", s.subdivide},
                   {"subdivide_to", s.subdivide_to},
                   {"weld", s.weld},
                   {"scene", scene.gltf_scene},
                   {"attributes", s.attributes},
                   {"dag", s.dag},
                   {"dag_resolution", s.dag_resolution}}}};
  out.report = write_package(scene, out.plan, s.output, cv);
  out.chunks_cost = cost_since(t0);
  return out;
}

}  // namespace rtp
