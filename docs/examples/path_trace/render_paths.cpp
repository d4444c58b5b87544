// render_paths PACKAGE IMAGE.ppm [WxH] [BUDGET] [PATHS_IN_FLIGHT]: an out-of-core renderer on rtpack's
// reader library. Opens the package under a geometry budget (bytes, or a percentage of its geometry;
// default 10%), path-traces its camera's view with path_trace.h (1 sample, 2 bounces, a sun and a sky)
// through a RayStream, and writes a binary PPM. The pixels are the same for every budget and in core:
// rtpack-trace --path-trace writes the same bytes (tests/install/consumer_test.cmake compares them).
#include <rtpack/rtpack.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>

#include "path_trace.h"

int main(int argc, char** argv) {
  if (argc < 3 || argc > 6) {
    std::fprintf(stderr, "usage: render_paths PACKAGE IMAGE.ppm [WxH] [BUDGET: bytes or N%%] [PATHS_IN_FLIGHT]\n");
    return 1;
  }
  pathtracer::PathTraceOptions o;
  o.width = o.height = 256;
  if (argc > 3 && std::sscanf(argv[3], "%dx%d", &o.width, &o.height) != 2) {
    std::fprintf(stderr, "render_paths: '%s' is not a size WxH\n", argv[3]);
    return 1;
  }
  rtpack::OpenOptions open;
  const std::string budget = argc > 4 ? argv[4] : "10%";
  char* end = nullptr;
  const double value = std::strtod(budget.c_str(), &end);
  if (end == budget.c_str() || !(value > 0) || (*end && std::string(end) != "%")) {
    std::fprintf(stderr, "render_paths: '%s' is not a budget (bytes, or a percentage such as 10%%)\n", budget.c_str());
    return 1;
  }
  if (*end == '%')
    open.memory_fraction = value / 100;  // raised to the package's minimum when below it
  else
    open.memory_budget = uint64_t(value);
  if (argc > 5) o.paths_in_flight = uint32_t(std::strtoul(argv[5], nullptr, 10));
  try {
    const rtpack::Package pkg = rtpack::Package::open(argv[1], open);
    std::printf("%s: %s, %.1f MiB of geometry, minimum budget %.1f MiB\n", argv[1], pkg.out_of_core() ? "out of core" : "in core",
                double(pkg.geometry_bytes()) / 1048576.0, double(pkg.minimum_budget()) / 1048576.0);
    const pathtracer::PathTraceResult r = pathtracer::path_trace(pkg, o);
    std::printf(
        "%llu paths, %llu rays in %zu waves: %llu batching-point visits (%llu culled), %llu chunks loaded, "
        "%.1f MiB read, peak resident %.1f MiB, %.2f s\n",
        (unsigned long long)r.paths, (unsigned long long)r.total.rays, r.waves.size(),
        (unsigned long long)r.total.batching_point_visits, (unsigned long long)r.total.culled_visits,
        (unsigned long long)r.total.chunks_loaded, double(r.total.bytes_read) / 1048576.0,
        double(r.total.peak_resident_bytes) / 1048576.0, r.seconds);
    std::ofstream out(argv[2], std::ios::binary | std::ios::trunc);
    out << "P6\n" << o.width << " " << o.height << "\n255\n";
    out.write(reinterpret_cast<const char*>(r.rgb.data()), std::streamsize(r.rgb.size()));
    if (!out) {
      std::fprintf(stderr, "%s: cannot write\n", argv[2]);
      return 4;
    }
  } catch (const rtpack::Error& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return e.code();
  }
  return 0;
}
