// rtpack-bench --out-of-core: time and bytes read against the memory budget (Molenaar 2019 §5.3).
#include "bench_budget.h"

#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "bench_convert.h"
#include "cli_checks.h"
#include "core/error.h"
#include "core/output_file.h"
#include "core/progress.h"
#include "package/convert.h"
#include "reader/reader.h"
#include "tool_version.h"
#include "trace/out_of_core.h"
#include "trace/package_tracer.h"
#include "trace/tracer.h"

namespace rtp::bench {
namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

}  // namespace

CLI::Option* add_budget_options(CLI::App& app, BudgetBenchConfig& cfg) {
  CLI::Option* ooc = app.add_option("--out-of-core", cfg.package,
                                    "instead: trace the package PKG (converted from the scene) out of core for each --budgets "
                                    "percentage, culling on and off, against the in-core tracer on the same rays (default: "
                                    "bounce rays; each run best of --reps, interleaved, after an untimed warm-up); prints "
                                    "time, bytes read, chunks loaded");
  app.add_option("--budgets", cfg.budgets_text,
                 "--out-of-core: comma-separated percentages of the on-demand bytes (default 100,50,25,10,5)")
      ->needs(ooc);
  app.add_flag("--direct-io", cfg.direct_io, "--out-of-core: read chunks with O_DIRECT (the page cache does not hide the disk)")
      ->needs(ooc);
  app.add_flag("--prefetch", cfg.prefetch, "--out-of-core: read ahead on an I/O thread while a round traces")->needs(ooc);
  app.add_option("--culling", cfg.culling, "--out-of-core: run with DAG culling on, off or both (default both)")
      ->check(CLI::IsMember({"on", "off", "both"}))
      ->needs(ooc);
  app.add_option("--save-rays", cfg.save_rays,
                 "--out-of-core: also write each kind's rays to PREFIX-KIND.rays (the ray-file format), to replay them "
                 "with rtpack-trace PKG --rays FILE --memory-budget B")
      ->needs(ooc);
  return ooc;
}

void parse_budgets(BudgetBenchConfig& cfg) {
  if (!cfg.budgets_text.empty()) {
    cfg.budgets.clear();
    for (const std::string& item : rtp::tools::split_list(cfg.budgets_text)) {
      char* end = nullptr;
      const double v = std::strtod(item.c_str(), &end);
      if (item.empty() || *end != '\0' || !(v > 0 && v <= 100))
        throw Error(ExitCode::kUsage, "--budgets: '" + item + "' is not a percentage in (0, 100]");
      cfg.budgets.push_back(v);
    }
    cfg.budgets_text.clear();
  }
}

int run_budget_bench(BudgetBenchConfig cfg) {
  parse_budgets(cfg);
  std::unique_ptr<tbb::global_control> limit;
  if (cfg.threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, cfg.threads);
  FILE* out = cfg.json ? stderr : stdout;
  // The scene for the rays (bounce rays need its normals), prepared as the converter did by default.
  ConvertSettings cs;
  cs.input = cfg.scene_path;
  cs.allow_paths = cfg.allow_paths;
  cs.dry_run = true;
  std::fprintf(stderr, "importing %s for the rays ...\n", cfg.scene_path.c_str());
  const Scene scene = convert_scene(cs).scene;
  const PackageReader reader(cfg.package, cfg.direct_io);
  if (reader.header().instanced_triangles != scene.instanced_triangles())
    throw Error(ExitCode::kUsage, "the package " + cfg.package + " was not converted from " + cfg.scene_path);
  auto t0 = Clock::now();
  const auto in_core = load_package_in_core(reader);
  const double in_core_load = since(t0);
  PackageTraceOptions opt;
  opt.isa = cfg.isa;
  // The reference is the in-core trace as rtpack-trace runs it: no DAG culling (in core the DAG test costs
  // more than it saves; it is the out-of-core tracer's, where a culled point is a chunk not read).
  opt.cull = false;
  const std::unique_ptr<Tracer> in_core_t = in_core_tracer(*in_core);
  auto trace_in_core = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { in_core_t->closest(r, h, n, opt); };
  const uint64_t on_demand = on_demand_bytes(reader), minimum = minimum_budget(reader);
  std::fprintf(out, "%s: %.1f MiB on demand (batching points and mesh segments), minimum budget %.1f MiB, %s, %d threads%s\n",
               cfg.package.c_str(), double(on_demand) / 1048576.0, double(minimum) / 1048576.0, isa_name(cfg.isa),
               cfg.threads > 0 ? cfg.threads : int(tbb::info::default_concurrency()), reader.direct_io() ? ", O_DIRECT" : "");
  std::fprintf(out, "%-8s %7s %6s %10s %8s %10s %9s %9s %8s %10s %10s\n", "kind", "budget", "cull", "budget MiB", "rounds",
               "chunks", "read MiB", "hit rate", "seconds", "x in-core", "peak MiB");
  nlohmann::json records = nlohmann::json::array();
  bool all_identical = true;
  for (RayKind kind : cfg.kinds) {
    RayGenOptions g;
    g.seed = cfg.seed;
    g.closest = trace_in_core;
    const std::vector<fmt::Ray> rays = generate_rays(scene, kind, cfg.rays, g);
    if (!cfg.save_rays.empty())
      write_output_file(cfg.save_rays + "-" + ray_kind_name(kind) + ".rays", rays.data(), rays.size() * sizeof(fmt::Ray));
    std::vector<fmt::Hit> want(rays.size()), got(rays.size());
    trace_in_core(rays.data(), want.data(), rays.size());  // warm
    double in_core_s = 1e300;
    for (int r = 0; r < cfg.reps; ++r) {
      t0 = Clock::now();
      trace_in_core(rays.data(), want.data(), rays.size());
      in_core_s = std::min(in_core_s, since(t0));
    }
    std::fprintf(out, "%-8s %7s %6s %10s %8s %10s %9s %9s %8.3f %10s %10.1f  (in core; load %.2f s not counted)\n",
                 ray_kind_name(kind), "-", "off", "-", "-", "-", "-", "-", in_core_s, "1.00",
                 double(in_core->load_stats().raw_bytes) / 1048576.0, in_core_load);
    records.push_back({{"kind", ray_kind_name(kind)},
                       {"mode", "in_core"},
                       {"rays", rays.size()},
                       {"seconds", in_core_s},
                       {"load_seconds", in_core_load},
                       {"resident_bytes", in_core->load_stats().raw_bytes}});
    // Every (budget, culling) run of this kind, best of --reps, the repetitions interleaved (run 1 of each,
    // then run 2 of each, ...) after one untimed run of the first: the first out-of-core run of a process
    // faults in the cache's memory, which later runs reuse, so without it whichever ran first (culling on)
    // paid that alone (unique-50m, 100 %, 131072 random rays: 3.5 s culling on against 1.6 s off, no visit culled).
    struct Config {
      double pct;
      uint64_t budget;
      bool cull;
      OutOfCoreStats best;
      bool timed = false, same = true;
    };
    std::vector<Config> configs;
    for (double pct : cfg.budgets) {
      const uint64_t budget = uint64_t(std::ceil(double(on_demand) * pct / 100.0));
      for (bool cull : {true, false}) {
        if (!cull && !in_core->has_dags()) continue;
        if (cfg.culling != "both" && cull != (cfg.culling == "on")) continue;
        if (budget < minimum) {
          std::fprintf(out, "%-8s %6.0f%% %6s below the minimum budget: skipped\n", ray_kind_name(kind), pct,
                       cull ? "on" : "off");
          continue;
        }
        configs.push_back({pct, budget, cull, {}});
      }
    }
    auto run_config = [&](Config& c) {
      PackageTraceOptions o = opt;
      o.cull = c.cull;
      TracerConfig tc;
      tc.memory_budget = c.budget;
      tc.prefetch = cfg.prefetch;
      const std::unique_ptr<Tracer> ooc = open_tracer(reader, tc);
      const TracerStats st = ooc->closest(rays.data(), got.data(), rays.size(), o);
      if (std::memcmp(want.data(), got.data(), want.size() * sizeof(fmt::Hit)) != 0) {
        all_identical = c.same = false;
        std::fprintf(out, "%-8s %6.0f%% %6s HITS DIFFER FROM IN CORE\n", ray_kind_name(kind), c.pct, c.cull ? "on" : "off");
      }
      return st;
    };
    if (!configs.empty()) (void)run_config(configs.front());  // warm-up, untimed (its hits are checked too)
    for (int r = 0; r < cfg.reps; ++r)
      for (Config& c : configs) {
        const OutOfCoreStats st = run_config(c);
        if (!c.timed || st.total_seconds < c.best.total_seconds) c.best = st, c.timed = true;
      }
    for (const Config& c : configs) {
      const OutOfCoreStats& st = c.best;
      std::fprintf(out, "%-8s %6.0f%% %6s %10.1f %8llu %10llu %9.1f %8.1f%% %8.3f %10.2f %10.1f%s\n", ray_kind_name(kind), c.pct,
                   c.cull ? "on" : "off", double(c.budget) / 1048576.0, (unsigned long long)st.rounds,
                   (unsigned long long)st.cache.loads, double(st.cache.bytes_read) / 1048576.0, 100 * st.cache.hit_rate(),
                   st.total_seconds, st.total_seconds / in_core_s, double(st.peak_resident_bytes) / 1048576.0,
                   c.same ? "" : "  HITS DIFFER FROM IN CORE");
      records.push_back({{"kind", ray_kind_name(kind)},
                         {"mode", "out_of_core"},
                         {"budget_percent", c.pct},
                         {"budget_bytes", c.budget},
                         {"cull", c.cull},
                         {"rays", rays.size()},
                         {"rounds", st.rounds},
                         {"passes", st.passes},
                         {"chunks_loaded", st.cache.loads},
                         {"bytes_read", st.cache.bytes_read},
                         {"raw_bytes_loaded", st.cache.raw_bytes_loaded},
                         {"chunks_prefetched", st.cache.prefetched},
                         {"cache_hit_rate", st.cache.hit_rate()},
                         {"seconds", st.total_seconds},
                         {"load_seconds", st.load_seconds},
                         {"walk_seconds", st.walk_seconds},
                         {"trace_seconds", st.trace_seconds},
                         {"vs_in_core", st.total_seconds / in_core_s},
                         {"peak_cache_bytes", st.cache.peak_resident_bytes},
                         {"peak_resident_bytes", st.peak_resident_bytes},
                         {"culled_visits", st.culled_visits},
                         {"point_visits", st.point_visits},
                         {"identical_to_in_core", c.same},
                         {"reps", cfg.reps}});
    }
  }
  if (cfg.json) {
    nlohmann::json j = rtp::tools::json_stamp("rtpack-bench");
    j["package"] = cfg.package;
    j["scene"] = cfg.scene_path;
    j["on_demand_bytes"] = on_demand;
    j["minimum_budget"] = minimum;
    j["threads"] = cfg.threads;
    j["cpu"] = cpu_model();
    j["direct_io"] = reader.direct_io();
    j["prefetch"] = cfg.prefetch;
    j["peak_rss_bytes"] = uint64_t(peak_rss_mib() * 1048576.0);
    j["records"] = records;
    std::cout << j.dump(2) << "\n";
  }
  if (!all_identical) {
    std::fprintf(stderr, "error: some out-of-core hits differ from the in-core hits\n");
    return int(ExitCode::kInternal);
  }
  return 0;
}

}  // namespace rtp::bench
