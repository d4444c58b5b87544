// rtpack-bench --packets: packets of P consecutive rays against single rays and Embree's packets.
#include "bench_packets.h"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>

#include "bench_agreement.h"
#include "cli_checks.h"
#include "bench_convert.h"
#include "bench_timing.h"
#include "bvh/bvh.h"
#include "core/error.h"
#include "oracle/compare.h"
#include "oracle/embree_oracle.h"
#include "scene/import.h"
#include "tool_version.h"

namespace rtp::bench {
namespace {

constexpr size_t kPacketGrain = 256;  // a multiple of 16: no packet straddles two tasks

std::vector<uint32_t> parse_packet_sizes(const std::string& text) {
  std::vector<uint32_t> out;
  for (const std::string& item : rtp::tools::split_list(text)) {
    char* end = nullptr;
    const long v = std::strtol(item.c_str(), &end, 10);
    if (item.empty() || *end != '\0' || v < 0 || !packet_size_ok(uint32_t(v)))
      throw Error(ExitCode::kUsage, "--packets: '" + item + "' is not a packet size (0 = single rays, 4, 8, 16)");
    out.push_back(uint32_t(v));
  }
  return out;
}

}  // namespace

CLI::Option* add_packet_options(CLI::App& app, PacketBenchConfig& cfg) {
  return app.add_option("--packets", cfg.sizes_text,
                        "instead: time packets of each size in this comma-separated list (0 = single rays, 4, 8, 16) "
                        "against Embree's 16-ray packets, with SIMD utilization (default kinds: primary; W=8)");
}

int run_packet_bench(PacketBenchConfig cfg) {
  cfg.sizes = parse_packet_sizes(cfg.sizes_text);
  std::unique_ptr<tbb::global_control> limit;
  if (cfg.threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, cfg.threads);
  FILE* out = cfg.json ? stderr : stdout;
  ImportOptions io;
  io.allowed_dirs = cfg.allow_paths;
  std::fprintf(stderr, "importing %s ...\n", cfg.scene_path.c_str());
  const Scene scene = import_gltf(cfg.scene_path, io);
  if (scene.instanced_triangles() == 0) throw Error(ExitCode::kInputInvalid, "the scene has no triangles");
  std::fprintf(stderr, "building rtpack W=8 and Embree (ROBUST, HIGH) ...\n");
  const InCoreScene<8, 8> bvh = InCoreScene<8, 8>::build(scene);
  const EmbreeOracle embree(scene, OracleQuality::kHigh);
  std::fprintf(out, "scene %s: %llu instanced triangles; isa %s, W=8, %zu rays per kind, best of %d interleaved runs\n",
               cfg.scene_path.c_str(), (unsigned long long)scene.instanced_triangles(), isa_name(cfg.isa), cfg.rays, cfg.reps);
  std::fprintf(out, "%-7s %-7s %6s %10s %10s %7s %11s %10s %10s  %s\n", "kind", "query", "packet", "rtpack", "Embree", "ratio",
               "SIMD util.", "in packets", "tests/ray", "agree / edge ties / precision ties / FAILURES");
  nlohmann::json records = nlohmann::json::array();
  bool bad = false;
  for (RayKind kind : cfg.kinds) {
    KindData k;
    k.kind = kind;
    k.any = kind == RayKind::kShadow;
    k.coherence = kind == RayKind::kPrimary || kind == RayKind::kShadow ? RayCoherence::kCoherent : RayCoherence::kIncoherent;
    RayGenOptions g;
    g.seed = cfg.seed;
    g.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { embree.closest(r, h, n); };
    k.rays = generate_rays(scene, kind, cfg.rays, g);
    const size_t n = k.rays.size();
    k.ref_hits.resize(n);
    embree.closest(k.rays.data(), k.ref_hits.data(), n);
    k.skip = unsupported_mask(k.rays.data(), n);
    std::vector<fmt::Hit> single_hits(n), hits(n), embree_hits(n);
    std::vector<uint8_t> single_occ(n), occ(n), embree_occ(n);
    auto trace = [&](uint32_t p, std::vector<fmt::Hit>& h, std::vector<uint8_t>& o) {
      const TraceOptions topt{cfg.isa, TraversalOrder::kOctantStack, p};
      tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kPacketGrain), [&](const tbb::blocked_range<size_t>& r) {
        if (k.any)
          trace_any<8, 8>(bvh.view(), k.rays.data() + r.begin(), o.data() + r.begin(), r.size(), topt);
        else
          trace_closest<8, 8>(bvh.view(), k.rays.data() + r.begin(), h.data() + r.begin(), r.size(), topt);
      });
    };
    trace(0, single_hits, single_occ);
    {  // rtpack's own closest hits for classifying any-hit ties (untimed)
      const TraceOptions topt{cfg.isa, TraversalOrder::kOctantStack, 0};
      if (k.any) trace_closest<8, 8>(bvh.view(), k.rays.data(), single_hits.data(), n, topt);
    }
    const Agreement agree = k.any ? agreement_any(scene, k, single_occ, single_hits) : agreement_closest(scene, k, single_hits);
    bad = bad || agree.failures;
    for (uint32_t p : cfg.sizes) {
      double secs = std::numeric_limits<double>::infinity(), embree_secs = secs;
      auto embree_run = [&] {
        if (k.any)
          embree.occluded(k.rays.data(), embree_occ.data(), n, k.coherence);
        else
          embree.closest(k.rays.data(), embree_hits.data(), n, k.coherence);
      };
      trace(p, hits, occ);
      embree_run();
      for (int r = 0; r < cfg.reps; ++r) {  // interleaved, best of each: load changes hit both alike
        auto t0 = Clock::now();
        trace(p, hits, occ);
        secs = std::min(secs, seconds_since(t0));
        t0 = Clock::now();
        embree_run();
        embree_secs = std::min(embree_secs, seconds_since(t0));
      }
      const bool same = k.any ? occ == single_occ : std::memcmp(hits.data(), single_hits.data(), n * sizeof(fmt::Hit)) == 0;
      bad = bad || !same;
      // Counters from one untimed pass in one call (they do not depend on threads).
      const TraceOptions topt{cfg.isa, TraversalOrder::kOctantStack, p};
      const TraceStats st = k.any ? trace_any<8, 8>(bvh.view(), k.rays.data(), occ.data(), n, topt)
                                  : trace_closest<8, 8>(bvh.view(), k.rays.data(), hits.data(), n, topt);
      const double util = st.packet_node_tests && p ? double(st.packet_active_lanes) / (double(st.packet_node_tests) * p) : 0.0;
      const double share = double(st.packet_rays) / double(n);
      const double mr = double(n) * 1e-6;
      std::fprintf(out, "%-7s %-7s %6u %10.2f %10.2f %7.2f %10.1f%% %9.1f%% %10.2f  %llu / %llu / %llu / %llu%s\n",
                   ray_kind_name(kind), k.any ? "any" : "closest", p, mr / secs, mr / embree_secs, embree_secs / secs, 100 * util,
                   100 * share, double(st.packet_node_tests) / double(n), (unsigned long long)agree.agree,
                   (unsigned long long)agree.edge_ties, (unsigned long long)agree.precision_ties,
                   (unsigned long long)agree.failures, same ? "" : "  PACKETS DIFFER FROM SINGLE RAYS");
      std::fflush(out);
      records.push_back({{"kind", ray_kind_name(kind)},
                         {"query", k.any ? "any" : "closest"},
                         {"packet", p},
                         {"rays", n},
                         {"rtpack_mrays", mr / secs},
                         {"embree_mrays", mr / embree_secs},
                         {"ratio", embree_secs / secs},
                         {"simd_utilization", util},
                         {"packet_ray_share", share},
                         {"packets", st.packets},
                         {"packet_node_tests", st.packet_node_tests},
                         {"packet_single_walks", st.packet_single_walks},
                         {"packet_triangle_tests", st.packet_triangle_tests},
                         {"same_as_single_rays", same},
                         {"failures", agree.failures}});
    }
  }
  if (cfg.json) std::cout << mode_run_json(cfg.scene_path, isa_name(cfg.isa), cfg.threads, cfg.reps, records).dump(2) << "\n";
  return bad ? int(ExitCode::kInternal) : 0;
}

}  // namespace rtp::bench
