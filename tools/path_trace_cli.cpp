// rtpack-trace --path-trace (path_trace_cli.h).
#include "path_trace_cli.h"

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include "core/error.h"
#include "core/input_file.h"
#include "core/output_file.h"
#include "core/progress.h"
#include "image/image.h"
#include "path_trace.h"
#include "stream_stats_json.h"
#include "reader/reader.h"
#include "trace/tracer.h"

namespace rtp::tools {
namespace {

void print_row(const char* name, const rtpack::StreamStats& s) {
  std::fprintf(stderr, "%8s %12llu %12llu %12llu %8llu %10.1f %8.3f\n", name, (unsigned long long)s.rays,
               (unsigned long long)s.batching_point_visits, (unsigned long long)s.culled_visits,
               (unsigned long long)s.chunks_loaded, double(s.bytes_read) / 1048576.0, s.seconds);
}

int render(const PathTraceCommand& c);

}  // namespace

// The public API's errors as the tools report them (its message starts with the package path, which
// the tools' report adds again).
int run_path_trace(const PathTraceCommand& c) {
  try {
    return render(c);
  } catch (const rtpack::Error& e) {
    std::string m = e.what();
    if (m.rfind(c.package + ": ", 0) == 0) m = m.substr(c.package.size() + 2);
    throw Error(ExitCode(e.code()), m);
  }
}

namespace {

int render(const PathTraceCommand& c) {
  check_output_path(c.image);
  check_not_same_file(c.package, c.image);
  rtpack::OpenOptions oo;
  oo.direct_io = c.direct;
  uint64_t geometry = 0;
  {
    const PackageReader reader(c.package);
    geometry = on_demand_bytes(reader);
    if (!c.budget_text.empty()) oo.memory_budget = parse_memory_budget(c.budget_text, geometry);
  }
  const rtpack::Package pkg = rtpack::Package::open(c.package, oo);
  pathtracer::PathTraceOptions o;
  o.width = c.width, o.height = c.height, o.camera = c.camera;
  o.spp = c.spp, o.bounces = c.bounces, o.paths_in_flight = c.paths_in_flight, o.seed = c.seed, o.refill = c.refill;
  o.stream.cull = !c.no_cull;
  o.stream.threads = c.threads;
  o.stream.isa = c.isa == "avx512"   ? rtpack::Isa::kAvx512
                 : c.isa == "avx2"   ? rtpack::Isa::kAvx2
                 : c.isa == "scalar" ? rtpack::Isa::kScalar
                                     : rtpack::Isa::kBest;
  o.progress = !c.json && (isatty(2) || std::getenv("RTP_PROGRESS"));
  const pathtracer::PathTraceResult r = pathtracer::path_trace(pkg, o);
  image::Rgb8 img;
  img.width = c.width, img.height = c.height, img.rgb = r.rgb;
  const std::vector<uint8_t> bytes = image::encode_for_path(img, c.image);  // PNG, or PPM for a .ppm name
  write_output_file(c.image, bytes.data(), bytes.size());
  if (c.json) {
    nlohmann::json waves = nlohmann::json::array();
    for (const rtpack::StreamStats& s : r.waves) waves.push_back(rtp::tools::stream_stats_json(s));
    nlohmann::json j = {{"image", c.image},
                        {"width", c.width},
                        {"height", c.height},
                        {"spp", c.spp},
                        {"bounces", c.bounces},
                        {"paths", r.paths},
                        {"paths_in_flight", c.paths_in_flight},
                        {"refill", c.refill},
                        {"seed", c.seed},
                        {"out_of_core", pkg.out_of_core()},
                        {"culling", !c.no_cull},
                        {"budget_bytes", oo.memory_budget},
                        {"geometry_bytes", geometry},
                        {"direct_io", c.direct},
                        {"seconds", r.seconds},
                        {"peak_rss_mib", peak_rss_mib()},
                        {"waves", waves},
                        {"total", rtp::tools::stream_stats_json(r.total)}};
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  std::fprintf(stderr, "%8s %12s %12s %12s %8s %10s %8s\n", "wave", "rays", "visits", "culled", "chunks", "MiB read", "s");
  for (size_t w = 0; w < r.waves.size(); ++w) print_row(std::to_string(w + 1).c_str(), r.waves[w]);
  print_row("total", r.total);
  std::fprintf(stderr,
               "image: %s, %dx%d, %u spp, %u bounces, %llu paths (%u in flight); %s%s, culling %s; %.3f s, peak RSS %.0f MiB\n",
               c.image.c_str(), c.width, c.height, c.spp, c.bounces, (unsigned long long)r.paths, c.paths_in_flight,
               pkg.out_of_core() ? "out of core, budget " : "in core",
               pkg.out_of_core() ? human_bytes(double(oo.memory_budget)).c_str() : "", c.no_cull ? "off" : "on", r.seconds,
               peak_rss_mib());
  return 0;
}

}  // namespace
}  // namespace rtp::tools
