// rtpack-validate --kinds path: the path workload of validate_paths.h.
#include "validate_paths.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "reader/camera.h"
#include "trace/ray_stream.h"

namespace rtp::tools {
namespace {

uint64_t mix(uint64_t z) {  // SplitMix64 (Steele 2014): a bounce's random numbers, no state
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
double unit(uint64_t seed, uint64_t path, uint32_t depth, uint32_t dim) {
  return double(mix(mix(seed ^ mix(path)) + (uint64_t(depth) << 4 | dim)) >> 11) * 0x1.0p-53;
}

// A ray's payload: its path and slot (2 depth: the bounce-depth closest ray, 2 depth + 1: its shadow ray).
uint64_t payload(uint64_t path, uint32_t slot) { return path << 8 | slot; }

struct Recorded {
  fmt::Ray ray;
  bool any = false;
  bool answered = false;
  fmt::Hit hit{};
  uint8_t occluded = 0;
};

}  // namespace

void accumulate(TracerStats& total, const TracerStats& s) {
  total.rays += s.rays;
  total.point_visits += s.point_visits;
  total.culled_visits += s.culled_visits;
  total.rounds += s.rounds;
  total.cache.loads += s.cache.loads;
  total.cache.requests += s.cache.requests;
  total.cache.hits += s.cache.hits;
  total.cache.bytes_read += s.cache.bytes_read;
  total.cache.peak_resident_bytes = std::max(total.cache.peak_resident_bytes, s.cache.peak_resident_bytes);
  total.peak_resident_bytes = std::max(total.peak_resident_bytes, s.peak_resident_bytes);
  total.total_seconds += s.total_seconds;
}

PathWorkload trace_path_workload(const PackageReader& reader, OutOfCoreTracer& tracer, const PathWorkloadOptions& o) {
  const size_t n = std::max<size_t>(1, o.paths);
  const int w = std::max(1, int(std::ceil(std::sqrt(double(n) * 1.5)))), h = std::max(1, int((n + size_t(w) - 1) / size_t(w)));
  std::vector<fmt::Ray> camera = camera_rays(reader, w, h).rays;
  camera.resize(std::min(camera.size(), n));
  const auto& hd = reader.header();
  double diag = 0;
  for (int k = 0; k < 3; ++k) diag += std::pow(double(hd.bounds_hi[k]) - double(hd.bounds_lo[k]), 2);
  diag = std::sqrt(diag);
  const double sun[3] = {0.45 / 1.0062, 0.8 / 1.0062, 0.35 / 1.0062};  // unit length

  StreamOptions so;
  so.trace = o.trace;
  so.max_in_flight = 4096;
  const std::unique_ptr<RayStream> stream = tracer.open_stream(so);
  std::map<uint64_t, Recorded> rec;  // by payload: the report's order is (path, depth), not arrival
  std::vector<StreamRay> batch;
  auto submit = [&](uint64_t path, uint32_t slot, const fmt::Ray& r, bool any) {
    rec[payload(path, slot)] = Recorded{r, any};
    batch.push_back({r, payload(path, slot), any ? 1u : 0u, 0});
  };
  PathWorkload out;
  out.paths = camera.size();
  const uint32_t waves = std::max<uint32_t>(1, std::min<uint32_t>(o.waves, uint32_t(camera.size())));
  const size_t per_wave = (camera.size() + waves - 1) / waves;
  for (size_t first = 0; first < camera.size(); first += per_wave) {
    batch.clear();
    for (size_t p = first; p < std::min(camera.size(), first + per_wave); ++p) submit(p, 0, camera[p], false);
    stream->submit(batch.data(), batch.size());
    const TracerStats st = stream->flush([&](const StreamResult* res, size_t count) {
      batch.clear();
      for (size_t j = 0; j < count; ++j) {
        const StreamResult& r = res[j];
        Recorded& ray = rec.at(r.payload);
        ray.answered = true;
        ray.hit = r.hit, ray.occluded = uint8_t(r.occluded);
        const uint64_t path = r.payload >> 8;
        const uint32_t slot = uint32_t(r.payload & 0xFF), depth = slot / 2;
        if (ray.any || !(r.hit.t < INFINITY)) continue;
        double nn[3] = {r.normal[0], r.normal[1], r.normal[2]};
        if (!(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2] > 0)) continue;  // a degenerate triangle
        const fmt::Ray& in = ray.ray;
        if (nn[0] * in.dir[0] + nn[1] * in.dir[1] + nn[2] * in.dir[2] > 0)
          for (double& c : nn) c = -c;
        double x[3], m = 1e-2 * diag;
        for (int k = 0; k < 3; ++k)
          x[k] = double(in.org[k]) + double(r.hit.t) * double(in.dir[k]), m = std::max(m, std::fabs(x[k]));
        fmt::Ray s{};
        for (int k = 0; k < 3; ++k) s.org[k] = float(x[k] + 1e-4 * m * nn[k]), s.dir[k] = float(sun[k]);
        s.tnear = 0, s.tfar = INFINITY;
        submit(path, slot + 1, s, true);
        if (depth >= o.bounces) continue;
        // A cosine-weighted direction about the normal (Malley's method).
        const double u1 = unit(o.seed, path, depth, 0), u2 = unit(o.seed, path, depth, 1);
        const double rr = std::sqrt(u1), phi = 2 * M_PI * u2, up = std::sqrt(std::max(0.0, 1 - u1));
        double t[3] = {0, -nn[2], nn[1]};
        if (std::fabs(nn[0]) > 0.9) t[0] = nn[2], t[1] = 0, t[2] = -nn[0];
        const double tl = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
        for (double& c : t) c /= tl;
        const double b[3] = {nn[1] * t[2] - nn[2] * t[1], nn[2] * t[0] - nn[0] * t[2], nn[0] * t[1] - nn[1] * t[0]};
        fmt::Ray d = s;
        for (int k = 0; k < 3; ++k) d.dir[k] = float(rr * std::cos(phi) * t[k] + rr * std::sin(phi) * b[k] + up * nn[k]);
        submit(path, slot + 2, d, false);
      }
      stream->submit(batch.data(), batch.size());
    });
    ++out.waves;
    accumulate(out.stats, st);
  }
  for (const auto& [key, r] : rec) {
    if (!r.answered) throw Error(ExitCode::kInternal, "the ray stream did not answer ray " + std::to_string(key));
    if (r.any) {
      out.shadow_rays.push_back(r.ray), out.occluded.push_back(r.occluded);
    } else {
      out.closest_rays.push_back(r.ray), out.closest_hits.push_back(r.hit);
    }
  }
  return out;
}

}  // namespace rtp::tools
