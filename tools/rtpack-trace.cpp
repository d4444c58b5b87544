// rtpack-trace: traces a ray file through a package (in core) and writes a hit file — the way
// outside tools check rtpack (formats/SPEC.md §5).
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include "core/error.h"
#include "core/json_checked.h"
#include "core/input_file.h"
#include "core/output_file.h"
#include "core/progress.h"
#include "core/utf8.h"
#include "package/writer.h"
#include "reader/reader.h"
#include "layout/chunk_io.h"
#include "reader/attribute_lookup.h"
#include "reader/camera.h"
#include "image/image.h"
#include "trace/out_of_core.h"
#include "trace/tracer.h"
#include "reader/ray_file.h"
#include "reader/tile_order.h"
#include "cli_checks.h"
#include "tool_version.h"

namespace {

// "WxH" with both positive and at most 2^28 pixels.
bool parse_size(const std::string& text, int* w, int* h) {
  const size_t x = text.find('x');
  if (x == std::string::npos) return false;
  // Digits only (no sign, no spaces), each side at most 2^28: strtoll on a checked digit string cannot overflow.
  auto side = [](const std::string& s, int* out) {
    if (s.empty() || s.size() > 9 || s.find_first_not_of("0123456789") != std::string::npos) return false;
    const long long v = std::strtoll(s.c_str(), nullptr, 10);
    if (v <= 0 || v > (1LL << 28)) return false;
    *out = int(v);
    return true;
  };
  return side(text.substr(0, x), w) && side(text.substr(x + 1), h) && int64_t(*w) * *h <= (int64_t(1) << 28);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rtpack-trace: trace a ray file through a package"};
  rtp::tools::add_version_flag(app, "rtpack-trace");
  std::string package, rays_path, hits_path, isa = "best", order = "octant";
  int threads = 0;
  bool any = false, json = false, direct = false, no_cull = false, force_cull = false;
  app.add_option("package", package, "the .rtp package")->required();
  std::string make_rays;
  app.add_option("--rays", rays_path, "ray file: N x {ox oy oz tnear dx dy dz tfar} float32 (not with --image)");
  app.add_option("--make-camera-rays", make_rays,
                 "WxH: first write primary rays from the package's camera (--camera; or an automatic one) to --rays");
  app.add_option("--hits", hits_path,
                 "hit file to write: N x {t, instance, primitive, u, v} (or N bytes with --any); with --image, the "
                 "image's rays in pixel order");
  std::string image_path, size = "1280x720", shade_name = "normal";
  int camera = -1;
  app.add_option("--image", image_path, "render the camera's primary rays to this PNG (no --rays needed)");
  app.add_option("--size", size, "image size WxH for --image (default 1280x720)");
  app.add_option("--camera", camera,
                 "glTF camera index for --image and --make-camera-rays (default: the first, or an "
                 "automatic camera framing the bounds when the package has none)")
      ->check(rtp::tools::non_negative());
  app.add_option("--shade", shade_name, "--image colours: normal (default), depth or instance")
      ->check(CLI::IsMember({"normal", "depth", "instance"}));
  std::string shading_path;
  app.add_option("--shading", shading_path,
                 "also write N x {normal xyz, u, v} float32: interpolated world normal and TEXCOORD_0 per hit "
                 "(packages converted with --attributes)");
  app.add_flag("--any", any, "any-hit (occlusion): write one byte per ray, 1 = occluded");
  uint32_t multi = 0;
  app.add_option("--multi-hit", multi,
                 "K: write the K closest hits of each ray (K hit records per ray, nearest first, then misses; SPEC §5), "
                 "K in 1..64")
      ->check(CLI::Range(1u, rtp::kMaxMultiHit));
  app.add_option("--threads", threads, "worker threads (default: all cores)")->check(rtp::tools::positive());
  app.add_option("--isa", isa, "best, scalar, avx2 or avx512")->check(CLI::IsMember({"best", "scalar", "avx2", "avx512"}));
  app.add_option("--order", order, "traversal order: octant (stack) or active (Benthin's active list)")
      ->check(CLI::IsMember({"octant", "active"}));
  std::string budget_text;
  app.add_option("--memory-budget", budget_text,
                 "trace out of core: batching points and mesh segments held in a cache of this many bytes "
                 "(e.g. 256MiB, 2GB, or 10% of the package's on-demand bytes); in core without it");
  bool prefetch = false;
  app.add_flag("--prefetch", prefetch,
               "with --memory-budget: read the next round's likely chunks on an I/O thread while a "
               "round traces (same hits; off by default, see docs/trace/budget.md)");
  uint32_t speculation = rtp::kDefaultSpeculation;
  app.add_option("--speculation", speculation,
                 "with --memory-budget: queue a ray at its next N batching points at once, 1..64 (same hits; default " +
                     std::to_string(rtp::kDefaultSpeculation) + "; 1 walks one point at a time, docs/trace/budget.md)")
      ->check(CLI::Range(1, 64));
  app.add_flag("--direct-io", direct, "read chunks with O_DIRECT (falls back when unsupported)");
  // Molenaar 2019 §3.2's DAG test spares the out-of-core tracer chunk loads; in core every chunk is loaded and
  // the test costs more than the BVH walks it saves (1.3-2.4x slower on the samples), so it is off there.
  CLI::Option* no_cull_opt = app.add_flag(
      "--no-cull", no_cull,
      "with --memory-budget: do not test rays against the batching points' culling DAGs (same hits; in core they are not "
      "tested unless --cull)");
  app.add_flag("--cull", force_cull,
               "in core too: test rays against the batching points' culling DAGs first (same hits, slower in core; on "
               "by default with --memory-budget, where a culled point is a chunk not read)")
      ->excludes(no_cull_opt);
  app.add_flag("--json", json, "print the counts as JSON on stdout");
  uint32_t packet = 0;
  app.add_option("--packet", packet,
                 "closest hits in core: trace each run of N consecutive rays as a packet, N = 4, 8 or 16, or 0 for single "
                 "rays (same hits either way; default 16 with --image, whose rays go in Hilbert-ordered 4x4 tiles, else 0)")
      ->check(CLI::IsMember({0u, 4u, 8u, 16u}));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return rtp::tools::parse_error_exit(app, e, "rtpack-trace", argc, argv);
  }
  std::unique_ptr<tbb::global_control> limit;
  if (threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
  const bool render = !image_path.empty();
  auto usage = [&](const std::string& msg) {
    if (json) return rtp::tools::report_error("rtpack-trace", true, package, rtp::ExitCode::kUsage, msg);
    std::cerr << "rtpack-trace: " << msg << "\nRun with --help for more information.\n";
    return int(rtp::ExitCode::kUsage);
  };
  if (render && (!rays_path.empty() || !make_rays.empty()))
    return usage("--image traces the camera's own rays: leave out --rays and --make-camera-rays");
  if (render && any) return usage("--image shows closest hits: it cannot be used with --any");
  if (multi && (any || render || app.count("--shading")))
    return usage("--multi-hit writes the K closest hits of a ray file: leave out --any, --image and --shading");
  if (!render && (rays_path.empty() || hits_path.empty()))
    return usage("--rays and --hits are required (or --image PNG to render the camera's rays)");
  int img_w = 0, img_h = 0;
  if (render && !parse_size(size, &img_w, &img_h)) return usage("--size " + size + ": expected WxH, e.g. 1280x720");
  if (!render && (app.count("--size") > 0 || app.count("--shade") > 0)) return usage("--size and --shade belong to --image");
  if (!render && camera >= 0 && make_rays.empty()) return usage("--camera belongs to --image and --make-camera-rays");
  const bool packet_given = app.count("--packet") > 0;
  if (packet_given && packet && (any || multi))
    return usage("--packet traces closest hits: it cannot be used with --any or --multi-hit");
  if (packet_given && packet && !budget_text.empty())
    return usage("--packet: the out-of-core tracer (--memory-budget) traces single rays; leave out one of them");
  if (!packet_given && render && budget_text.empty()) packet = 16;
  return rtp::tools::run_reporting_errors("rtpack-trace", json, package, [&]() -> int {
    // No output may be an input (or another output): compared by device and inode.
    for (const std::string* out : {&hits_path, &shading_path, &image_path}) {
      rtp::check_not_same_file(package, *out);
      rtp::check_not_same_file(rays_path, *out);
    }
    if (!make_rays.empty()) rtp::check_not_same_file(package, rays_path);  // the ray file is written then
    rtp::check_not_same_file(hits_path, shading_path);
    rtp::check_not_same_file(hits_path, image_path);
    rtp::check_not_same_file(shading_path, image_path);
    if ((!hits_path.empty() && (hits_path == shading_path || hits_path == image_path)) ||
        (!shading_path.empty() && shading_path == image_path) ||
        (!make_rays.empty() && (rays_path == hits_path || rays_path == shading_path)))
      throw rtp::Error(rtp::ExitCode::kUsage, "two outputs name the same file");
    if (!hits_path.empty()) rtp::check_output_path(hits_path);
    if (render) rtp::check_output_path(image_path);
    if (!shading_path.empty()) {
      if (any) throw rtp::Error(rtp::ExitCode::kUsage, "--shading needs closest hits: it cannot be used with --any");
      rtp::check_output_path(shading_path);
    }
    const rtp::PackageReader reader(package, direct);
    // In core (every chunk loaded first) or, with --memory-budget, the batched out-of-core tracer.
    rtp::TracerConfig tc;
    if (!budget_text.empty()) tc.memory_budget = rtp::parse_memory_budget(budget_text, rtp::on_demand_bytes(reader));
    tc.prefetch = prefetch;
    tc.speculation = speculation;
    const uint64_t budget = tc.memory_budget;
    const std::unique_ptr<rtp::Tracer> tracer = rtp::open_tracer(reader, tc);
    const bool ooc = tracer->out_of_core();
    std::vector<rtp::fmt::Ray> rays;
    std::string camera_text;
    if (!make_rays.empty()) {
      int w = 0, h = 0;
      if (!parse_size(make_rays, &w, &h))
        throw rtp::Error(rtp::ExitCode::kUsage, "--make-camera-rays " + make_rays + ": expected WxH, e.g. 640x480");
      rtp::check_output_path(rays_path);
      rays = rtp::camera_rays(reader, w, h, camera).rays;  // the ray file is written with the hits, below
    } else if (render) {
      rtp::CameraRays cr = rtp::camera_rays(reader, img_w, img_h, camera);
      rays = std::move(cr.rays);
      camera_text = cr.description;
    } else {
      rays = rtp::read_ray_file(rays_path);
    }
    // Packets of an image: its rays traced in Hilbert-ordered 4x4 tiles (reader/tile_order.h), the hits put
    // back in pixel order. Ray files are traced in their own order.
    std::vector<uint32_t> tile_order;
    if (render && packet) tile_order = rtp::hilbert_tile_order(img_w, img_h);
    std::vector<rtp::fmt::Ray> tiled(tile_order.size());
    for (size_t k = 0; k < tile_order.size(); ++k) tiled[k] = rays[tile_order[k]];
    const std::vector<rtp::fmt::Ray>& traced = tile_order.empty() ? rays : tiled;
    rtp::PackageTraceOptions opt;
    opt.cull = force_cull || (ooc && !no_cull);
    const rtp::Isa best = rtp::detect_isa();
    opt.isa = isa == "best" ? best : isa == "avx512" ? rtp::Isa::kAvx512 : isa == "avx2" ? rtp::Isa::kAvx2 : rtp::Isa::kScalar;
    if (int(opt.isa) > int(best))
      throw rtp::Error(rtp::ExitCode::kUsage, std::string("--isa ") + isa + ": this CPU supports up to " + rtp::isa_name(best));
    opt.order = order == "active" ? rtp::TraversalOrder::kActiveList : rtp::TraversalOrder::kOctantStack;
    opt.packet = opt.isa == rtp::Isa::kScalar ? 0 : packet;  // the scalar reference has no packets
    std::vector<rtp::fmt::Hit> hits(any ? 0 : rays.size() * (multi ? multi : 1));
    std::vector<uint32_t> counts(multi ? rays.size() : 0);
    std::vector<uint8_t> occ(any ? rays.size() : 0);
    std::atomic<uint64_t> invalid{0}, visits{0}, culled{0}, packets{0}, packet_rays{0}, node_tests{0}, active_lanes{0};
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<rtp::fmt::Hit> tiled_hits(tile_order.size());
    rtp::fmt::Hit* out = tile_order.empty() ? hits.data() : tiled_hits.data();
    const rtp::TracerStats os = any     ? tracer->any(traced.data(), occ.data(), traced.size(), opt)
                                : multi ? tracer->multi(traced.data(), traced.size(), multi, hits.data(), counts.data(), opt)
                                        : tracer->closest(traced.data(), out, traced.size(), opt);
    for (size_t k = 0; k < tile_order.size(); ++k) hits[tile_order[k]] = tiled_hits[k];
    invalid = os.invalid_rays;
    visits = os.point_visits;
    culled = os.culled_visits;
    packets = os.packets, packet_rays = os.packet_rays;
    node_tests = os.packet_node_tests, active_lanes = os.packet_active_lanes;
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    // --make-camera-rays: the ray file is written now and put at its path after the hit file, so a trace or
    // an output that fails leaves neither (a complete ray file of a failed run was left behind).
    std::unique_ptr<rtp::OutputFile> made_rays;
    if (!make_rays.empty()) {
      made_rays = std::make_unique<rtp::OutputFile>(rays_path);
      made_rays->write_at(0, rays.data(), rays.size() * sizeof(rtp::fmt::Ray));
      made_rays->set_size(rays.size() * sizeof(rtp::fmt::Ray));
    }
    uint64_t hit_count = 0, multi_hits = 0;
    size_t first_invalid = rays.size();  // named on stderr and in --json: which ray to look at
    if (invalid.load())
      for (size_t i = 0; i < rays.size() && first_invalid == rays.size(); ++i)
        if (!rtp::ray_is_valid(rays[i])) first_invalid = i;
    if (any) {
      for (uint8_t o : occ) hit_count += o;
      rtp::write_output_file(hits_path, occ.data(), occ.size());
    } else if (multi) {
      for (uint32_t c : counts) hit_count += c > 0, multi_hits += c;
      rtp::write_output_file(hits_path, hits.data(), hits.size() * sizeof(rtp::fmt::Hit));
    } else {
      for (const auto& h : hits) hit_count += h.t != std::numeric_limits<float>::infinity();
      std::vector<rtp::fmt::Shading> shading;
      bool stored_normals = false;
      rtp::image::Shade shade_mode = rtp::image::Shade::kNormal;
      rtp::image::parse_shade(shade_name, &shade_mode);
      const bool need_normals = render && shade_mode != rtp::image::Shade::kDepth;
      if (!shading_path.empty() || need_normals) {
        const rtp::AttributeLookup lookup(reader);
        stored_normals = lookup.has_normals();
        if (!shading_path.empty() && !lookup.has_normals() && !lookup.has_uvs())
          std::cerr << "warning: " << package << ": no attribute streams (convert with --attributes normal,uv); "
                    << "--shading writes zeros\n";
        if (!shading_path.empty() || stored_normals) {
          shading.resize(hits.size());
          tbb::parallel_for(size_t(0), hits.size(), [&](size_t i) { shading[i] = lookup.shade(hits[i]); });
        }
      }
      // Written first: the hit file appears only when everything succeeded.
      if (!shading_path.empty()) rtp::write_output_file(shading_path, shading.data(), shading.size() * sizeof(rtp::fmt::Shading));
      if (render) {
        const rtp::image::Rgb8 img =
            rtp::image::shade(rays.data(), hits.data(), img_w, img_h, shade_mode, stored_normals ? shading.data() : nullptr);
        const std::vector<uint8_t> png = rtp::image::encode_png(img);
        rtp::write_output_file(image_path, png.data(), png.size());
        const char* normals = shade_mode == rtp::image::Shade::kDepth ? ""
                              : stored_normals                        ? ", stored normals"
                                                                      : ", normals from neighbouring hits";
        if (!json)
          std::fprintf(stderr, "image: %s, %dx%d, %s, shade %s%s\n", image_path.c_str(), img_w, img_h, camera_text.c_str(),
                       shade_name.c_str(), normals);
      }
      if (!hits_path.empty()) rtp::write_output_file(hits_path, hits.data(), hits.size() * sizeof(rtp::fmt::Hit));
    }
    if (made_rays) made_rays->commit();
    nlohmann::json j = {{"rays", rays.size()},
                        {any ? "occluded" : "hits", hit_count},
                        {"misses", rays.size() - hit_count - invalid.load()},
                        {"invalid_rays", invalid.load()},
                        {"first_invalid_ray", first_invalid < rays.size() ? nlohmann::json(first_invalid) : nlohmann::json()},
                        {"seconds", secs},
                        {"mrays_per_s", secs > 0 ? double(rays.size()) / secs / 1e6 : 0.0},
                        {"isa", rtp::isa_name(opt.isa)},
                        {"order", order},
                        {"direct_io", reader.direct_io()}};
    if (multi) j["multi_hit"] = {{"k", multi}, {"hits", multi_hits}};
    // Wu 2016 §4.2.1 SIMD utilization: active rays per packet node test over the packet size.
    const double utilization =
        opt.packet && node_tests.load() ? double(active_lanes.load()) / (double(node_tests.load()) * opt.packet) : 0.0;
    // A ray traced at two batching points counts twice: shares are of the traced (entered, not culled) visits.
    const uint64_t traced_visits = visits.load() - culled.load();
    const double packet_share = traced_visits ? double(packet_rays.load()) / double(traced_visits) : 0.0;
    j["packets"] = {{"size", opt.packet},
                    {"order", tile_order.empty() ? "as given" : "hilbert 4x4 tiles"},
                    {"packets", packets.load()},
                    {"packet_ray_visits", packet_rays.load()},
                    {"packet_visit_share", packet_share},
                    {"simd_utilization", utilization}};
    if (render)
      j["image"] = {{"path", rtp::utf8_display(image_path)},
                    {"width", img_w},
                    {"height", img_h},
                    {"camera", camera_text},
                    {"shade", shade_name}};
    // Culling (Molenaar 2019 §3.2): how many batching-point visits the DAGs saved.
    const bool has_dags = tracer->has_dags();
    const bool culling = opt.cull && has_dags;
    const double rate = visits.load() ? double(culled.load()) / double(visits.load()) : 0.0;
    j["culling"] = culling     ? "on"
                   : !has_dags ? "off (package has no DAGs)"
                   : no_cull   ? "off (--no-cull)"
                               : "off (in core; --cull tests the DAGs)";
    j["batching_point_visits"] = visits.load();
    j["culled_visits"] = culled.load();
    j["cull_rate"] = rate;
    // The same keys for both paths: in core every chunk is loaded (and checked) before the first ray.
    const rtp::PackageLoadStats ls = tracer->load_stats();
    j["mode"] = ooc ? "out of core" : "in core";
    j["memory_budget"] = ooc ? nlohmann::json(budget) : nlohmann::json(nullptr);
    j["rounds"] = ooc ? os.rounds : 0;
    j["passes"] = ooc ? os.passes : 0;
    j["chunks_loaded"] = ooc ? os.cache.loads : ls.chunks;
    j["bytes_read"] = ooc ? os.cache.bytes_read : ls.stored_bytes;
    j["chunk_raw_bytes"] = ooc ? os.cache.raw_bytes_loaded : ls.raw_bytes;
    j["cache_hit_rate"] = ooc ? nlohmann::json(os.cache.hit_rate()) : nlohmann::json(nullptr);
    j["cache_evictions"] = ooc ? os.cache.evictions : 0;
    j["chunks_prefetched"] = ooc ? os.cache.prefetched : 0;
    j["peak_cache_bytes"] = ooc ? os.cache.peak_resident_bytes : ls.raw_bytes;
    j["peak_resident_bytes"] = ooc ? os.peak_resident_bytes : ls.raw_bytes;
    j["peak_rss_bytes"] = uint64_t(rtp::peak_rss_mib() * 1048576.0);
    j["load_seconds"] = ooc ? os.load_seconds : ls.total_seconds;
    j["load_read_seconds"] = ooc ? os.cache.load_seconds : ls.read_seconds;
    j["load_check_seconds"] = ooc ? std::max(0.0, os.load_seconds - os.cache.load_seconds) : ls.check_seconds;
    j["stage_seconds"] = {{"load", ooc ? os.load_seconds : ls.total_seconds},
                          {"load_read", ooc ? os.cache.load_seconds : ls.read_seconds},
                          {"load_check", ooc ? nlohmann::json(nullptr) : nlohmann::json(ls.check_seconds)},
                          {"walk", ooc ? nlohmann::json(os.walk_seconds) : nlohmann::json(nullptr)},
                          {"trace", ooc ? os.trace_seconds : secs},
                          {"total", (ooc ? 0.0 : ls.total_seconds) + secs}};
    j.update(rtp::tools::json_stamp("rtpack-trace"));
    if (json)
      std::cout << j.dump(2) << "\n";
    else {
      if (ooc)
        std::fprintf(stderr,
                     "out of core, budget %.1f MiB: %llu rounds, %llu chunks loaded (%llu read ahead; %.1f MiB read, %.1f MiB "
                     "decompressed), cache hit rate %.1f%%, %llu evictions; peak cache %.1f MiB, peak resident %.1f MiB, "
                     "peak RSS %.1f MiB; load %.3f s, walk %.3f s, trace %.3f s\n",
                     double(budget) / 1048576.0, (unsigned long long)os.rounds, (unsigned long long)os.cache.loads,
                     (unsigned long long)os.cache.prefetched, double(os.cache.bytes_read) / 1048576.0,
                     double(os.cache.raw_bytes_loaded) / 1048576.0, 100 * os.cache.hit_rate(),
                     (unsigned long long)os.cache.evictions, double(os.cache.peak_resident_bytes) / 1048576.0,
                     double(os.peak_resident_bytes) / 1048576.0, rtp::peak_rss_mib(), os.load_seconds, os.walk_seconds,
                     os.trace_seconds);
      else
        std::fprintf(stderr, "load: %llu chunks, %.1f MiB in %.3f s (read and decompress %.3f s, structural checks %.3f s)\n",
                     (unsigned long long)ls.chunks, double(ls.raw_bytes) / 1048576.0, ls.total_seconds, ls.read_seconds,
                     ls.check_seconds);
      if (opt.packet)
        std::fprintf(stderr,
                     "packets of %u (%s): %llu packets; %.1f%% of the traced batching-point visits went in packets; SIMD "
                     "utilization %.1f%%\n",
                     opt.packet, tile_order.empty() ? "rays in file order" : "Hilbert-ordered 4x4 tiles",
                     (unsigned long long)packets.load(), 100 * packet_share, 100 * utilization);
      if (multi)
        std::fprintf(stderr, "multi-hit: the %u closest hits of each ray, %llu in all (%.2f per ray that hits)\n", multi,
                     (unsigned long long)multi_hits, hit_count ? double(multi_hits) / double(hit_count) : 0.0);
      std::fprintf(stderr,
                   "%zu rays: %llu %s, %llu invalid (returned as misses); %.3f s, %.2f Mrays/s (%s, %s); "
                   "batching-point visits %llu, culled %llu (%.1f%%, culling %s)\n",
                   rays.size(), (unsigned long long)hit_count, any ? "occluded" : "hits", (unsigned long long)invalid.load(),
                   secs, j["mrays_per_s"].get<double>(), rtp::isa_name(opt.isa), order.c_str(), (unsigned long long)visits.load(),
                   (unsigned long long)culled.load(), 100 * rate, j["culling"].get<std::string>().c_str());
      if (first_invalid < rays.size()) {
        const rtp::fmt::Ray& r = rays[first_invalid];
        std::fprintf(stderr,
                     "warning: %llu invalid rays (NaN/Inf, tnear > tfar or tnear = inf: formats/ray_file.h), the first ray "
                     "%zu: org (%g, %g, %g) dir (%g, %g, %g) t [%g, %g]\n",
                     (unsigned long long)invalid.load(), first_invalid, r.org[0], r.org[1], r.org[2], r.dir[0], r.dir[1],
                     r.dir[2], r.tnear, r.tfar);
      }
    }
    return 0;
  });
}
