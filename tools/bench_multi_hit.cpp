// rtpack-bench --multi-hit: node-culling multi-hit against collect-all and Embree's gathering filter.
#include "bench_multi_hit.h"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>

#include "bench_convert.h"
#include "cli_checks.h"
#include "bench_timing.h"
#include "bvh/bvh.h"
#include "core/error.h"
#include "oracle/embree_oracle.h"
#include "package/convert.h"
#include "tool_version.h"

namespace rtp::bench {
namespace {

constexpr size_t kGrain = 256;

struct Lists {
  std::vector<fmt::Hit> hits;
  std::vector<uint32_t> counts;
};

// Per ray: the same number of hits at the same t within TESTING.md's tolerance (ids may differ at ties).
size_t agreeing_rays(const Lists& a, const Lists& b, uint32_t k) {
  size_t same = 0;
  for (size_t i = 0; i < a.counts.size(); ++i) {
    bool ok = a.counts[i] == b.counts[i];
    for (uint32_t j = 0; ok && j < a.counts[i]; ++j) {
      const double ta = a.hits[i * k + j].t, tb = b.hits[i * k + j].t;
      ok = std::abs(ta - tb) <= 1e-4 * std::max(1.0, std::abs(tb));
    }
    same += ok;
  }
  return same;
}

}  // namespace

CLI::Option* add_multi_hit_options(CLI::App& app, MultiHitBenchConfig& cfg) {
  return app.add_option("--multi-hit", cfg.ks_text,
                        "instead: time the N closest hits per ray for each N of this comma-separated list (1..64): "
                        "rtpack's node culling, its collect-all baseline and Embree's gathering filter (default kinds: "
                        "random,bounce)");
}

int run_multi_hit_bench(MultiHitBenchConfig cfg) {
  for (const std::string& item : rtp::tools::split_list(cfg.ks_text)) {
    char* end = nullptr;
    const long v = std::strtol(item.c_str(), &end, 10);
    if (item.empty() || *end != '\0' || v < 1 || v > long(kMaxMultiHit))
      throw Error(ExitCode::kUsage, "--multi-hit: '" + item + "' is not a hit count in 1.." + std::to_string(kMaxMultiHit));
    cfg.ks.push_back(uint32_t(v));
  }
  std::unique_ptr<tbb::global_control> limit;
  if (cfg.threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, cfg.threads);
  FILE* out = cfg.json ? stderr : stdout;
  ConvertSettings cs;  // prepared as rtpack-convert does by default
  cs.input = cfg.scene_path;
  cs.allow_paths = cfg.allow_paths;
  cs.dry_run = true;
  std::fprintf(stderr, "importing %s ...\n", cfg.scene_path.c_str());
  const Scene scene = convert_scene(cs).scene;
  std::fprintf(stderr, "building rtpack W=8 and Embree (ROBUST, HIGH, context filter) ...\n");
  const InCoreScene<8, 8> bvh = InCoreScene<8, 8>::build(scene);
  const EmbreeOracle embree(scene, OracleQuality::kHigh, true);
  const TraceOptions topt{cfg.isa, TraversalOrder::kOctantStack};
  std::fprintf(out, "scene %s: %llu instanced triangles; isa %s, W=8, %zu rays per kind, best of %d after a warm-up\n",
               cfg.scene_path.c_str(), (unsigned long long)scene.instanced_triangles(), isa_name(cfg.isa), cfg.rays, cfg.reps);
  std::fprintf(out, "%-7s %3s %10s %10s %10s %8s %8s %9s %s\n", "kind", "N", "cull Mr/s", "all Mr/s", "Embree", "vs all",
               "vs Embr", "hits/ray", "rays agreeing with Embree (t within 1e-4)");
  nlohmann::json records = nlohmann::json::array();
  bool differ = false;
  for (RayKind kind : cfg.kinds) {
    RayGenOptions g;
    g.seed = cfg.seed;
    g.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { embree.closest(r, h, n); };
    const std::vector<fmt::Ray> rays = generate_rays(scene, kind, cfg.rays, g);
    const size_t n = rays.size();
    for (uint32_t k : cfg.ks) {
      Lists cull{std::vector<fmt::Hit>(n * k), std::vector<uint32_t>(n)}, all = cull, emb = cull;
      auto rtpack = [&](Lists& l, MultiHitMethod m) {
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kGrain), [&](const tbb::blocked_range<size_t>& r) {
          trace_multi<8, 8>(bvh.view(), rays.data() + r.begin(), r.size(), k, l.hits.data() + r.begin() * k,
                            l.counts.data() + r.begin(), topt, m);
        });
      };
      const double t_cull = best_of(cfg.reps, [&] { rtpack(cull, MultiHitMethod::kNodeCulling); });
      const double t_all = best_of(cfg.reps, [&] { rtpack(all, MultiHitMethod::kCollectAll); });
      const double t_emb = best_of(cfg.reps, [&] { embree.multi_hit(rays.data(), n, k, emb.hits.data(), emb.counts.data()); });
      const bool same =
          cull.counts == all.counts && std::memcmp(cull.hits.data(), all.hits.data(), n * k * sizeof(fmt::Hit)) == 0;
      differ = differ || !same;
      uint64_t total = 0;
      for (uint32_t c : cull.counts) total += c;
      const size_t agree = agreeing_rays(cull, emb, k);
      const double mr = double(n) / 1e6;
      std::fprintf(out, "%-7s %3u %10.2f %10.2f %10.2f %7.2fx %7.2fx %9.2f %zu / %zu%s\n", ray_kind_name(kind), k, mr / t_cull,
                   mr / t_all, mr / t_emb, t_all / t_cull, t_emb / t_cull, double(total) / double(n), agree, n,
                   same ? "" : "  NODE CULLING DIFFERS FROM COLLECT-ALL");
      std::fflush(out);
      records.push_back({{"kind", ray_kind_name(kind)},
                         {"n", k},
                         {"rays", n},
                         {"node_culling_seconds", t_cull},
                         {"collect_all_seconds", t_all},
                         {"embree_gather_seconds", t_emb},
                         {"speedup_vs_collect_all", t_all / t_cull},
                         {"speedup_vs_embree", t_emb / t_cull},
                         {"hits_per_ray", double(total) / double(n)},
                         {"rays_agreeing_with_embree", agree},
                         {"same_as_collect_all", same}});
    }
  }
  if (cfg.json) std::cout << mode_run_json(cfg.scene_path, isa_name(cfg.isa), cfg.threads, cfg.reps, records).dump(2) << "\n";
  return differ ? int(ExitCode::kInternal) : 0;
}

}  // namespace rtp::bench
