// rtpack-trace: traces a ray file through a package (in core) and writes a hit file — the way
// outside tools check rtpack (formats/SPEC.md §5).
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <CLI/CLI.hpp>
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
#include "path_trace_cli.h"
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

// The command line, as parsed and checked.
struct Args {
  std::string package, rays_path, hits_path, isa = "best", order = "octant", make_rays, image_path, size = "1280x720";
  std::string shade_name = "normal", shading_path, budget_text;
  int threads = 0, camera = -1, img_w = 0, img_h = 0;
  bool any = false, json = false, direct = false, no_cull = false, force_cull = false, prefetch = false, render = false;
  uint32_t multi = 0, speculation = rtp::kDefaultSpeculation, packet = 0;
  rtp::tools::PathTraceCommand path;  // --path-trace
};

void add_options(CLI::App& app, Args& a) {
  app.add_option("package", a.package, "the .rtp package")->required();
  app.add_option("--rays", a.rays_path, "ray file: N x {ox oy oz tnear dx dy dz tfar} float32 (not with --image)");
  app.add_option("--make-camera-rays", a.make_rays,
                 "WxH: first write primary rays from the package's camera (--camera; or an automatic one) to --rays");
  app.add_option("--hits", a.hits_path,
                 "hit file to write: N x {t, instance, primitive, u, v} (or N bytes with --any); with --image, the "
                 "image's rays in pixel order");
  app.add_option("--image", a.image_path, "render the camera's primary rays to this PNG (no --rays needed)");
  app.add_option("--size", a.size, "image size WxH for --image (default 1280x720)");
  app.add_option("--camera", a.camera,
                 "glTF camera index for --image and --make-camera-rays (default: the first, or an "
                 "automatic camera framing the bounds when the package has none)")
      ->check(rtp::tools::non_negative());
  app.add_option("--shade", a.shade_name, "--image colours: normal (default), depth or instance")
      ->check(CLI::IsMember({"normal", "depth", "instance"}));
  app.add_option("--shading", a.shading_path,
                 "also write N x {normal xyz, u, v} float32: interpolated world normal and TEXCOORD_0 per hit "
                 "(packages converted with --attributes)");
  app.add_flag("--any", a.any, "any-hit (occlusion): write one byte per ray, 1 = occluded");
  app.add_option("--multi-hit", a.multi,
                 "K: write the K closest hits of each ray (K hit records per ray, nearest first, then misses; SPEC §5), "
                 "K in 1..64")
      ->check(CLI::Range(1u, rtp::kMaxMultiHit));
  app.add_option("--threads", a.threads, "worker threads (default: all cores)")->check(rtp::tools::positive());
  app.add_option("--isa", a.isa, "best, scalar, avx2 or avx512")->check(CLI::IsMember({"best", "scalar", "avx2", "avx512"}));
  app.add_option("--order", a.order, "traversal order: octant (stack) or active (Benthin's active list)")
      ->check(CLI::IsMember({"octant", "active"}));
  app.add_option("--memory-budget", a.budget_text,
                 "trace out of core: batching points and mesh segments held in a cache of this many bytes "
                 "(e.g. 256MiB, 2GB, or 10% of the package's on-demand bytes); in core without it");
  app.add_flag("--prefetch", a.prefetch,
               "with --memory-budget: read the next round's likely chunks on an I/O thread while a "
               "round traces (same hits; off by default, see docs/trace/budget.md)");
  app.add_option("--speculation", a.speculation,
                 "with --memory-budget: queue a ray at its next N batching points at once, 1..64 (same hits; default " +
                     std::to_string(rtp::kDefaultSpeculation) + "; 1 walks one point at a time, docs/trace/budget.md)")
      ->check(CLI::Range(1, 64));
  app.add_flag("--direct-io", a.direct, "read chunks with O_DIRECT (falls back when unsupported)");
  // Molenaar 2019 §3.2's DAG test spares the out-of-core tracer chunk loads; in core every chunk is loaded and
  // the test costs more than the BVH walks it saves (1.3-2.4x slower on the samples), so it is off there.
  CLI::Option* no_cull_opt = app.add_flag(
      "--no-cull", a.no_cull,
      "with --memory-budget: do not test rays against the batching points' culling DAGs (same hits; in core they are not "
      "tested unless --cull)");
  app.add_flag("--cull", a.force_cull,
               "in core too: test rays against the batching points' culling DAGs first (same hits, slower in core; on "
               "by default with --memory-budget, where a culled point is a chunk not read)")
      ->excludes(no_cull_opt);
  app.add_flag("--json", a.json, "print the counts as JSON on stdout");
  // A renderer's workload on the streaming API (rtpack.h RayStream): docs/trace/path.md.
  app.add_option("--path-trace", a.path.image,
                 "path-trace the camera's view to this PNG (binary PPM for a .ppm name) through the streaming API (Lambert, sky "
                 "and sun, shadow rays; "
                 "--size, --spp, --bounces, --paths-in-flight, --seed, --memory-budget, --no-cull); the same bytes for any "
                 "budget, thread count and culling");
  app.add_option("--spp", a.path.spp, "--path-trace: samples (paths) per pixel (default 1)")->check(CLI::Range(1u, 4096u));
  app.add_option("--bounces", a.path.bounces, "--path-trace: bounces after the primary hit (default 2)")
      ->check(CLI::Range(0u, 16u));
  app.add_option("--paths-in-flight", a.path.paths_in_flight, "--path-trace: paths traced at once, one wave each (default 16384)")
      ->check(CLI::Range(1u, 1u << 24));
  app.add_option("--seed", a.path.seed, "--path-trace: the random numbers' seed (default 1)");
  app.add_flag("--refill", a.path.refill,
               "--path-trace: start a new path whenever one ends (one flush for the image) instead of waves; same image");
  app.add_option("--packet", a.packet,
                 "closest hits in core: trace each run of N consecutive rays as a packet, N = 4, 8 or 16, or 0 for single "
                 "rays (same hits either way; default 16 with --image, whose rays go in Hilbert-ordered 4x4 tiles, else 0)")
      ->check(CLI::IsMember({0u, 4u, 8u, 16u}));
}

// What is wrong with a command line CLI11 accepted (options that exclude each other), or "" when nothing is;
// sets the defaults that depend on other options.
std::string usage_problem(const CLI::App& app, Args& a) {
  if (!a.path.image.empty()) {
    for (const char* o : {"--rays", "--hits", "--image", "--any", "--multi-hit", "--packet", "--make-camera-rays", "--shading",
                          "--shade", "--cull", "--prefetch", "--speculation", "--order"})
      if (app.count(o)) return std::string("--path-trace renders through the streaming API: leave out ") + o;
    if (!parse_size(a.size, &a.path.width, &a.path.height)) return "--size " + a.size + ": expected WxH, e.g. 512x512";
    if (!app.count("--size")) a.path.width = a.path.height = 512;
    a.path.package = a.package, a.path.budget_text = a.budget_text, a.path.isa = a.isa;
    a.path.camera = a.camera, a.path.threads = a.threads, a.path.no_cull = a.no_cull, a.path.direct = a.direct;
    a.path.json = a.json;
    return "";
  }
  for (const char* o : {"--spp", "--bounces", "--paths-in-flight", "--seed", "--refill"})
    if (app.count(o)) return std::string(o) + " belongs to --path-trace";
  a.render = !a.image_path.empty();
  if (a.render && (!a.rays_path.empty() || !a.make_rays.empty()))
    return "--image traces the camera's own rays: leave out --rays and --make-camera-rays";
  if (a.render && a.any) return "--image shows closest hits: it cannot be used with --any";
  if (a.multi && (a.any || a.render || app.count("--shading")))
    return "--multi-hit writes the K closest hits of a ray file: leave out --any, --image and --shading";
  if (!a.render && (a.rays_path.empty() || a.hits_path.empty()))
    return "--rays and --hits are required (or --image PNG to render the camera's rays)";
  if (a.render && !parse_size(a.size, &a.img_w, &a.img_h)) return "--size " + a.size + ": expected WxH, e.g. 1280x720";
  if (!a.render && (app.count("--size") > 0 || app.count("--shade") > 0)) return "--size and --shade belong to --image";
  if (!a.render && a.camera >= 0 && a.make_rays.empty()) return "--camera belongs to --image and --make-camera-rays";
  const bool packet_given = app.count("--packet") > 0;
  if (packet_given && a.packet && (a.any || a.multi))
    return "--packet traces closest hits: it cannot be used with --any or --multi-hit";
  if (packet_given && a.packet && !a.budget_text.empty())
    return "--packet: the out-of-core tracer (--memory-budget) traces single rays; leave out one of them";
  if (!packet_given && a.render && a.budget_text.empty()) a.packet = 16;
  return "";
}

// No output may be an input (or another output): compared by device and inode.
void check_outputs(const Args& a) {
  for (const std::string* out : {&a.hits_path, &a.shading_path, &a.image_path}) {
    rtp::check_not_same_file(a.package, *out);
    rtp::check_not_same_file(a.rays_path, *out);
  }
  if (!a.make_rays.empty()) rtp::check_not_same_file(a.package, a.rays_path);  // the ray file is written then
  rtp::check_not_same_file(a.hits_path, a.shading_path);
  rtp::check_not_same_file(a.hits_path, a.image_path);
  rtp::check_not_same_file(a.shading_path, a.image_path);
  if ((!a.hits_path.empty() && (a.hits_path == a.shading_path || a.hits_path == a.image_path)) ||
      (!a.shading_path.empty() && a.shading_path == a.image_path) ||
      (!a.make_rays.empty() && (a.rays_path == a.hits_path || a.rays_path == a.shading_path)))
    throw rtp::Error(rtp::ExitCode::kUsage, "two outputs name the same file");
  if (!a.hits_path.empty()) rtp::check_output_path(a.hits_path);
  if (a.render) rtp::check_output_path(a.image_path);
  if (!a.shading_path.empty()) {
    if (a.any) throw rtp::Error(rtp::ExitCode::kUsage, "--shading needs closest hits: it cannot be used with --any");
    rtp::check_output_path(a.shading_path);
  }
}

// The rays to trace: made from the package's camera (--make-camera-rays, --image) or read from --rays.
std::vector<rtp::fmt::Ray> input_rays(const rtp::PackageReader& reader, const Args& a, std::string* camera_text) {
  if (!a.make_rays.empty()) {
    int w = 0, h = 0;
    if (!parse_size(a.make_rays, &w, &h))
      throw rtp::Error(rtp::ExitCode::kUsage, "--make-camera-rays " + a.make_rays + ": expected WxH, e.g. 640x480");
    rtp::check_output_path(a.rays_path);
    return rtp::camera_rays(reader, w, h, a.camera).rays;  // the ray file is written with the hits, in trace()
  }
  if (a.render) {
    rtp::CameraRays cr = rtp::camera_rays(reader, a.img_w, a.img_h, a.camera);
    *camera_text = cr.description;
    return std::move(cr.rays);
  }
  return rtp::read_ray_file(a.rays_path);
}

rtp::PackageTraceOptions trace_options(const Args& a, bool ooc) {
  rtp::PackageTraceOptions opt;
  opt.cull = a.force_cull || (ooc && !a.no_cull);
  const rtp::Isa best = rtp::detect_isa();
  opt.isa = a.isa == "best"     ? best
            : a.isa == "avx512" ? rtp::Isa::kAvx512
            : a.isa == "avx2"   ? rtp::Isa::kAvx2
                                : rtp::Isa::kScalar;
  if (int(opt.isa) > int(best))
    throw rtp::Error(rtp::ExitCode::kUsage, std::string("--isa ") + a.isa + ": this CPU supports up to " + rtp::isa_name(best));
  opt.order = a.order == "active" ? rtp::TraversalOrder::kActiveList : rtp::TraversalOrder::kOctantStack;
  opt.packet = opt.isa == rtp::Isa::kScalar ? 0 : a.packet;  // the scalar reference has no packets
  return opt;
}

// What one run traced, for the report.
struct Run {
  size_t rays = 0;
  uint64_t hit_count = 0, multi_hits = 0;
  size_t first_invalid = 0;  // == rays when every ray is valid
  double secs = 0;
  rtp::PackageTraceOptions opt;
  bool tiled = false, ooc = false, has_dags = false;
  uint64_t budget = 0;
  std::string camera_text;
  rtp::TracerStats os;
  rtp::PackageLoadStats ls;
};

// Closest hits: the shading file, the image and the hit file, in that order, so the hit file appears only
// when everything succeeded.
void write_closest(const Args& a, const rtp::PackageReader& reader, const std::vector<rtp::fmt::Ray>& rays,
                   const std::vector<rtp::fmt::Hit>& hits, const std::string& camera_text) {
  std::vector<rtp::fmt::Shading> shading;
  bool stored_normals = false;
  rtp::image::Shade shade_mode = rtp::image::Shade::kNormal;
  rtp::image::parse_shade(a.shade_name, &shade_mode);
  const bool need_normals = a.render && shade_mode != rtp::image::Shade::kDepth;
  if (!a.shading_path.empty() || need_normals) {
    const rtp::AttributeLookup lookup(reader);
    stored_normals = lookup.has_normals();
    if (!a.shading_path.empty() && !lookup.has_normals() && !lookup.has_uvs())
      std::cerr << "warning: " << a.package << ": no attribute streams (convert with --attributes normal,uv); "
                << "--shading writes zeros\n";
    if (!a.shading_path.empty() || stored_normals) {
      shading.resize(hits.size());
      tbb::parallel_for(size_t(0), hits.size(), [&](size_t i) { shading[i] = lookup.shade(hits[i]); });
    }
  }
  if (!a.shading_path.empty()) rtp::write_output_file(a.shading_path, shading.data(), shading.size() * sizeof(rtp::fmt::Shading));
  if (a.render) {
    const rtp::image::Rgb8 img =
        rtp::image::shade(rays.data(), hits.data(), a.img_w, a.img_h, shade_mode, stored_normals ? shading.data() : nullptr);
    const std::vector<uint8_t> png = rtp::image::encode_png(img);
    rtp::write_output_file(a.image_path, png.data(), png.size());
    const char* normals = shade_mode == rtp::image::Shade::kDepth ? ""
                          : stored_normals                        ? ", stored normals"
                                                                  : ", normals from neighbouring hits";
    if (!a.json)
      std::fprintf(stderr, "image: %s, %dx%d, %s, shade %s%s\n", a.image_path.c_str(), a.img_w, a.img_h, camera_text.c_str(),
                   a.shade_name.c_str(), normals);
  }
  if (!a.hits_path.empty()) rtp::write_output_file(a.hits_path, hits.data(), hits.size() * sizeof(rtp::fmt::Hit));
}

// Wu 2016 §4.2.1 SIMD utilization: active rays per packet node test over the packet size.
double simd_utilization(const Run& r) {
  const uint64_t tests = r.os.packet_node_tests;
  return r.opt.packet && tests ? double(r.os.packet_active_lanes) / (double(tests) * r.opt.packet) : 0.0;
}

// A ray traced at two batching points counts twice: shares are of the traced (entered, not culled) visits.
double packet_visit_share(const Run& r) {
  const uint64_t traced_visits = r.os.point_visits - r.os.culled_visits;
  return traced_visits ? double(r.os.packet_rays) / double(traced_visits) : 0.0;
}

nlohmann::json report_json(const Args& a, const Run& r, bool direct_io) {
  const rtp::TracerStats& os = r.os;
  const rtp::PackageLoadStats& ls = r.ls;
  const bool ooc = r.ooc;
  nlohmann::json j = {{"rays", r.rays},
                      {a.any ? "occluded" : "hits", r.hit_count},
                      {"misses", r.rays - r.hit_count - os.invalid_rays},
                      {"invalid_rays", os.invalid_rays},
                      {"first_invalid_ray", r.first_invalid < r.rays ? nlohmann::json(r.first_invalid) : nlohmann::json()},
                      {"seconds", r.secs},
                      {"mrays_per_s", r.secs > 0 ? double(r.rays) / r.secs / 1e6 : 0.0},
                      {"isa", rtp::isa_name(r.opt.isa)},
                      {"order", a.order},
                      {"direct_io", direct_io}};
  if (a.multi) j["multi_hit"] = {{"k", a.multi}, {"hits", r.multi_hits}};
  j["packets"] = {{"size", r.opt.packet},
                  {"order", r.tiled ? "hilbert 4x4 tiles" : "as given"},
                  {"packets", os.packets},
                  {"packet_ray_visits", os.packet_rays},
                  {"packet_visit_share", packet_visit_share(r)},
                  {"simd_utilization", simd_utilization(r)}};
  if (a.render)
    j["image"] = {{"path", rtp::utf8_display(a.image_path)},
                  {"width", a.img_w},
                  {"height", a.img_h},
                  {"camera", r.camera_text},
                  {"shade", a.shade_name}};
  // Culling (Molenaar 2019 §3.2): how many batching-point visits the DAGs saved.
  j["culling"] = r.opt.cull && r.has_dags ? "on"
                 : !r.has_dags            ? "off (package has no DAGs)"
                 : a.no_cull              ? "off (--no-cull)"
                                          : "off (in core; --cull tests the DAGs)";
  j["batching_point_visits"] = os.point_visits;
  j["culled_visits"] = os.culled_visits;
  j["cull_rate"] = os.point_visits ? double(os.culled_visits) / double(os.point_visits) : 0.0;
  // The same keys for both paths: in core every chunk is loaded (and checked) before the first ray.
  j["mode"] = ooc ? "out of core" : "in core";
  j["memory_budget"] = ooc ? nlohmann::json(r.budget) : nlohmann::json(nullptr);
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
                        {"trace", ooc ? os.trace_seconds : r.secs},
                        {"total", (ooc ? 0.0 : ls.total_seconds) + r.secs}};
  j.update(rtp::tools::json_stamp("rtpack-trace"));
  return j;
}

void print_summary(const Args& a, const Run& r, const std::vector<rtp::fmt::Ray>& rays, const nlohmann::json& j) {
  const rtp::TracerStats& os = r.os;
  const rtp::PackageLoadStats& ls = r.ls;
  if (r.ooc)
    std::fprintf(stderr,
                 "out of core, budget %.1f MiB: %llu rounds, %llu chunks loaded (%llu read ahead; %.1f MiB read, %.1f MiB "
                 "decompressed), cache hit rate %.1f%%, %llu evictions; peak cache %.1f MiB, peak resident %.1f MiB, "
                 "peak RSS %.1f MiB; load %.3f s, walk %.3f s, trace %.3f s\n",
                 double(r.budget) / 1048576.0, (unsigned long long)os.rounds, (unsigned long long)os.cache.loads,
                 (unsigned long long)os.cache.prefetched, double(os.cache.bytes_read) / 1048576.0,
                 double(os.cache.raw_bytes_loaded) / 1048576.0, 100 * os.cache.hit_rate(), (unsigned long long)os.cache.evictions,
                 double(os.cache.peak_resident_bytes) / 1048576.0, double(os.peak_resident_bytes) / 1048576.0,
                 rtp::peak_rss_mib(), os.load_seconds, os.walk_seconds, os.trace_seconds);
  else
    std::fprintf(stderr, "load: %llu chunks, %.1f MiB in %.3f s (read and decompress %.3f s, structural checks %.3f s)\n",
                 (unsigned long long)ls.chunks, double(ls.raw_bytes) / 1048576.0, ls.total_seconds, ls.read_seconds,
                 ls.check_seconds);
  if (r.opt.packet)
    std::fprintf(stderr,
                 "packets of %u (%s): %llu packets; %.1f%% of the traced batching-point visits went in packets; SIMD "
                 "utilization %.1f%%\n",
                 r.opt.packet, r.tiled ? "Hilbert-ordered 4x4 tiles" : "rays in file order", (unsigned long long)os.packets,
                 100 * packet_visit_share(r), 100 * simd_utilization(r));
  if (a.multi)
    std::fprintf(stderr, "multi-hit: the %u closest hits of each ray, %llu in all (%.2f per ray that hits)\n", a.multi,
                 (unsigned long long)r.multi_hits, r.hit_count ? double(r.multi_hits) / double(r.hit_count) : 0.0);
  std::fprintf(stderr,
               "%zu rays: %llu %s, %llu invalid (returned as misses); %.3f s, %.2f Mrays/s (%s, %s); "
               "batching-point visits %llu, culled %llu (%.1f%%, culling %s)\n",
               r.rays, (unsigned long long)r.hit_count, a.any ? "occluded" : "hits", (unsigned long long)os.invalid_rays, r.secs,
               j["mrays_per_s"].get<double>(), rtp::isa_name(r.opt.isa), a.order.c_str(), (unsigned long long)os.point_visits,
               (unsigned long long)os.culled_visits, 100 * j["cull_rate"].get<double>(), j["culling"].get<std::string>().c_str());
  if (r.first_invalid < r.rays) {
    const rtp::fmt::Ray& ray = rays[r.first_invalid];
    std::fprintf(stderr,
                 "warning: %llu invalid rays (NaN/Inf, tnear > tfar or tnear = inf: formats/ray_file.h), the first ray "
                 "%zu: org (%g, %g, %g) dir (%g, %g, %g) t [%g, %g]\n",
                 (unsigned long long)os.invalid_rays, r.first_invalid, ray.org[0], ray.org[1], ray.org[2], ray.dir[0], ray.dir[1],
                 ray.dir[2], ray.tnear, ray.tfar);
  }
}

int trace(const Args& a) {
  check_outputs(a);
  const rtp::PackageReader reader(a.package, a.direct);
  // In core (every chunk loaded first) or, with --memory-budget, the batched out-of-core tracer.
  rtp::TracerConfig tc;
  if (!a.budget_text.empty()) tc.memory_budget = rtp::parse_memory_budget(a.budget_text, rtp::on_demand_bytes(reader));
  tc.prefetch = a.prefetch;
  tc.speculation = a.speculation;
  const std::unique_ptr<rtp::Tracer> tracer = rtp::open_tracer(reader, tc);
  Run r;
  r.budget = tc.memory_budget;
  r.ooc = tracer->out_of_core();
  r.has_dags = tracer->has_dags();
  const std::vector<rtp::fmt::Ray> rays = input_rays(reader, a, &r.camera_text);
  r.rays = rays.size();
  // Packets of an image: its rays traced in Hilbert-ordered 4x4 tiles (reader/tile_order.h), the hits put
  // back in pixel order. Ray files are traced in their own order.
  std::vector<uint32_t> tile_order;
  if (a.render && a.packet) tile_order = rtp::hilbert_tile_order(a.img_w, a.img_h);
  r.tiled = !tile_order.empty();
  std::vector<rtp::fmt::Ray> tiled(tile_order.size());
  for (size_t k = 0; k < tile_order.size(); ++k) tiled[k] = rays[tile_order[k]];
  const std::vector<rtp::fmt::Ray>& traced = r.tiled ? tiled : rays;
  r.opt = trace_options(a, r.ooc);
  std::vector<rtp::fmt::Hit> hits(a.any ? 0 : rays.size() * (a.multi ? a.multi : 1));
  std::vector<uint32_t> counts(a.multi ? rays.size() : 0);
  std::vector<uint8_t> occ(a.any ? rays.size() : 0);
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<rtp::fmt::Hit> tiled_hits(tile_order.size());
  rtp::fmt::Hit* out = r.tiled ? tiled_hits.data() : hits.data();
  r.os = a.any     ? tracer->any(traced.data(), occ.data(), traced.size(), r.opt)
         : a.multi ? tracer->multi(traced.data(), traced.size(), a.multi, hits.data(), counts.data(), r.opt)
                   : tracer->closest(traced.data(), out, traced.size(), r.opt);
  for (size_t k = 0; k < tile_order.size(); ++k) hits[tile_order[k]] = tiled_hits[k];
  r.secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.ls = tracer->load_stats();
  // --make-camera-rays: the ray file is written now and put at its path after the hit file, so a trace or
  // an output that fails leaves neither (a complete ray file of a failed run was left behind).
  std::unique_ptr<rtp::OutputFile> made_rays;
  if (!a.make_rays.empty()) {
    made_rays = std::make_unique<rtp::OutputFile>(a.rays_path);
    made_rays->write_at(0, rays.data(), rays.size() * sizeof(rtp::fmt::Ray));
    made_rays->set_size(rays.size() * sizeof(rtp::fmt::Ray));
  }
  r.first_invalid = rays.size();  // named on stderr and in --json: which ray to look at
  if (r.os.invalid_rays)
    for (size_t i = 0; i < rays.size() && r.first_invalid == rays.size(); ++i)
      if (!rtp::ray_is_valid(rays[i])) r.first_invalid = i;
  if (a.any) {
    for (uint8_t o : occ) r.hit_count += o;
    rtp::write_output_file(a.hits_path, occ.data(), occ.size());
  } else if (a.multi) {
    for (uint32_t c : counts) r.hit_count += c > 0, r.multi_hits += c;
    rtp::write_output_file(a.hits_path, hits.data(), hits.size() * sizeof(rtp::fmt::Hit));
  } else {
    for (const auto& h : hits) r.hit_count += h.t != std::numeric_limits<float>::infinity();
    write_closest(a, reader, rays, hits, r.camera_text);
  }
  if (made_rays) made_rays->commit();
  const nlohmann::json j = report_json(a, r, reader.direct_io());
  if (a.json)
    std::cout << j.dump(2) << "\n";
  else
    print_summary(a, r, rays, j);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rtpack-trace: trace a ray file through a package"};
  rtp::tools::add_version_flag(app, "rtpack-trace");
  Args a;
  add_options(app, a);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return rtp::tools::parse_error_exit(app, e, "rtpack-trace", argc, argv);
  }
  std::unique_ptr<tbb::global_control> limit;
  if (a.threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, a.threads);
  if (const std::string problem = usage_problem(app, a); !problem.empty()) {
    if (a.json) return rtp::tools::report_error("rtpack-trace", true, a.package, rtp::ExitCode::kUsage, problem);
    std::cerr << "rtpack-trace: " << problem << "\nRun with --help for more information.\n";
    return int(rtp::ExitCode::kUsage);
  }
  return rtp::tools::run_reporting_errors("rtpack-trace", a.json, a.package,
                                          [&] { return a.path.image.empty() ? trace(a) : rtp::tools::run_path_trace(a.path); });
}
