// rtpack-convert: glTF scene -> chunked .rtp package (import, prepare, batching points, per-chunk
// wide BVHs, zstd chunks). --dry-run stops after preparation and prints the scene summary.
#include <algorithm>
#include <tbb/global_control.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "cluster/cluster.h"
#include "core/error.h"
#include "core/input_file.h"
#include "core/utf8.h"
#include "core/progress.h"
#include "mesh/prepare.h"
#include "package/writer.h"
#include "reader/reader.h"
#include "package/convert.h"
#include "package/write_package.h"
#include "scene/import.h"
#include "scene/summary.h"
#include "malloc_policy.h"
#include "cli_checks.h"
#include "tool_version.h"

namespace {

std::string human(double bytes) { return rtp::human_bytes(bytes); }

}  // namespace

int main(int argc, char** argv) {
  rtp::tools::configure_malloc(argv);  // first: may re-execute with huge pages (malloc_policy.h)
  CLI::App app{"rtpack-convert: prepare a glTF scene for out-of-core ray tracing"};
  rtp::tools::add_version_flag(app, "rtpack-convert");
  std::string input, output, build = "collapse", chunk_by = "instanced";
  bool dry_run = false, json = false, quiet = false, verbose = false, topology = false;
  int scene_index = -1, subdivide = 0, width = 8, leaf_width = 0, zstd_level = rtp::kDefaultZstdLevel, threads = 0;
  double weld = -1, subdivide_to = 0;
  uint64_t chunk_target = 0;
  std::vector<std::string> attributes, allow_paths;
  app.add_option("input", input, "input .gltf or .glb")->required();
  app.add_option("--allow-path", allow_paths,
                 "also read external buffers from DIR (repeatable; default: only inside the glTF's directory)");
  app.add_option("-o,--output", output, "output package (.rtp)");
  app.add_flag("--dry-run", dry_run, "import and prepare only; print the scene summary");
  app.add_flag("--topology", topology,
               "also analyse each mesh's half-edge topology with OpenMesh (faces it refuses, non-manifold vertices; "
               "report only, about an eighth of a convert's time)");
  app.add_flag("--json", json, "print the summary as JSON on stdout");
  app.add_option("--scene", scene_index, "glTF scene index (default: the file's default scene)")
      ->check(rtp::tools::non_negative());
  app.add_option("--weld", weld, "weld vertices closer than EPS (L-inf, local units)")->check(rtp::tools::non_negative());
  auto* sub = app.add_option("--subdivide", subdivide, "uniform Loop subdivision levels")->check(CLI::Range(0, 8));
  app.add_option("--subdivide-to", subdivide_to, "refine each mesh until its longest world-space edge is below LENGTH")
      ->check(rtp::tools::positive())
      ->excludes(sub);
  app.add_option("--bvh-width", width, "BVH width W: 4, 8 or 16 (default 8)")->check(CLI::IsMember({4, 8, 16}));
  app.add_option("--leaf-width", leaf_width, "triangles per leaf block B: 4, 8 or 16 (default W, 8 for W=16)")
      ->check(CLI::IsMember({4, 8, 16}));
  app.add_option("--bvh-build", build, "collapse (SAH collapse, default) or split (top-down W-way)")
      ->check(CLI::IsMember({"collapse", "split"}));
  app.add_option("--chunk-target", chunk_target, "triangles per batching point (default: derived from the scene)")
      ->check(rtp::tools::chunk_target_range());
  app.add_option("--chunk-by", chunk_by, "count instanced (default) or unique triangles toward the target")
      ->check(CLI::IsMember({"instanced", "unique"}));
  app.add_option("--attributes", attributes,
                 "vertex attributes to store as separate per-chunk streams: normal, uv (comma-separated; default none)")
      ->delimiter(',')
      ->check(CLI::IsMember({"normal", "uv"}));
  app.add_option(
         "--zstd-level", zstd_level,
         "zstd level per chunk, 0 = store, " + std::to_string(rtp::kMinZstdLevel) + "..-1 zstd's fast levels (default " +
             std::to_string(rtp::kDefaultZstdLevel) +
             "; 6: 11-12 % smaller, chunks stage 1.5-1.7x slower; 19: 20-22 % smaller, 12-28x slower; docs/package/zstd.md)")
      ->check(CLI::Range(rtp::kMinZstdLevel, 22));
  bool huffman_literals = false;
  app.add_flag("--zstd-huffman-literals", huffman_literals,
               "Huffman-code zstd's literals in batching points and mesh segments too (default: raw there, 4 % larger, "
               "decompressed about 1.4x faster when tracing out of core; docs/trace/budget.md)");
  int leaf_min_match = rtp::kDefaultLeafMinMatch;
  app.add_option("--zstd-leaf-min-match", leaf_min_match,
                 "zstd's shortest match in batching points and mesh segments, 3..7, or 0 for the level's own (level 3: 5; level "
                 "2: 5 or 6 by chunk size) "
                 "(default " +
                     std::to_string(rtp::kDefaultLeafMinMatch) +
                     ": about 16 % larger there than 0, decompressed about 1.5x "
                     "faster when tracing out of core; docs/package/zstd.md)")
      ->check(CLI::IsMember({0, 3, 4, 5, 6, 7}));
  app.add_option("--threads", threads, "worker threads (default: all cores); the output is identical for any value")
      ->check(rtp::tools::positive());
  bool no_dag = false;
  uint32_t dag_resolution = 0;
  app.add_flag("--no-dag", no_dag, "store no occlusion-culling DAGs (smaller package, no culling)");
  app.add_option("--dag-resolution", dag_resolution,
                 "cells per axis of every batching point's culling grid: a power of two, 4..1024 "
                 "(default: chosen per point from its triangle count, 32..512; halved where cells would be smaller "
                 "than twice the float-rounding margin, far from the origin)")
      ->check([](const std::string& s) {
        try {
          const unsigned long v = std::stoul(s);
          if (v >= 4 && v <= 1024 && (v & (v - 1)) == 0) return std::string();
        } catch (...) {}
        return std::string("must be a power of two from 4 to 1024");
      });
  app.add_flag("-q,--quiet", quiet, "no warnings or progress on stderr");
  app.add_flag("-v,--verbose", verbose, "stage times and peak memory on stderr");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return rtp::tools::parse_error_exit(app, e, "rtpack-convert", argc, argv);
  }
  if (!dry_run && output.empty()) {
    return rtp::tools::report_error("rtpack-convert", json, input, rtp::ExitCode::kUsage, "-o OUTPUT is required (or --dry-run)");
  }
  if (leaf_width == 0) leaf_width = width == 16 ? 8 : width;
  if (!rtp::supported_widths(width, leaf_width)) {
    return rtp::tools::report_error("rtpack-convert", json, input, rtp::ExitCode::kUsage,
                                    "--bvh-width " + std::to_string(width) + " --leaf-width " + std::to_string(leaf_width) +
                                        " is not a supported pair (4/4, 8/8, 16/16, 8/4, 16/8)");
  }
  std::unique_ptr<tbb::global_control> limit;
  if (threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
  rtp::Progress progress(!quiet && !json);
  return rtp::tools::run_reporting_errors(
      "rtpack-convert", json, input,
      [&]() -> int {
        if (!dry_run) {  // before any work
          rtp::check_not_same_file(input, output);
          rtp::check_output_path(output);
        }
        rtp::ConvertSettings cs;
        cs.input = input;
        cs.output = output;
        cs.scene = scene_index;
        cs.allow_paths = allow_paths;
        cs.attributes = attributes;
        cs.weld = weld;
        cs.subdivide = subdivide;
        cs.subdivide_to = subdivide_to;
        cs.width = width;
        cs.leaf_width = leaf_width;
        cs.bvh_build = build;
        cs.chunk_target = chunk_target;
        cs.chunk_by = chunk_by;
        cs.zstd_level = zstd_level;
        cs.zstd_raw_literals = !huffman_literals;
        cs.zstd_leaf_min_match = leaf_min_match;
        cs.dag = !no_dag;
        cs.dag_resolution = dag_resolution;
        cs.dry_run = dry_run;
        cs.topology = topology;
        rtp::ConvertHooks hooks;
        hooks.stage = [&](const std::string& name, bool counts) { progress.stage(name, counts); };
        hooks.progress = [&](uint64_t d, uint64_t t) { progress.update(d, t); };
        hooks.prepared = [&](const rtp::Scene& sc, const rtp::PrepareReport&) {  // warnings before the long stages
          progress.finish();
          if (!quiet)
            for (const auto& w : sc.warnings) std::cerr << "warning: " << input << ": " << w << "\n";
        };
        const rtp::ConvertOutcome done = rtp::convert_scene(cs, hooks);
        progress.finish();
        const rtp::Scene& scene = done.scene;
        if (dry_run) {
          if (json) {
            nlohmann::json j = rtp::scene_summary_json(scene);
            j["preparation"] = rtp::prepare_report_json(done.prepare);
            j.update(rtp::tools::json_stamp("rtpack-convert"));
            std::cout << j.dump(2) << "\n";
          } else {
            std::cout << rtp::scene_summary_text(scene) << "\n" << rtp::prepare_report_text(done.prepare);
          }
          if (verbose)
            std::fprintf(stderr, "import %.3f s, preparation %.3f s, peak RSS %.1f MiB\n", done.import_cost.seconds,
                         done.prepare_cost.seconds, rtp::peak_rss_mib());
          return 0;
        }
        const rtp::Plan& plan = done.plan;
        const rtp::ConvertReport& rep = done.report;
        const double t_import = done.import_cost.seconds, t_prepare = done.prepare_cost.seconds, t_plan = done.plan_cost.seconds,
                     t_chunks = done.chunks_cost.seconds;
        // Input = what the importer read: the glTF/.glb and its external buffers (images are never read).
        const rtp::InputFiles& inf = scene.input;
        const double in_bytes = double(inf.read_bytes());
        const double per_instance = double(rep.package_bytes) / double(std::max<size_t>(1, scene.instances.size()));
        const double tris = double(std::max<uint64_t>(1, scene.unique_triangles()));
        nlohmann::json sections = nlohmann::json::object();
        for (const auto& [kind, s] : rep.by_kind)
          sections[rtp::tools::json_key(kind)] = {{"chunks", s.chunks},
                                                  {"raw_bytes", s.raw},
                                                  {"stored_bytes", s.stored},
                                                  {"bytes_per_unique_triangle", double(s.stored) / tris}};
        nlohmann::json j = {{"input", rtp::utf8_display(input)},
                            {"output", rtp::utf8_display(output)},
                            {"input_bytes", inf.read_bytes()},
                            {"input_files",
                             {{"gltf_bytes", inf.gltf_bytes},
                              {"buffer_bytes", inf.buffer_bytes},
                              {"buffer_files", inf.buffer_files},
                              {"images_not_read", inf.images},
                              {"image_file_bytes_not_read", inf.image_file_bytes}}},
                            {"package_bytes", rep.package_bytes},
                            {"chunks", rep.chunks},
                            {"batching_points", plan.points.size()},
                            {"mesh_segments", plan.segments.size()},
                            {"chunk_target", plan.chunk_target},
                            {"unique_triangles", scene.unique_triangles()},
                            {"instanced_triangles", scene.instanced_triangles()},
                            {"instances", scene.instances.size()},
                            {"bytes_per_unique_triangle", double(rep.package_bytes) / tris},
                            {"bytes_per_instance", per_instance},
                            {"sections", sections},
                            {"dag", nlohmann::json::object()},
                            {"seconds",
                             {{"import", t_import},
                              {"prepare", t_prepare},
                              {"plan", t_plan},
                              {"chunks", t_chunks},
                              {"total", done.total_seconds()}}},
                            {"peak_rss_mib", rtp::peak_rss_mib()}};
        if (!no_dag) {
          nlohmann::json hist = nlohmann::json::object();
          for (const auto& [r, n] : rep.dag_resolutions) hist[std::to_string(r)] = n;
          j["dag"] = {{"pool_bytes", rep.dag_pool_bytes},         {"separate_bytes", rep.dag_separate_bytes},
                      {"set_cells", rep.dag_set_cells},           {"resolutions", hist},
                      {"voxelize_seconds", rep.voxelize_seconds}, {"box_points", rep.box_points},
                      {"box_node_bytes", rep.box_node_bytes}};
        }
        j.update(rtp::tools::json_stamp("rtpack-convert"));
        if (json) {
          std::cout << j.dump(2) << "\n";
        } else if (!quiet) {
          std::printf("%s -> %s\n", input.c_str(), output.c_str());
          std::printf("  triangles      %llu unique, %llu instanced\n", (unsigned long long)scene.unique_triangles(),
                      (unsigned long long)scene.instanced_triangles());
          std::printf("  chunks         %llu (%zu batching points, %zu mesh segments; target %llu triangles)\n",
                      (unsigned long long)rep.chunks, plan.points.size(), plan.segments.size(),
                      (unsigned long long)plan.chunk_target);
          std::string read = human(in_bytes) + " read";
          if (inf.buffer_files > 0)
            read += " (" + human(double(inf.gltf_bytes)) + " glTF + " + std::to_string(inf.buffer_files) +
                    (inf.buffer_files == 1 ? " buffer " : " buffers ") + human(double(inf.buffer_bytes)) + ")";
          if (inf.images > 0) read += ", " + std::to_string(inf.images) + (inf.images == 1 ? " image" : " images") + " not read";
          // Bytes per instance only where some mesh is instanced: for six meshes placed once each, the
          // package's bytes over six (FlightHelmet: "692978.7 B per instance") described nothing.
          const bool instancing =
              std::any_of(plan.mesh_instanced.begin(), plan.mesh_instanced.end(), [](auto m) { return bool(m); });
          char per_inst[64] = "no mesh instanced";
          if (instancing) std::snprintf(per_inst, sizeof per_inst, "%.1f B per instance", per_instance);
          std::printf("  bytes          %s -> %s stored (%.1f B per unique triangle, %s)\n", read.c_str(),
                      human(double(rep.package_bytes)).c_str(), double(rep.package_bytes) / tris, per_inst);
          for (const auto& [kind, s] : rep.by_kind)
            std::printf("    %-28s %5llu chunks %10s raw %10s stored %6.1f B/tri\n", kind.c_str(), (unsigned long long)s.chunks,
                        human(double(s.raw)).c_str(), human(double(s.stored)).c_str(), double(s.stored) / tris);
          if (!no_dag) {
            std::string res;
            for (const auto& [r, n] : rep.dag_resolutions)
              res += (res.empty() ? "" : ", ") + std::to_string(n) + " at " + std::to_string(r) + "^3";
            if (rep.box_points)
              res += (res.empty() ? "" : ", ") + std::to_string(rep.box_points) + " by instance boxes (" +
                     human(double(rep.box_node_bytes)) + " of nodes)";
            std::printf("  culling DAGs   %s in one pool (%s if built apart), %llu set cells; %s; voxelized in %.2f s\n",
                        human(double(rep.dag_pool_bytes)).c_str(), human(double(rep.dag_separate_bytes)).c_str(),
                        (unsigned long long)rep.dag_set_cells, res.c_str(), rep.voxelize_seconds);
          }
          std::printf("  time           import %.2f s, prepare %.2f s, plan %.2f s, chunks %.2f s; peak RSS %.0f MiB\n", t_import,
                      t_prepare, t_plan, t_chunks, rtp::peak_rss_mib());
        }
        if (verbose) {  // what -v adds: each stage with the peak RSS reached by its end, and the settings
          const std::pair<const char*, rtp::StageCost> stages[4] = {{"import", done.import_cost},
                                                                    {"prepare", done.prepare_cost},
                                                                    {"batching points", done.plan_cost},
                                                                    {"chunks", done.chunks_cost}};
          for (const auto& [name, c] : stages)
            std::fprintf(stderr, "stage %-16s %8.3f s  peak RSS %7.1f MiB\n", name, c.seconds, c.peak_rss_mib);
          std::fprintf(stderr, "  of chunks: voxelize %.3f s (summed over threads)\n", rep.voxelize_seconds);
          std::fprintf(stderr, "memory: malloc huge pages %s; %.1f MiB of anonymous huge pages resident at the end\n",
                       rtp::tools::huge_page_state().c_str(), rtp::tools::anon_huge_pages_mib());
          std::fprintf(stderr, "settings: %d threads, W=%d, B=%d, zstd level %d, %s build, chunk target %llu triangles\n",
                       int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)), width, leaf_width,
                       zstd_level, build.c_str(), (unsigned long long)plan.chunk_target);
        }
        return 0;
      },
      [&] { progress.finish(); });
}
