// rtpack-bench --convert: convert time vs an Embree 3 HIGH build of the same triangles, same process.
//
// The converter is run exactly as rtpack-convert runs it with its default options (import_gltf ->
// prepare_scene -> plan_batching_points -> write_package, the same options and metadata), so the
// package written here is byte-identical to `rtpack-convert SCENE -o OUT` with the same --bvh-width,
// --zstd-level and --chunk-target (tests/test_oracle_bench.cpp checks it). Each repetition runs the
// whole pipeline from the file (import included); one warm-up, then the best of --reps by total time;
// the stage times reported are those of that best repetition. Embree is then built from the prepared
// scene of the last repetition as --build-stats builds it (EmbreeOracle, RTC_BUILD_QUALITY_HIGH,
// ROBUST, one instance per rtp::Instance): one warm-up, best of --reps. Both run in one
// tbb::task_arena of --threads threads under a tbb::global_control of the same value.
// Peak RSS (getrusage) is read after the convert repetitions and again after the Embree builds.
#include "bench_convert.h"

#include <sys/types.h>
#include <unistd.h>

#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cinttypes>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>

#include "cluster/cluster.h"
#include "core/error.h"
#include "core/input_file.h"
#include "core/utf8.h"
#include "core/progress.h"
#include "package/convert.h"
#include "malloc_policy.h"
#include "mesh/prepare.h"
#include "oracle/embree_oracle.h"
#include "package/writer.h"
#include "reader/reader.h"
#include "package/write_package.h"
#include "scene/import.h"
#include "tool_version.h"

namespace rtp::bench {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string human(double bytes) { return rtp::human_bytes(bytes); }

std::string percent_decode(const std::string& s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && std::isxdigit((unsigned char)s[i + 1]) && std::isxdigit((unsigned char)s[i + 2])) {
      out += char(std::stoi(s.substr(i + 1, 2), nullptr, 16));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

// The input file's size plus, for a .gltf, the external buffers and images it names by URI (a .glb
// carries them inside). Only files that exist are counted.
uint64_t input_total_bytes(const std::string& path) {
  uint64_t total = fs::file_size(path);
  if (fs::path(path).extension() != ".gltf") return total;
  std::ifstream f(path);
  const json doc = json::parse(f, nullptr, /*allow_exceptions=*/false);
  if (!doc.is_object()) return total;
  const fs::path dir = fs::path(path).parent_path();
  for (const char* key : {"buffers", "images"}) {
    if (!doc.contains(key) || !doc[key].is_array()) continue;
    for (const json& b : doc[key]) {
      if (!b.is_object() || !b.contains("uri") || !b["uri"].is_string()) continue;
      const std::string uri = b["uri"].get<std::string>();
      if (uri.rfind("data:", 0) == 0) continue;
      std::error_code ec;
      const uint64_t n = fs::file_size(dir / percent_decode(uri), ec);
      if (!ec) total += n;
    }
  }
  return total;
}

// One run of the converter pipeline, as rtpack-convert runs it.
struct ConvertRun {
  double import_s = 0, prepare_s = 0, plan_s = 0, chunks_s = 0;
  double total() const { return import_s + prepare_s + plan_s + chunks_s; }
  double without_import() const { return prepare_s + plan_s + chunks_s; }
  ConvertReport report;
  uint64_t unique = 0, instanced = 0, instances = 0, chunk_target = 0;
  size_t points = 0, segments = 0;
  std::vector<std::string> warnings;
};

ConvertRun convert_once(const ConvertBenchConfig& cfg, const std::string& output, Progress& progress, const std::string& label,
                        std::optional<Scene>* keep) {
  // rtpack-convert's own pipeline (package/convert.h) with its defaults and the options this bench
  // exposes: the same call, so the same bytes.
  ConvertSettings cs;
  cs.input = cfg.scene_path;
  cs.output = output;
  cs.allow_paths = cfg.allow_paths;
  cs.width = cfg.bvh_width;
  cs.chunk_target = cfg.chunk_target;
  cs.zstd_level = cfg.zstd_level;
  cs.zstd_raw_literals = cfg.zstd_raw_literals;
  cs.zstd_leaf_min_match = cfg.zstd_leaf_min_match;
  cs.dag = cfg.dag;
  ConvertHooks hooks;
  hooks.stage = [&](const std::string& name, bool counts) { progress.stage(label + name, counts); };
  hooks.progress = [&](uint64_t d, uint64_t t) { progress.update(d, t); };
  ConvertOutcome done = convert_scene(cs, hooks);
  progress.finish();
  ConvertRun r;
  r.import_s = done.import_cost.seconds;
  r.prepare_s = done.prepare_cost.seconds;
  r.plan_s = done.plan_cost.seconds;
  r.chunks_s = done.chunks_cost.seconds;
  r.report = done.report;
  const Scene& scene = done.scene;
  r.unique = scene.unique_triangles();
  r.instanced = scene.instanced_triangles();
  r.instances = scene.instances.size();
  r.chunk_target = done.plan.chunk_target;
  r.points = done.plan.points.size();
  r.segments = done.plan.segments.size();
  r.warnings = scene.warnings;
  if (keep) keep->emplace(std::move(done.scene));
  return r;
}

// Removes the temporary package on every way out.
struct RemoveOnExit {
  std::string path;
  ~RemoveOnExit() {
    if (path.empty()) return;
    std::error_code ec;
    fs::remove(path, ec);
  }
};

}  // namespace

int run_convert_bench(const ConvertBenchConfig& cfg) {
  const int leaf_width = cfg.bvh_width == 16 ? 8 : cfg.bvh_width;
  if (!supported_widths(cfg.bvh_width, leaf_width))
    throw Error(ExitCode::kUsage, "--bvh-width " + std::to_string(cfg.bvh_width) + " is not supported (4, 8 or 16)");
  const int hw = std::max(1, tbb::info::default_concurrency());
  const int threads = cfg.threads > 0 ? cfg.threads : hw;
  const bool keep_output = !cfg.output.empty();
  RemoveOnExit cleanup;
  std::string output = cfg.output;
  if (!keep_output) {
    output = (fs::temp_directory_path() / ("rtpack-bench-convert-" + std::to_string(::getpid()) + ".rtp")).string();
    cleanup.path = output;
  }
  check_not_same_file(cfg.scene_path, output);  // before any work, as rtpack-convert
  check_output_path(output);

  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
  tbb::task_arena arena(threads);
  Progress progress(true);  // only on a terminal

  // Convert: one warm-up, then the best of reps by total time (each from the file, import included).
  std::optional<ConvertRun> best;
  std::optional<Scene> prepared;
  std::vector<std::string> warnings;
  arena.execute([&] {
    for (int r = 0; r <= cfg.reps; ++r) {
      const std::string label =
          r == 0 ? "convert warm-up: " : "convert " + std::to_string(r) + "/" + std::to_string(cfg.reps) + ": ";
      prepared.reset();
      // Each repetition converts as into a new path: the previous repetition's package (ours, written
      // by the warm-up or the run before) is removed untimed, or the next run's atomic replacement would
      // pay for freeing its blocks (FlightHelmet: renameat 2.4 ms of a 54 ms convert at 2 threads).
      // Only a regular file: an output that is a character device (/dev/null) is written in place and
      // must never be unlinked.
      if (std::error_code ec; r > 0 && fs::symlink_status(output, ec).type() == fs::file_type::regular) fs::remove(output, ec);
      ConvertRun run = convert_once(cfg, output, progress, label, r == cfg.reps ? &prepared : nullptr);
      if (r == 0) warnings = run.warnings;
      if (r > 0 && (!best || run.total() < best->total())) best = std::move(run);
    }
  });
  const double rss_convert = peak_rss_mib();
  // The file's size on disk, as measured (not as reported); an output that is a device (/dev/null)
  // has no size: the bytes written to it.
  std::error_code size_ec;
  const bool regular_output = fs::is_regular_file(output, size_ec);
  const uint64_t package_bytes = regular_output ? fs::file_size(output) : best->report.package_bytes;

  // Embree HIGH from the prepared scene: one warm-up, then the best of reps.
  double embree_s = std::numeric_limits<double>::infinity();
  uint64_t embree_geometries = 0;
  arena.execute([&] {
    for (int r = 0; r <= cfg.reps; ++r) {
      progress.stage(r == 0 ? "Embree HIGH warm-up" : "Embree HIGH " + std::to_string(r) + "/" + std::to_string(cfg.reps));
      EmbreeOracle e(*prepared, OracleQuality::kHigh);
      embree_geometries = e.geometry_count();
      if (r > 0) embree_s = std::min(embree_s, e.build_seconds());
    }
  });
  progress.finish();
  const double rss_all = peak_rss_mib();

  const ConvertRun& c = *best;
  const double tris = double(std::max<uint64_t>(1, c.unique));
  uint64_t sections_stored = 0;
  json sections = json::object();
  for (const auto& [kind, s] : c.report.by_kind) {
    sections_stored += s.stored;
    sections[rtp::tools::json_key(kind)] = {{"chunks", s.chunks},
                                            {"raw_bytes", s.raw},
                                            {"stored_bytes", s.stored},
                                            {"bytes_per_unique_triangle", double(s.stored) / tris}};
  }
  const uint64_t container = package_bytes - std::min(package_bytes, sections_stored);
  const uint64_t in_bytes = fs::file_size(cfg.scene_path), in_total = input_total_bytes(cfg.scene_path);
  const std::string cpu = cpu_model();

  if (cfg.json) {
    json rec = {{"type", "convert"},
                {"scene", utf8_display(cfg.scene_path)},
                {"input_bytes", in_bytes},
                {"input_total_bytes", in_total},
                {"package_bytes", package_bytes},
                {"package", keep_output ? json(utf8_display(cfg.output)) : json(nullptr)},
                {"unique_triangles", c.unique},
                {"instanced_triangles", c.instanced},
                {"instances", c.instances},
                {"stored_triangles", c.report.unique_triangles},
                {"chunks", c.report.chunks},
                {"batching_points", c.points},
                {"mesh_segments", c.segments},
                {"chunk_target", c.chunk_target},
                {"bvh_width", cfg.bvh_width},
                {"leaf_width", leaf_width},
                {"zstd_level", cfg.zstd_level},
                {"zstd_raw_literals", cfg.zstd_raw_literals},
                {"zstd_leaf_min_match", cfg.zstd_leaf_min_match},
                {"dag", cfg.dag},
                {"sections", sections},
                {"sections_stored_bytes", sections_stored},
                {"container_bytes", container},
                {"bvh_node_raw_bytes", c.report.node_bytes},
                {"bvh_block_raw_bytes", c.report.block_bytes},
                {"bytes_per_unique_triangle", double(package_bytes) / tris},
                {"seconds",
                 {{"import", c.import_s},
                  {"prepare", c.prepare_s},
                  {"plan", c.plan_s},
                  {"chunks", c.chunks_s},
                  {"total", c.total()},
                  {"without_import", c.without_import()}}},
                {"embree_high_build_seconds", embree_s},
                {"embree_geometries", embree_geometries},
                {"ratio_embree_over_convert", embree_s / c.total()},
                {"ratio_embree_over_convert_without_import", embree_s / c.without_import()},
                {"ratio_embree_over_chunks", embree_s / c.chunks_s},
                {"peak_rss_mib_convert", rss_convert},
                {"peak_rss_mib", rss_all},
                {"malloc_huge_pages", rtp::tools::huge_page_state()},
                {"threads", threads},
                {"hardware_threads", hw},
                {"reps", cfg.reps},
                {"cpu", cpu}};
    rec.update(rtp::tools::json_stamp("rtpack-bench"));
    std::cout << json::array({rec}).dump(1) << "\n";
  }

  FILE* o = cfg.json ? stderr : stdout;
  for (const std::string& w : warnings) std::fprintf(o, "warning: %s: %s\n", cfg.scene_path.c_str(), w.c_str());
  std::fprintf(o, "convert %s -> %s%s\n", cfg.scene_path.c_str(), output.c_str(), keep_output ? "" : " (temporary, deleted)");
  std::fprintf(
      o, "cpu %s; %d of %d hardware threads; W=%d B=%d, zstd %d, chunk target %" PRIu64 "%s%s; best of %d after a warm-up\n",
      cpu.c_str(), threads, hw, cfg.bvh_width, leaf_width, cfg.zstd_level, c.chunk_target, cfg.chunk_target ? "" : " (derived)",
      cfg.dag ? "" : ", no culling DAGs (--no-dag)", cfg.reps);
  std::fprintf(o,
               "triangles %" PRIu64 " unique, %" PRIu64 " instanced (%" PRIu64 " instances); %" PRIu64
               " chunks (%zu batching points, %zu mesh segments)\n",
               c.unique, c.instanced, c.instances, c.report.chunks, c.points, c.segments);
  std::fprintf(o, "bytes %s input (%" PRIu64 " B; %" PRIu64 " B with external files) -> %s package (%" PRIu64 " B)\n",
               human(double(in_bytes)).c_str(), in_bytes, in_total, human(double(package_bytes)).c_str(), package_bytes);
  std::fprintf(o, "\n  %-40s %7s %12s %12s %10s\n", "section", "chunks", "raw B", "stored B", "B/unique");
  for (const auto& [kind, s] : c.report.by_kind)
    std::fprintf(o, "  %-40s %7" PRIu64 " %12" PRIu64 " %12" PRIu64 " %10.2f\n", kind.c_str(), s.chunks, s.raw, s.stored,
                 double(s.stored) / tris);
  std::fprintf(o, "  %-40s %7s %12s %12" PRIu64 " %10.2f\n", "container (header, TOC, 4 KiB padding)", "", "", container,
               double(container) / tris);
  std::fprintf(o, "  %-40s %7s %12s %12" PRIu64 " %10.2f\n", "package, all in", "", "", package_bytes,
               double(package_bytes) / tris);
  std::fprintf(o, "\n  %-40s %10s\n", "stage (best repetition)", "seconds");
  std::fprintf(o, "  %-40s %10.4f\n", "import", c.import_s);
  std::fprintf(o, "  %-40s %10.4f\n", "prepare", c.prepare_s);
  std::fprintf(o, "  %-40s %10.4f\n", "plan (batching points)", c.plan_s);
  std::fprintf(o, "  %-40s %10.4f\n", "chunks (BVH + zstd + write)", c.chunks_s);
  std::fprintf(o, "  %-40s %10.4f\n", "convert total", c.total());
  std::fprintf(o, "  %-40s %10.4f\n", "convert without import", c.without_import());
  std::fprintf(o, "  %-40s %10.4f  (%" PRIu64 " instances)\n", "Embree 3 HIGH build (ROBUST)", embree_s, embree_geometries);
  std::fprintf(o, "\n  Embree / convert %.3f, Embree / convert without import %.3f, Embree / chunks %.3f\n", embree_s / c.total(),
               embree_s / c.without_import(), embree_s / c.chunks_s);
  std::fprintf(o, "  peak RSS %.1f MiB after the convert runs, %.1f MiB after the Embree builds\n", rss_convert, rss_all);
  std::fprintf(o, "  malloc huge pages %s (both the convert and Embree run in this process)\n",
               rtp::tools::huge_page_state().c_str());
  return 0;
}

nlohmann::json mode_run_json(const std::string& scene, const char* isa, int threads, int reps, nlohmann::json records) {
  nlohmann::json j = rtp::tools::json_stamp("rtpack-bench");
  j["scene"] = scene;
  j["cpu"] = cpu_model();
  j["isa"] = isa;
  j["threads"] = threads;
  j["reps"] = reps;
  j["records"] = std::move(records);
  return j;
}

std::string cpu_model() {
  std::ifstream f("/proc/cpuinfo");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("model name", 0) == 0) {
      const size_t p = line.find(':');
      if (p != std::string::npos) return line.substr(p + 2);
    }
  return "unknown";
}

}  // namespace rtp::bench
