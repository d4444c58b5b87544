// rtpack-bench: rtpack's in-core tracer against Embree 3 (ROBUST, HIGH) on the same rays, in the same run.
//
// Loads a glTF scene, builds Embree directly from it and rtpack's InCoreScene<W,W> for each width,
// generates the rays once (lib/oracle/rays.h, seeded), times both tracers on exactly those rays
// (best of --reps interleaved runs after a warm-up; 1..T threads through tbb::task_arena), and verifies, untimed,
// that every timed rtpack answer agrees with Embree ray by ray (lib/oracle/compare.h). Shadow rays
// are timed as any-hit queries (trace_any vs rtcOccluded1M), every other kind as closest hit.
// Embree is driven as its documentation advises: primary rays (4x4 tiles) in rtcIntersect16 packets
// with the COHERENT flag, other rays in rtcIntersect1M/rtcOccluded1M streams with the INCOHERENT flag;
// the reference answers are always the robust stream ones.
//
// Exit codes: 0 ok, 1 usage, 2 input unreadable, 3 invalid input (or no triangles), 5 rtpack disagreed
// with Embree on some ray (the numbers are printed, but they are not worth anything).
//
// --convert instead times the converter (rtpack-convert's pipeline) against an Embree HIGH build of the
// same prepared scene: tools/bench_convert.cpp. --dag SCENE... measures the occlusion-culling DAGs
// (bytes, voxelization, culling on vs off, convert cost): tools/bench_dag.cpp.
#include <CLI/CLI.hpp>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "bench_agreement.h"
#include "bench_kinds.h"
#include "bench_budget.h"
#include "bench_paths.h"
#include "bench_convert.h"
#include "bench_dag.h"
#include "bench_multi_hit.h"
#include "bench_packets.h"
#include "bench_records.h"
#include "bench_timing.h"
#include "bvh/bvh.h"
#include "core/error.h"
#include "core/utf8.h"
#include "oracle/compare.h"
#include "oracle/embree_oracle.h"
#include "oracle/rays.h"
#include "package/writer.h"
#include "reader/reader.h"  // kMinZstdLevel
#include "scene/import.h"
#include "trace/trace.h"
#include "malloc_policy.h"
#include "cli_checks.h"
#include "tool_version.h"

namespace {

using namespace rtp;
using bench::Agreement;
using bench::agreement_any;
using bench::agreement_closest;
using bench::best_of;
using bench::build_record_json;
using bench::BuildRecord;
using bench::Clock;
using bench::KindData;
using bench::make_kind;
using bench::print_row;
using bench::Record;
using bench::sah_record_json;
using bench::seconds_since;
using bench::trace_record_json;
using nlohmann::json;

constexpr size_t kGrain = 256;  // rays per TBB task, the same for both tracers (EmbreeOracle uses 256)

struct Config {
  std::string scene_path;
  std::vector<std::string> allow_paths;  // --allow-path: further directories for external buffers
  size_t rays = 1u << 16;                // --all: 1 << 19
  std::vector<RayKind> kinds;
  std::vector<int> widths;
  std::vector<int> threads;
  std::vector<TraversalOrder> orders;
  Isa isa = Isa::kScalar;
  int reps = 3;
  uint64_t seed = 1;
  // Primary rays are timed as packets of this many consecutive rays (Wu 2016; 0 = single rays), as
  // Embree's are timed in its 16-ray packets.
  uint32_t primary_packet = 16;
  // --hot-rays N: each kind's first N rays, repeated in order up to `rays` (0: every ray its own).
  size_t hot_rays = 0;
  bool json = false;
  bool build_stats = false;
  size_t steps = 0, step = 0;  // timed configurations, for the progress line
  FILE* table = stdout;        // rows are printed here as each configuration finishes
};

bool g_progress = false;
void progress(const std::string& s) {
  if (g_progress) std::fprintf(stderr, "\r\033[K%s", s.c_str());
}
void progress_done() {
  if (g_progress) std::fprintf(stderr, "\r\033[K");
}

std::vector<std::string> split_list(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

template <int W>
uint64_t mesh_bvh_bytes(const InCoreScene<W, W>& s) {
  uint64_t b = 0;
  for (size_t m = 0; m < s.mesh_count(); ++m) b += s.mesh_stats(m).node_bytes + s.mesh_stats(m).block_bytes;
  return b;
}

template <int W>
void run_width(Config& cfg, const Scene& scene, const EmbreeOracle& embree, std::vector<KindData>& kinds,
               std::vector<Record>& records, std::vector<BuildRecord>& builds) {
  const int max_threads = *std::max_element(cfg.threads.begin(), cfg.threads.end());
  progress("building rtpack W=" + std::to_string(W) + " ...");
  std::optional<InCoreScene<W, W>> bvh;
  {
    tbb::task_arena arena(max_threads);
    arena.execute([&] { bvh.emplace(InCoreScene<W, W>::build(scene)); });
  }
  const double unique = double(std::max<uint64_t>(1, scene.unique_triangles()));
  const uint64_t bytes = mesh_bvh_bytes(*bvh);
  const double bpt = double(bytes) / unique;

  if (cfg.build_stats) {
    for (int t : cfg.threads) {
      tbb::task_arena arena(t);
      BuildRecord br;
      br.width = W;
      br.threads = t;
      br.bytes_per_triangle = bpt;
      br.bvh_bytes = bytes;
      const int reps = std::max(1, std::min(cfg.reps, 3));
      progress("build timing W=" + std::to_string(W) + " T=" + std::to_string(t) + " ...");
      arena.execute([&] {
        br.rtpack_seconds = best_of(reps, [&] { (void)InCoreScene<W, W>::build(scene); });
        br.embree_seconds = std::numeric_limits<double>::infinity();
        for (int r = 0; r < reps + 1; ++r) {
          EmbreeOracle e(scene, OracleQuality::kHigh);
          if (r > 0) br.embree_seconds = std::min(br.embree_seconds, e.build_seconds());
        }
      });
      builds.push_back(br);
    }
  }

  const SceneView<W, W> view = bvh->view();
  for (KindData& k : kinds) {
    const size_t n = k.rays.size();
    std::vector<fmt::Hit> hits(n), embree_hits(n);
    std::vector<uint8_t> occ(n), embree_occ(n);
    for (TraversalOrder order : cfg.orders) {
      // Packets walk in octant order whatever `order` says: one packet row per kind, not one per order.
      const uint32_t packet = k.kind == RayKind::kPrimary && cfg.isa != Isa::kScalar ? cfg.primary_packet : 0;
      if (packet && order != cfg.orders.front()) continue;
      const TraceOptions topt{cfg.isa, order, packet};
      for (int t : cfg.threads) {
        ++cfg.step;
        progress("[" + std::to_string(cfg.step) + "/" + std::to_string(cfg.steps) + "] timing " + ray_kind_name(k.kind) +
                 " W=" + std::to_string(W) + " " + order_name(order) + " T=" + std::to_string(t) + " ...");
        tbb::task_arena arena(t);
        auto rtpack_run = [&] {
          tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kGrain), [&](const tbb::blocked_range<size_t>& r) {
            if (k.any)
              trace_any<W, W>(view, k.rays.data() + r.begin(), occ.data() + r.begin(), r.size(), topt);
            else
              trace_closest<W, W>(view, k.rays.data() + r.begin(), hits.data() + r.begin(), r.size(), topt);
          });
        };
        auto embree_run = [&](RayCoherence c) {
          if (k.any)
            embree.occluded(k.rays.data(), embree_occ.data(), n, c);
          else
            embree.closest(k.rays.data(), embree_hits.data(), n, c);
        };
        // Incoherent rays: Embree both ways, its stream and one call per ray (either can be the faster).
        const bool per_ray = k.coherence == RayCoherence::kIncoherent;
        // Interleaved repetitions (rtpack, Embree, rtpack, ...) after one warm-up of each, best of each:
        // a change of machine load during the run hits both sides alike.
        double secs = std::numeric_limits<double>::infinity(), embree_secs = secs, single_secs = secs;
        arena.execute([&] {
          rtpack_run();
          embree_run(k.coherence);
          if (per_ray) embree_run(RayCoherence::kSingle);
          for (int r = 0; r < cfg.reps; ++r) {
            auto t0 = Clock::now();
            rtpack_run();
            secs = std::min(secs, seconds_since(t0));
            t0 = Clock::now();
            embree_run(k.coherence);
            embree_secs = std::min(embree_secs, seconds_since(t0));
            if (!per_ray) continue;
            t0 = Clock::now();
            embree_run(RayCoherence::kSingle);
            single_secs = std::min(single_secs, seconds_since(t0));
          }
        });
        Record rec;
        rec.kind = k.kind;
        rec.width = W;
        rec.order = packet ? TraversalOrder::kOctantStack : order;
        rec.packet = packet;
        rec.threads = t;
        rec.rtpack_mrays = double(n) / secs * 1e-6;
        rec.embree_stream_mrays = double(n) / embree_secs * 1e-6;
        rec.embree_single_mrays = per_ray ? double(n) / single_secs * 1e-6 : 0;
        rec.embree_mrays = std::max(rec.embree_stream_mrays, rec.embree_single_mrays);
        rec.embree_path = !per_ray ? (k.any ? "stream" : "packet16") : single_secs < embree_secs ? "per-ray" : "stream";
        if (!per_ray) rec.embree_stream_mrays = 0;
        rec.bytes_per_triangle = bpt;
        // Verify the timed answers (untimed).
        if (k.any) {
          arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kGrain), [&](const tbb::blocked_range<size_t>& r) {
              trace_closest<W, W>(view, k.rays.data() + r.begin(), hits.data() + r.begin(), r.size(), topt);
            });
          });
          rec.agreement = agreement_any(scene, k, occ, hits);
        } else {
          rec.agreement = agreement_closest(scene, k, hits);
        }
        records.push_back(rec);
        progress_done();
        print_row(cfg.table, rec);
      }
    }
  }
}

int run(Config& cfg) {
  const auto t_load = Clock::now();
  progress("loading " + cfg.scene_path + " ...");
  ImportOptions import_options;
  import_options.allowed_dirs = cfg.allow_paths;
  const Scene scene = import_gltf(cfg.scene_path, import_options);
  if (scene.instanced_triangles() == 0) throw Error(ExitCode::kInputInvalid, "the scene has no triangles");
  const double load_s = seconds_since(t_load);
  const int max_threads = *std::max_element(cfg.threads.begin(), cfg.threads.end());

  progress("building Embree (ROBUST, HIGH) ...");
  std::optional<EmbreeOracle> embree;
  {
    tbb::task_arena arena(max_threads);
    arena.execute([&] { embree.emplace(scene, OracleQuality::kHigh); });
  }

  // Rays, once, and Embree's (robust stream) answers to them: the reference.
  std::vector<KindData> kinds;
  for (RayKind kind : cfg.kinds) {
    progress(std::string("generating ") + ray_kind_name(kind) + " rays ...");
    kinds.push_back(make_kind(scene, *embree, kind, cfg.rays, cfg.seed, cfg.hot_rays));
  }

  // The header now and each row as its configuration finishes (stdout, or stderr when stdout carries JSON).
  FILE* o = cfg.json ? stderr : stdout;
  cfg.table = o;
  cfg.steps = 0;
  for (RayKind kind : cfg.kinds)  // a packet row (primary rays) walks in one order
    cfg.steps += (kind == RayKind::kPrimary && cfg.primary_packet && cfg.isa != Isa::kScalar ? 1 : cfg.orders.size()) *
                 cfg.widths.size() * cfg.threads.size();
  const std::string cpu = rtp::bench::cpu_model();
  progress_done();
  std::fprintf(o, "scene %s: %" PRIu64 " instanced / %" PRIu64 " unique triangles, %zu meshes, %zu instances (load %.2f s)\n",
               cfg.scene_path.c_str(), scene.instanced_triangles(), scene.unique_triangles(), scene.meshes.size(),
               scene.instances.size(), load_s);
  std::fprintf(o, "cpu %s; isa %s; %zu rays per kind, seed %" PRIu64 ", best of %d interleaved runs after a warm-up\n",
               cpu.c_str(), isa_name(cfg.isa), cfg.rays, cfg.seed, cfg.reps);
  if (cfg.hot_rays)
    std::fprintf(o, "hot rays: each kind's first %zu rays repeated (cached data, learnt branches: the cost in instructions)\n",
                 cfg.hot_rays);
  for (const KindData& k : kinds) {
    if (k.info.fallback) std::fprintf(o, "note: %s: %zu rays: %s\n", ray_kind_name(k.kind), k.info.fallback, k.info.note.c_str());
    if (k.embree_timed_failures)
      std::fprintf(o, "note: %s: Embree's timed %s path disagrees with its own robust stream answers on %" PRIu64 " rays\n",
                   ray_kind_name(k.kind), k.kind == RayKind::kPrimary ? "packet" : "stream", k.embree_timed_failures);
  }
  // B/tri: the in-memory BVH (nodes + leaf blocks, raw) per unique triangle, not the stored package.
  // Embree's column is its faster path for the row: packet16 (primary), stream (1M) or per-ray (one call each).
  std::fprintf(o, "\n%-8s %-7s %3s %-12s %3s %14s %14s %-8s %7s %8s  %s\n", "kind", "query", "W", "order", "T", "rtpack Mrays/s",
               "Embree Mrays/s", "path", "ratio", "mem B/tri",
               "agree / edge ties / precision ties / FAILURES / skipped / Embree errors");
  std::fflush(o);

  std::vector<Record> records;
  std::vector<BuildRecord> builds;
  for (int w : cfg.widths) {
    if (w == 4) run_width<4>(cfg, scene, *embree, kinds, records, builds);
    if (w == 8) run_width<8>(cfg, scene, *embree, kinds, records, builds);
    if (w == 16) run_width<16>(cfg, scene, *embree, kinds, records, builds);
  }

  // The SAH table of lib/bvh (whole scene flattened when small enough, else the scene's meshes).
  std::string sah_table;
  std::vector<BvhStatsRow> sah_rows;
  if (cfg.build_stats) {
    progress("SAH statistics ...");
    std::vector<BvhStatsRow> rows;
    const std::string base = cfg.scene_path.substr(cfg.scene_path.find_last_of('/') + 1);
    if (scene.instanced_triangles() <= 2'000'000) {
      rows = bvh_stats_rows(base, flatten_scene(scene));
    } else {
      for (const Mesh& m : scene.meshes) {
        if (m.triangle_count() == 0) continue;
        auto r = bvh_stats_rows(base + ":" + m.name, m);
        rows.insert(rows.end(), r.begin(), r.end());
      }
    }
    sah_table = bvh_stats_table(rows);
    sah_rows = rows;
  }
  progress_done();

  uint64_t failures = 0;
  for (const Record& r : records) failures += r.agreement.failures;
  if (cfg.json) {
    json out = json::array();
    for (const Record& r : records) {
      const KindData* k = nullptr;
      for (const KindData& x : kinds)
        if (x.kind == r.kind) k = &x;
      out.push_back(trace_record_json(r, *k, cfg.scene_path, cfg.isa, cpu, cfg.hot_rays));
    }
    for (const BuildRecord& b : builds) out.push_back(build_record_json(b, cfg.scene_path, cpu));
    for (const BvhStatsRow& r : sah_rows) out.push_back(sah_record_json(r, cfg.scene_path));
    // Agreement failures (exit 5): the records, then one record carrying the `error` object (docs/json.md).
    if (failures)
      out.push_back(
          {{"type", "error"},
           {"error", rtp::tools::error_json("rtpack-bench", cfg.scene_path, ExitCode::kInternal,
                                            "rtpack disagrees with Embree on " + std::to_string(failures) + " rays")["error"]}});
    for (auto& rec : out) rec.update(rtp::tools::json_stamp("rtpack-bench"));
    std::cout << out.dump(1) << "\n";
  }

  if (!builds.empty()) {
    std::fprintf(o, "\nbuild (same triangles; Embree ROBUST + HIGH quality):\n%3s %3s %12s %14s %15s %10s\n", "W", "T",
                 "rtpack s", "Embree HIGH s", "Embree/rtpack", "mem B/tri");
    for (const BuildRecord& b : builds)
      std::fprintf(o, "%3d %3d %12.3f %14.3f %15.2f %10.1f\n", b.width, b.threads, b.rtpack_seconds, b.embree_seconds,
                   b.embree_seconds / b.rtpack_seconds, b.bytes_per_triangle);
    std::fprintf(o, "\nSAH statistics (lib/bvh, Benthin 2008 Table 1 style):\n%s\n", sah_table.c_str());
  }
  if (failures) {
    std::fprintf(o, "\nAGREEMENT FAILURES: rtpack disagrees with Embree on %" PRIu64 " rays; these numbers are worthless.\n",
                 failures);
    for (const Record& r : records)
      if (!r.agreement.first_failure.empty()) {
        std::fprintf(o, "first failure (%s W=%d %s T=%d):\n%s", ray_kind_name(r.kind), r.width, order_name(r.order), r.threads,
                     r.agreement.first_failure.c_str());
        break;
      }
    return int(ExitCode::kInternal);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  rtp::tools::configure_malloc(argv);  // first: may re-execute with huge pages (malloc_policy.h)
  CLI::App app{"rtpack-bench: rtpack's in-core tracer vs Embree 3 (ROBUST) on the same rays, same run"};
  rtp::tools::add_version_flag(app, "rtpack-bench");
  Config cfg;
  std::string kinds = "primary,random,bounce,shadow", width = "8", threads = "all", order = "octant", isa = "best";
  bool all = false;
  app.add_option("scene", cfg.scene_path, "input .gltf or .glb")->required();
  app.add_option("--allow-path", cfg.allow_paths,
                 "also read external buffers from DIR (repeatable; default: only inside the glTF's directory)");
  app.add_option("--rays", cfg.rays, "rays per kind (default 65536; 524288 with --all)")
      ->check(CLI::Range(size_t(1), size_t(1) << 30));
  app.add_option(
      "--kinds", kinds,
      "comma-separated: primary,random,bounce,shadow,inside,short, and path with --out-of-core (a path tracer through the "
      "ray stream; default primary,random,bounce,shadow)");
  app.add_option("--width", width, "BVH width W (= leaf block B): 4, 8, 16 or all (default 8)");
  app.add_option("--threads", threads, "thread count or all (1, 2, 4, ... up to the hardware threads; default all)");
  app.add_option("--order", order, "traversal order: octant, active or all (default octant)");
  auto* all_flag = app.add_flag("--all", all,
                                "the full sweep: every width and order, 524288 rays per kind (an explicit --width, "
                                "--order or --rays still wins); takes minutes");
  app.add_option("--isa", isa, "best, scalar, avx2 or avx512 (default best)");
  app.add_option("--reps", cfg.reps, "timed repetitions, best taken (default 3)")->check(CLI::Range(1, 100));
  app.add_option("--seed", cfg.seed, "ray generator seed (default 1)")->check(rtp::tools::unsigned_integer());
  app.add_option("--primary-packet", cfg.primary_packet,
                 "rays per packet for primary rays: 4, 8, 16, or 0 for single rays (default 16; Embree's are timed in "
                 "16-ray packets)")
      ->check(CLI::IsMember({0, 4, 8, 16}));
  auto* hot_opt = app.add_option("--hot-rays", cfg.hot_rays,
                                 "time each kind's first N rays repeated up to --rays: their data stays in cache and "
                                 "their branches are learnt, so the run shows the cost in instructions alone (beside a "
                                 "default run, what cache misses and mispredictions cost)")
                      ->check(CLI::Range(size_t(1), size_t(1) << 30));
  app.add_flag("--json", cfg.json, "print the records as a JSON array on stdout (the table goes to stderr)");
  auto* build_stats =
      app.add_flag("--build-stats", cfg.build_stats, "also time BVH builds against Embree HIGH and print lib/bvh's SAH table");
  bench::ConvertBenchConfig conv;
  bool convert = false;
  auto* convert_flag = app.add_flag(
      "--convert", convert,
      "instead of tracing: time rtpack-convert's pipeline (import, prepare, plan, chunks) against an Embree HIGH build "
      "of the same prepared scene; --threads T runs both with T threads (default all); prints sizes per section");
  app.add_option("--convert-output", conv.output, "--convert: keep the package here (default: a temporary file, deleted)")
      ->needs(convert_flag);
  app.add_option("--bvh-width", conv.bvh_width, "--convert: BVH width W, 4, 8 or 16 (leaf width W, 8 for W=16; default 8)")
      ->check(CLI::IsMember({4, 8, 16}))
      ->needs(convert_flag);
  app.add_option("--zstd-level", conv.zstd_level,
                 "--convert: zstd level per chunk, 0 = store, " + std::to_string(rtp::kMinZstdLevel) +
                     "..-1 zstd's fast levels (default " + std::to_string(rtp::kDefaultZstdLevel) + ")")
      ->check(CLI::Range(rtp::kMinZstdLevel, 22))
      ->needs(convert_flag);
  app.add_flag("--zstd-huffman-literals{false}", conv.zstd_raw_literals,
               "--convert: Huffman-code zstd's literals in batching points and mesh segments too (as rtpack-convert)")
      ->needs(convert_flag);
  app.add_option("--zstd-leaf-min-match", conv.zstd_leaf_min_match,
                 "--convert: zstd's shortest match in batching points and mesh segments, 3..7 or 0 for the level's own (as "
                 "rtpack-convert)")
      ->check(CLI::IsMember({0, 3, 4, 5, 6, 7}))
      ->needs(convert_flag);
  app.add_option("--chunk-target", conv.chunk_target, "--convert: triangles per batching point (default: derived)")
      ->check(rtp::tools::chunk_target_range())
      ->needs(convert_flag);
  app.add_flag("--no-dag{false}", conv.dag,
               "--convert: store no culling DAGs (as rtpack-convert --no-dag): beside a default run, what the DAGs cost")
      ->needs(convert_flag);
  for (const char* trace_only : {"--rays", "--kinds", "--width", "--order", "--isa", "--seed"})
    convert_flag->excludes(app.get_option(trace_only));
  convert_flag->excludes(build_stats);
  convert_flag->excludes(hot_opt);
  convert_flag->excludes(all_flag);
  bench::BudgetBenchConfig budget;
  CLI::Option* ooc_opt = bench::add_budget_options(app, budget);
  bench::PathBenchConfig paths;
  bench::add_path_options(app, paths, ooc_opt);
  ooc_opt->excludes(convert_flag)->excludes(build_stats)->excludes(all_flag)->excludes(hot_opt);
  bench::DagBenchConfig dag;
  CLI::Option* dag_opt = bench::add_dag_options(app, dag);
  dag_opt->excludes(convert_flag)->excludes(build_stats)->excludes(all_flag)->excludes(hot_opt);
  bench::MultiHitBenchConfig multi;
  bench::add_multi_hit_options(app, multi)
      ->excludes(convert_flag)
      ->excludes(build_stats)
      ->excludes(all_flag)
      ->excludes(ooc_opt)
      ->excludes(dag_opt)
      ->excludes(hot_opt);
  bench::PacketBenchConfig packets;
  bench::add_packet_options(app, packets)
      ->excludes(convert_flag)
      ->excludes(build_stats)
      ->excludes(all_flag)
      ->excludes(ooc_opt)
      ->excludes(dag_opt)
      ->excludes("--multi-hit")
      ->excludes(hot_opt);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return tools::parse_error_exit(app, e, "rtpack-bench", argc, argv);
  }
  auto usage = [&cfg](const std::string& msg) {
    return tools::report_error("rtpack-bench", cfg.json, cfg.scene_path, ExitCode::kUsage, msg);
  };
  if (all) {
    if (!app.count("--width")) width = "all";
    if (!app.count("--order")) order = "all";
    if (!app.count("--rays")) cfg.rays = size_t(1) << 19;
  }
  bool path_kind = false;  // --kinds path: the renderer's workload, --out-of-core only (bench_paths.h)
  for (const std::string& k : split_list(kinds)) {
    if (k == "path" && app.count("--out-of-core")) {
      path_kind = true;
      continue;
    }
    const auto kind = parse_ray_kind(k);
    if (!kind)
      return usage("unknown ray kind '" + k + "' (primary, random, bounce, shadow, inside, short; path with --out-of-core)");
    if (std::find(cfg.kinds.begin(), cfg.kinds.end(), *kind) == cfg.kinds.end()) cfg.kinds.push_back(*kind);
  }
  if (cfg.kinds.empty() && !path_kind) return usage("--kinds is empty");
  if (cfg.hot_rays > cfg.rays)
    return usage("--hot-rays " + std::to_string(cfg.hot_rays) + " is more than --rays " + std::to_string(cfg.rays));
  if (width == "all")
    cfg.widths = {4, 8, 16};
  else if (width == "4" || width == "8" || width == "16")
    cfg.widths = {std::stoi(width)};
  else
    return usage("--width must be 4, 8, 16 or all, not '" + width + "'");
  const int hw = std::max(1, tbb::info::default_concurrency());
  if (threads == "all") {
    for (int t = 1; t < hw; t *= 2) cfg.threads.push_back(t);
    cfg.threads.push_back(hw);
  } else {
    char* end = nullptr;
    const long t = std::strtol(threads.c_str(), &end, 10);
    if (threads.empty() || *end != '\0' || t < 1 || t > 64) return usage("--threads must be 1..64 or all, not '" + threads + "'");
    cfg.threads = {int(t)};
  }
  if (order == "all")
    cfg.orders = {TraversalOrder::kOctantStack, TraversalOrder::kActiveList};
  else if (order == "octant")
    cfg.orders = {TraversalOrder::kOctantStack};
  else if (order == "active")
    cfg.orders = {TraversalOrder::kActiveList};
  else
    return usage("--order must be octant, active or all, not '" + order + "'");
  const Isa best = detect_isa();
  if (isa == "best")
    cfg.isa = best;
  else if (isa == "scalar")
    cfg.isa = Isa::kScalar;
  else if (isa == "avx2")
    cfg.isa = Isa::kAvx2;
  else if (isa == "avx512")
    cfg.isa = Isa::kAvx512;
  else
    return usage("--isa must be best, scalar, avx2 or avx512, not '" + isa + "'");
  if (int(cfg.isa) > int(best)) return usage(std::string("this CPU does not support ") + isa + " (best: " + isa_name(best) + ")");
  g_progress = isatty(2) != 0;
  return rtp::tools::run_reporting_errors(
      "rtpack-bench", cfg.json, cfg.scene_path,
      [&]() -> int {
        if (convert) {
          conv.scene_path = cfg.scene_path;
          conv.allow_paths = cfg.allow_paths;
          conv.threads = threads == "all" ? 0 : cfg.threads[0];
          conv.reps = cfg.reps;
          conv.json = cfg.json;
          return bench::run_convert_bench(conv);
        }
        // The main command line's settings every mode shares (--rays and --kinds only when given:
        // each mode has its own defaults).
        const auto shared = [&](bench::ModeConfig& m) {
          m.scene_path = cfg.scene_path;
          m.allow_paths = cfg.allow_paths;
          m.threads = threads == "all" ? 0 : cfg.threads[0];
          m.reps = cfg.reps, m.json = cfg.json, m.seed = cfg.seed, m.isa = cfg.isa;
          if (app.count("--rays")) m.rays = cfg.rays;
          if (app.count("--kinds")) m.kinds = cfg.kinds;
        };
        if (app.count("--out-of-core")) {
          shared(budget);
          if (path_kind && cfg.kinds.empty()) return bench::run_path_bench(budget, paths);
          const int rc = bench::run_budget_bench(budget);
          return rc != 0 || !path_kind ? rc : bench::run_path_bench(budget, paths);
        }
        if (app.count("--multi-hit")) {
          shared(multi);
          return bench::run_multi_hit_bench(multi);
        }
        if (app.count("--packets")) {
          shared(packets);
          return bench::run_packet_bench(packets);
        }
        if (app.count("--dag")) {
          shared(dag);
          dag.scenes.insert(dag.scenes.begin(), cfg.scene_path);
          dag.order = cfg.orders[0];
          return bench::run_dag_bench(dag);
        }
        return run(cfg);
      },
      progress_done);
}
