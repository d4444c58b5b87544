// rtpack-bench --out-of-core --kinds path (bench_paths.h).
#include "bench_paths.h"

#include <cstring>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "bench_convert.h"
#include "cli_checks.h"
#include "stream_stats_json.h"
#include "core/error.h"
#include "core/progress.h"
#include "oracle/embree_oracle.h"
#include "package/convert.h"
#include "path_trace.h"
#include "rtpack/rtpack.h"
#include "tool_version.h"

namespace rtp::bench {
namespace {

using Clock = std::chrono::steady_clock;

// The path tracer's rays through Embree in core: each flush traces what is pending (closest hits and
// occlusion, `coherence` as EmbreeOracle takes it), the normals from the scene's world triangles as the
// stream computes them, and hands the answers back; rays submitted from the callback are the next pass.
class EmbreePaths final : public pathtracer::RayTracer {
 public:
  EmbreePaths(const EmbreeOracle& embree, const Scene& scene, RayCoherence coherence)
      : embree_(embree), scene_(scene), coherence_(coherence) {}
  void submit(const rtpack::StreamRay* rays, size_t count) override { pending_.insert(pending_.end(), rays, rays + count); }
  rtpack::StreamStats flush(const std::function<void(const rtpack::StreamHit*, size_t)>& on_hits) override {
    const auto t0 = Clock::now();
    rtpack::StreamStats st;
    while (!pending_.empty()) {
      current_.swap(pending_);
      pending_.clear();
      const size_t n = current_.size();
      rays_.resize(n), hits_.resize(n), occluded_.resize(n), out_.resize(n);
      static_assert(sizeof(fmt::Ray) == sizeof(rtpack::Ray), "the public ray is the package's ray");
      for (size_t i = 0; i < n; ++i) std::memcpy(&rays_[i], &current_[i].ray, sizeof(fmt::Ray));  // no type punning
      // Closest and any-hit rays apart, each kind in one call (their order kept).
      closest_.clear(), any_.clear();
      for (size_t i = 0; i < n; ++i) (current_[i].any ? any_ : closest_).push_back(i);
      gather(closest_), embree_.closest(buf_.data(), hit_buf_.data(), closest_.size(), coherence_);
      for (size_t k = 0; k < closest_.size(); ++k) hits_[closest_[k]] = hit_buf_[k];
      gather(any_), embree_.occluded(buf_.data(), occ_buf_.data(), any_.size(), coherence_);
      for (size_t k = 0; k < any_.size(); ++k) occluded_[any_[k]] = occ_buf_[k];
      tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i) answer(i);
      });
      st.rays += n, ++st.passes;
      on_hits(out_.data(), n);
    }
    st.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    return st;
  }

 private:
  void gather(const std::vector<size_t>& idx) {
    buf_.resize(idx.size()), hit_buf_.resize(idx.size()), occ_buf_.resize(idx.size());
    for (size_t k = 0; k < idx.size(); ++k) buf_[k] = rays_[idx[k]];
  }
  void answer(size_t i) {
    rtpack::StreamHit& o = out_[i];
    o = {};
    o.payload = current_[i].payload;
    if (current_[i].any) {
      o.hit.t = INFINITY, o.hit.instance = o.hit.prim = kNoIndex;
      o.occluded = occluded_[i];
      return;
    }
    const fmt::Hit& h = hits_[i];
    o.hit = reinterpret_cast<const rtpack::Hit&>(h);
    if (!(h.t < INFINITY)) return;
    o.occluded = 1;
    const Instance& inst = scene_.instances[h.instance];
    const Mesh& m = scene_.meshes[inst.mesh];
    const Vec3d v0 = inst.transform.apply(to_d(m.positions[m.indices[3 * size_t(h.prim)]]));
    const Vec3d v1 = inst.transform.apply(to_d(m.positions[m.indices[3 * size_t(h.prim) + 1]]));
    const Vec3d v2 = inst.transform.apply(to_d(m.positions[m.indices[3 * size_t(h.prim) + 2]]));
    const Vec3d c = cross(v1 - v0, v2 - v0);
    const double len = length(c);
    if (!(len > 0)) return;
    o.normal[0] = float(c.x / len), o.normal[1] = float(c.y / len), o.normal[2] = float(c.z / len);
  }

  const EmbreeOracle& embree_;
  const Scene& scene_;
  RayCoherence coherence_;
  std::vector<rtpack::StreamRay> pending_, current_;
  std::vector<fmt::Ray> rays_, buf_;
  std::vector<fmt::Hit> hits_, hit_buf_;
  std::vector<uint8_t> occluded_, occ_buf_;
  std::vector<size_t> closest_, any_;
  std::vector<rtpack::StreamHit> out_;
};

std::vector<uint32_t> parse_counts(const std::string& text) {
  std::vector<uint32_t> out;
  for (const std::string& item : rtp::tools::split_list(text)) {
    char* end = nullptr;
    const unsigned long v = std::strtoul(item.c_str(), &end, 10);
    if (item.empty() || *end != '\0' || v < 1 || v > (1u << 24))
      throw Error(ExitCode::kUsage, "--paths-in-flight: '" + item + "' is not a count from 1 to 16777216");
    out.push_back(uint32_t(v));
  }
  return out;
}

}  // namespace

void add_path_options(CLI::App& app, PathBenchConfig& cfg, CLI::Option* ooc) {
  app.add_option("--paths-in-flight", cfg.paths_text,
                 "--out-of-core --kinds path: comma-separated paths traced at once (default 4096,16384)")
      ->needs(ooc);
  app.add_option("--path-size", cfg.size, "--out-of-core --kinds path: image size WxH (default 512x512)")->needs(ooc);
  app.add_option("--path-camera", cfg.camera, "--out-of-core --kinds path: the package's camera (default: the first)")
      ->check(CLI::Range(0, 1 << 20))
      ->needs(ooc);
  app.add_option("--spp", cfg.spp, "--out-of-core --kinds path: samples per pixel (default 1)")
      ->check(CLI::Range(1u, 4096u))
      ->needs(ooc);
  app.add_option("--bounces", cfg.bounces, "--out-of-core --kinds path: bounces after the primary hit (default 2)")
      ->check(CLI::Range(0u, 16u))
      ->needs(ooc);
  app.add_flag("--refill", cfg.refill, "--out-of-core --kinds path: a new path whenever one ends, not waves")->needs(ooc);
}

int run_path_bench(BudgetBenchConfig b, PathBenchConfig cfg) {
  parse_budgets(b);
  if (!cfg.paths_text.empty()) cfg.paths_in_flight = parse_counts(cfg.paths_text);
  pathtracer::PathTraceOptions po;
  if (std::sscanf(cfg.size.c_str(), "%dx%d", &po.width, &po.height) != 2 || po.width < 1 || po.height < 1 || po.width > 16384 ||
      po.height > 16384)
    throw Error(ExitCode::kUsage, "--path-size " + cfg.size + ": expected WxH, e.g. 512x512");
  po.spp = cfg.spp, po.bounces = cfg.bounces, po.seed = b.seed, po.refill = cfg.refill;
  po.camera = cfg.camera;
  po.stream.threads = b.threads;
  po.stream.isa = b.isa == Isa::kAvx512 ? rtpack::Isa::kAvx512 : b.isa == Isa::kAvx2 ? rtpack::Isa::kAvx2 : rtpack::Isa::kScalar;
  std::unique_ptr<tbb::global_control> limit;
  if (b.threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, b.threads);
  FILE* out = b.json ? stderr : stdout;
  ConvertSettings cs;
  cs.input = b.scene_path;
  cs.allow_paths = b.allow_paths;
  cs.dry_run = true;
  std::fprintf(stderr, "importing %s for Embree ...\n", b.scene_path.c_str());
  const Scene scene = convert_scene(cs).scene;
  // In core: the package resident (one render to load it, untimed), then the best of --reps.
  const rtpack::Package in_core = rtpack::Package::open(b.package);
  if (in_core.info().instanced_triangles != scene.instanced_triangles())
    throw Error(ExitCode::kUsage, "the package " + b.package + " was not converted from " + b.scene_path);
  const uint64_t geometry = in_core.geometry_bytes(), minimum = in_core.minimum_budget();
  po.paths_in_flight = cfg.paths_in_flight.front();
  const pathtracer::PathTraceResult ref = pathtracer::path_trace(in_core, po);
  double in_core_s = 1e300;
  for (int r = 0; r < b.reps; ++r) in_core_s = std::min(in_core_s, pathtracer::path_trace(in_core, po).seconds);
  // Embree in core on the same paths: both of its paths, the faster one the peer.
  const EmbreeOracle embree(scene, OracleQuality::kHigh);
  const std::vector<rtpack::Ray> camera = in_core.camera_rays(po.width, po.height, po.camera);
  double embree_s = 1e300;
  const char* embree_path = "";
  size_t embree_pixels_differ = 0;
  for (const auto& [coherence, name] : {std::pair{RayCoherence::kSingle, "one rtcIntersect1/rtcOccluded1 call per ray"},
                                        std::pair{RayCoherence::kIncoherent, "rtcIntersect1M/rtcOccluded1M streams"}}) {
    EmbreePaths e(embree, scene, coherence);
    const pathtracer::PathTraceResult warm = pathtracer::path_trace(e, camera, in_core.info().bounds, po);
    embree_pixels_differ = 0;
    for (size_t i = 0; i < warm.rgb.size(); i += 3)
      embree_pixels_differ += warm.rgb[i] != ref.rgb[i] || warm.rgb[i + 1] != ref.rgb[i + 1] || warm.rgb[i + 2] != ref.rgb[i + 2];
    for (int r = 0; r < b.reps; ++r) {
      const double s = pathtracer::path_trace(e, camera, in_core.info().bounds, po).seconds;
      if (s < embree_s) embree_s = s, embree_path = name;
    }
  }
  std::fprintf(out,
               "%s: %.1f MiB of geometry, minimum budget %.1f MiB; %dx%d, %u spp, %u bounces, %llu rays%s; %d threads%s\n"
               "in core %.3f s (the package resident); Embree in core %.3f s (%s; %zu of %zu pixels differ from rtpack's)\n",
               b.package.c_str(), double(geometry) / 1048576.0, double(minimum) / 1048576.0, po.width, po.height, po.spp,
               po.bounces, (unsigned long long)ref.total.rays, cfg.refill ? ", refilled" : ", in waves",
               b.threads > 0 ? b.threads : int(tbb::info::default_concurrency()), b.direct_io ? ", O_DIRECT" : "", in_core_s,
               embree_s, embree_path, embree_pixels_differ, ref.rgb.size() / 3);
  std::fprintf(out, "%9s %7s %5s %9s %9s %8s %9s %8s %8s %8s %9s %9s\n", "in flight", "budget", "cull", "visits", "culled",
               "chunks", "read MiB", "MB/s", "seconds", "x in-core", "x Embree", "peak MiB");
  struct Config {
    uint32_t in_flight;
    double pct;
    bool cull;
    pathtracer::PathTraceResult best;
    bool timed = false, same = true;
  };
  std::vector<Config> configs;
  for (uint32_t f : cfg.paths_in_flight)
    for (double pct : b.budgets)
      for (bool cull : {true, false}) {
        if (b.culling != "both" && cull != (b.culling == "on")) continue;
        if (double(geometry) * pct / 100.0 < double(minimum)) {
          std::fprintf(out, "%9u %6.0f%% %5s below the minimum budget: skipped\n", f, pct, cull ? "on" : "off");
          continue;
        }
        configs.push_back({f, pct, cull, {}});
      }
  bool all_same = true;
  auto run_config = [&](Config& c) {
    rtpack::OpenOptions oo;
    oo.memory_budget = uint64_t(std::ceil(double(geometry) * c.pct / 100.0));
    oo.direct_io = b.direct_io;
    const rtpack::Package pkg = rtpack::Package::open(b.package, oo);  // a cold cache for every run
    pathtracer::PathTraceOptions o = po;
    o.paths_in_flight = c.in_flight, o.stream.cull = c.cull;
    pathtracer::PathTraceResult r = pathtracer::path_trace(pkg, o);
    if (r.rgb != ref.rgb) all_same = c.same = false;
    return r;
  };
  if (!configs.empty()) (void)run_config(configs.front());  // the first run of the process, untimed (its image checked)
  for (int r = 0; r < b.reps; ++r)
    for (Config& c : configs) {
      pathtracer::PathTraceResult res = run_config(c);
      if (!c.timed || res.seconds < c.best.seconds) c.best = std::move(res), c.timed = true;
    }
  nlohmann::json records = nlohmann::json::array();
  for (const Config& c : configs) {
    const rtpack::StreamStats& t = c.best.total;
    const double mbps = t.load_seconds > 0 ? double(t.bytes_read) / t.load_seconds / 1e6 : 0;
    std::fprintf(out, "%9u %6.0f%% %5s %9llu %9llu %8llu %9.1f %8.0f %8.3f %8.2f %9.2f %9.1f%s\n", c.in_flight, c.pct,
                 c.cull ? "on" : "off", (unsigned long long)t.batching_point_visits, (unsigned long long)t.culled_visits,
                 (unsigned long long)t.chunks_loaded, double(t.bytes_read) / 1048576.0, mbps, c.best.seconds,
                 c.best.seconds / in_core_s, c.best.seconds / embree_s, double(t.peak_resident_bytes) / 1048576.0,
                 c.same ? "" : "  IMAGE DIFFERS FROM IN CORE");
    nlohmann::json rec = rtp::tools::stream_stats_json(t);
    rec["paths_in_flight"] = c.in_flight, rec["budget_percent"] = c.pct, rec["cull"] = c.cull;
    rec["budget_bytes"] = uint64_t(std::ceil(double(geometry) * c.pct / 100.0));
    rec["seconds"] = c.best.seconds, rec["vs_in_core"] = c.best.seconds / in_core_s, rec["vs_embree"] = c.best.seconds / embree_s;
    rec["read_mb_per_s"] = mbps, rec["identical_to_in_core"] = c.same, rec["waves"] = c.best.waves.size();
    records.push_back(rec);
  }
  if (b.json) {
    nlohmann::json j = rtp::tools::json_stamp("rtpack-bench");
    j["mode"] = "path";
    j["package"] = b.package, j["scene"] = b.scene_path;
    j["geometry_bytes"] = geometry, j["minimum_budget"] = minimum;
    j["width"] = po.width, j["height"] = po.height, j["spp"] = po.spp, j["bounces"] = po.bounces, j["refill"] = cfg.refill;
    j["threads"] = b.threads, j["direct_io"] = b.direct_io, j["reps"] = b.reps, j["cpu"] = cpu_model();
    j["in_core"] = {{"seconds", in_core_s}, {"rays", ref.total.rays}};
    j["embree"] = {{"seconds", embree_s}, {"path", embree_path}, {"pixels_differ", embree_pixels_differ}};
    j["records"] = records;
    std::cout << j.dump(2) << "\n";
  }
  if (!all_same) {
    std::fprintf(stderr, "error: some out-of-core images differ from the in-core image\n");
    return int(ExitCode::kInternal);
  }
  return 0;
}

}  // namespace rtp::bench
