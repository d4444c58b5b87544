// rtpack-trace: traces a ray file through a package (in core) and writes a hit file — the way
// outside tools check rtpack (formats/SPEC.md §5).
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include "core/error.h"
#include "core/json_checked.h"
#include "core/input_file.h"
#include "core/output_file.h"
#include "package/package.h"
#include "package/chunk_io.h"
#include "package/attribute_lookup.h"
#include "package/package_tracer.h"
#include "trace/ray_file.h"

namespace {

// Primary rays through a W x H image from the package's first glTF camera, or from an automatic
// camera framing the header bounds (looking at the centre from +z, 45 degrees).
std::vector<rtp::fmt::Ray> camera_rays(const rtp::PackageReader& r, int w, int h) {
  namespace fmt = rtp::fmt;
  const int64_t mi = r.find(fmt::ChunkKind::kMetadata, 0);
  nlohmann::json cam;
  std::string label;
  if (mi >= 0) {
    const rtp::AlignedBytes b = r.read(size_t(mi));
    rtp::ChunkView v(b.data(), b.size(), uint32_t(fmt::ChunkKind::kMetadata), rtp::chunk_label(r.toc()[size_t(mi)], size_t(mi)));
    const auto text = v.copy<uint8_t>(fmt::SectionType::kJson);
    label = v.label();
    rtp::jsonc::check_depth(std::string_view(reinterpret_cast<const char*>(text.data()), text.size()), label + ": metadata ");
    const auto meta = nlohmann::json::parse(text.begin(), text.end(), nullptr, false);
    if (meta.is_discarded() || !meta.is_object()) rtp::fail_invalid(label + ": metadata is not a JSON object");
    if (const nlohmann::json* cams = rtp::jsonc::find(meta, "cameras")) {
      if (!cams->is_array()) rtp::fail_invalid(label + ": /cameras: not an array");
      if (!cams->empty()) cam = (*cams)[0];
    }
  }
  double m[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
  double yfov = 0.785398, aspect = double(w) / h;
  const std::string cp = label + ": /cameras/0";  // the camera written by rtpack-convert (write_package.cpp)
  if (!cam.is_null() && rtp::jsonc::get_string(cam, "type", cp) == "perspective") {
    const nlohmann::json& world = rtp::jsonc::member(cam, "world", cp);
    if (!world.is_array() || world.size() != 12) rtp::fail_invalid(cp + "/world: needs 12 numbers");
    for (size_t i = 0; i < 12; ++i) m[i] = rtp::jsonc::as_number(world[i], cp + "/world/" + std::to_string(i));
    yfov = rtp::jsonc::get_number(cam, "yfov", cp);
    if (!(yfov > 0)) rtp::fail_invalid(cp + "/yfov: " + std::to_string(yfov) + " is not positive");
  } else {
    const auto& hd = r.header();
    double c[3], ext = 0;
    for (int k = 0; k < 3; ++k) {
      c[k] = 0.5 * (double(hd.bounds_lo[k]) + hd.bounds_hi[k]);
      ext = std::max(ext, double(hd.bounds_hi[k]) - hd.bounds_lo[k]);
    }
    m[3] = c[0];
    m[7] = c[1];
    m[11] = c[2] + 1.5 * ext + 1e-3;
  }
  std::vector<fmt::Ray> rays;
  rays.reserve(size_t(w) * size_t(h));
  const double t = std::tan(yfov / 2);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double px = (2 * (x + 0.5) / w - 1) * t * aspect, py = (1 - 2 * (y + 0.5) / h) * t;
      const double d[3] = {px, py, -1};  // camera looks down -z
      fmt::Ray ray{};
      for (int k = 0; k < 3; ++k) {
        ray.org[k] = float(m[4 * k + 3]);
        ray.dir[k] = float(m[4 * k] * d[0] + m[4 * k + 1] * d[1] + m[4 * k + 2] * d[2]);
      }
      ray.tnear = 0;
      ray.tfar = std::numeric_limits<float>::infinity();
      rays.push_back(ray);
    }
  return rays;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rtpack-trace: trace a ray file through a package"};
  std::string package, rays_path, hits_path, isa = "best", order = "octant";
  int threads = 0;
  bool any = false, json = false, direct = false, no_cull = false;
  app.add_option("package", package, "the .rtp package")->required();
  std::string make_rays;
  app.add_option("--rays", rays_path, "ray file: N x {ox oy oz tnear dx dy dz tfar} float32")->required();
  app.add_option("--make-camera-rays", make_rays,
                 "WxH: first write primary rays from the package's first camera (or an automatic one) to --rays");
  app.add_option("--hits", hits_path, "hit file to write: N x {t, instance, primitive, u, v} (or N bytes with --any)")->required();
  std::string shading_path;
  app.add_option("--shading", shading_path,
                 "also write N x {normal xyz, u, v} float32: interpolated world normal and TEXCOORD_0 per hit "
                 "(packages converted with --attributes)");
  app.add_flag("--any", any, "any-hit (occlusion): write one byte per ray, 1 = occluded");
  app.add_option("--threads", threads, "worker threads (default: all cores)")->check(CLI::PositiveNumber);
  app.add_option("--isa", isa, "best, scalar, avx2 or avx512")->check(CLI::IsMember({"best", "scalar", "avx2", "avx512"}));
  app.add_option("--order", order, "traversal order: octant (stack) or active (Benthin's active list)")
      ->check(CLI::IsMember({"octant", "active"}));
  app.add_flag("--direct-io", direct, "read chunks with O_DIRECT (falls back when unsupported)");
  app.add_flag("--no-cull", no_cull, "do not test rays against the batching points' culling DAGs (same hits, slower)");
  app.add_flag("--json", json, "print the counts as JSON on stdout");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : int(rtp::ExitCode::kUsage);
  }
  std::unique_ptr<tbb::global_control> limit;
  if (threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
  try {
    // No output may be an input (or another output): compared by device and inode.
    for (const std::string* out : {&hits_path, &shading_path}) {
      rtp::check_not_same_file(package, *out);
      rtp::check_not_same_file(rays_path, *out);
    }
    if (!make_rays.empty()) rtp::check_not_same_file(package, rays_path);  // the ray file is written then
    rtp::check_not_same_file(hits_path, shading_path);
    if (hits_path == shading_path || (!make_rays.empty() && rays_path == hits_path))
      throw rtp::Error(rtp::ExitCode::kUsage, "two outputs name the same file '" + hits_path + "'");
    rtp::check_output_path(hits_path);
    if (!shading_path.empty()) {
      if (any) throw rtp::Error(rtp::ExitCode::kUsage, "--shading needs closest hits: it cannot be used with --any");
      rtp::check_output_path(shading_path);
    }
    const rtp::PackageReader reader(package, direct);
    const auto tracer = rtp::load_package_in_core(reader);
    if (!make_rays.empty()) {
      int w = 0, h = 0;
      if (std::sscanf(make_rays.c_str(), "%dx%d", &w, &h) != 2 || w <= 0 || h <= 0 || int64_t(w) * h > (int64_t(1) << 28))
        throw rtp::Error(rtp::ExitCode::kUsage, "--make-camera-rays " + make_rays + ": expected WxH, e.g. 640x480");
      rtp::check_output_path(rays_path);
      const auto cr = camera_rays(reader, w, h);
      rtp::write_output_file(rays_path, cr.data(), cr.size() * sizeof(rtp::fmt::Ray));
    }
    const std::vector<rtp::fmt::Ray> rays = rtp::read_ray_file(rays_path);
    rtp::PackageTraceOptions opt;
    opt.cull = !no_cull;
    const rtp::Isa best = rtp::detect_isa();
    opt.isa = isa == "best" ? best : isa == "avx512" ? rtp::Isa::kAvx512 : isa == "avx2" ? rtp::Isa::kAvx2 : rtp::Isa::kScalar;
    if (int(opt.isa) > int(best))
      throw rtp::Error(rtp::ExitCode::kUsage, std::string("--isa ") + isa + ": this CPU supports up to " + rtp::isa_name(best));
    opt.order = order == "active" ? rtp::TraversalOrder::kActiveList : rtp::TraversalOrder::kOctantStack;
    std::vector<rtp::fmt::Hit> hits(any ? 0 : rays.size());
    std::vector<uint8_t> occ(any ? rays.size() : 0);
    std::atomic<uint64_t> invalid{0}, visits{0}, culled{0};
    const auto t0 = std::chrono::steady_clock::now();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
      const rtp::PackageTraceStats st = any ? tracer->any(rays.data() + r.begin(), occ.data() + r.begin(), r.size(), opt)
                                            : tracer->closest(rays.data() + r.begin(), hits.data() + r.begin(), r.size(), opt);
      invalid += st.invalid_rays;
      visits += st.point_visits;
      culled += st.culled_visits;
    });
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    uint64_t hit_count = 0;
    if (any) {
      for (uint8_t o : occ) hit_count += o;
      rtp::write_output_file(hits_path, occ.data(), occ.size());
    } else {
      for (const auto& h : hits) hit_count += h.t != std::numeric_limits<float>::infinity();
      if (!shading_path.empty()) {  // written first: the hit file appears only when everything succeeded
        const rtp::AttributeLookup lookup(reader);
        if (!lookup.has_normals() && !lookup.has_uvs())
          std::cerr << "warning: " << package << ": no attribute streams (convert with --attributes normal,uv); "
                    << "--shading writes zeros\n";
        std::vector<rtp::fmt::Shading> shading(hits.size());
        tbb::parallel_for(size_t(0), hits.size(), [&](size_t i) { shading[i] = lookup.shade(hits[i]); });
        rtp::write_output_file(shading_path, shading.data(), shading.size() * sizeof(rtp::fmt::Shading));
      }
      rtp::write_output_file(hits_path, hits.data(), hits.size() * sizeof(rtp::fmt::Hit));
    }
    nlohmann::json j = {{"rays", rays.size()}, {any ? "occluded" : "hits", hit_count},
                        {"misses", rays.size() - hit_count - invalid.load()}, {"invalid_rays", invalid.load()},
                        {"seconds", secs}, {"mrays_per_s", secs > 0 ? double(rays.size()) / secs / 1e6 : 0.0},
                        {"isa", rtp::isa_name(opt.isa)}, {"order", order}, {"direct_io", reader.direct_io()}};
    // Culling (Molenaar 2019 §3.2): how many batching-point visits the DAGs saved.
    const bool culling = opt.cull && tracer->has_dags();
    const double rate = visits.load() ? double(culled.load()) / double(visits.load()) : 0.0;
    j["culling"] = culling ? "on" : (tracer->has_dags() ? "off (--no-cull)" : "off (package has no DAGs)");
    j["batching_point_visits"] = visits.load();
    j["culled_visits"] = culled.load();
    j["cull_rate"] = rate;
    // Loading: every chunk read (and decompressed) and structurally checked before the first ray.
    const rtp::PackageLoadStats ls = tracer->load_stats();
    j["load_seconds"] = ls.total_seconds;
    j["load_read_seconds"] = ls.read_seconds;
    j["load_check_seconds"] = ls.check_seconds;
    j["chunks_loaded"] = ls.chunks;
    j["chunk_raw_bytes"] = ls.raw_bytes;
    if (json) std::cout << j.dump(2) << "\n";
    else {
      std::fprintf(stderr, "load: %llu chunks, %.1f MiB in %.3f s (read and decompress %.3f s, structural checks %.3f s)\n",
                   (unsigned long long)ls.chunks, double(ls.raw_bytes) / 1048576.0, ls.total_seconds, ls.read_seconds,
                   ls.check_seconds);
      std::fprintf(stderr,
                   "%zu rays: %llu %s, %llu invalid (returned as misses); %.3f s, %.2f Mrays/s (%s, %s); "
                   "batching-point visits %llu, culled %llu (%.1f%%, culling %s)\n",
                   rays.size(), (unsigned long long)hit_count, any ? "occluded" : "hits",
                   (unsigned long long)invalid.load(), secs, j["mrays_per_s"].get<double>(), rtp::isa_name(opt.isa), order.c_str(),
                   (unsigned long long)visits.load(), (unsigned long long)culled.load(), 100 * rate,
                   j["culling"].get<std::string>().c_str());
    }
  } catch (const rtp::Error& e) {
    std::cerr << "error: " << package << ": " << e.what() << "\n";
    return int(e.code());
  } catch (const std::exception& e) {
    std::cerr << "error: " << package << ": internal error: " << e.what() << "\n";
    return int(rtp::ExitCode::kInternal);
  }
  return 0;
}
