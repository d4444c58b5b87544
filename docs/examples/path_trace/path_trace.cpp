// The path tracer of path_trace.h (render_paths.cpp, rtpack-trace --path-trace).
#include "path_trace.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <utility>

namespace pathtracer {
namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kInf = INFINITY;

// SplitMix64 (Steele 2014): a path's random numbers from (seed, path, bounce, dimension), no state.
uint64_t mix(uint64_t z) {
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
float uniform(uint64_t seed, uint64_t path, uint32_t bounce, uint32_t dim) {
  const uint64_t h = mix(mix(mix(seed) ^ path) ^ (uint64_t(bounce) << 8 | dim));
  return float(h >> 40) * (1.0f / 16777216.0f);  // [0, 1)
}

struct V3 {
  float x, y, z;
};
V3 add(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
V3 scale(V3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
V3 mul(V3 a, V3 b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
float dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
V3 normalized(V3 a) { return scale(a, 1.0f / std::sqrt(dot(a, a))); }

const V3 kSun = normalized({0.45f, 0.8f, 0.35f});
constexpr float kSunIrradiance = 2.5f;

// Sky radiance along d: white at the horizon to blue above, dim below.
V3 sky(V3 d) {
  const float t = 0.5f * (std::clamp(d.y, -1.0f, 1.0f) + 1.0f);
  return add(scale({1.0f, 1.0f, 1.0f}, 0.9f * (1 - t)), scale({0.45f, 0.65f, 1.0f}, 0.9f * t));
}

// A Lambert albedo per scene instance, in [0.35, 0.8].
V3 albedo(uint32_t instance) {
  const uint64_t h = mix(instance);
  return {0.35f + 0.45f * float(h & 0xFF) / 255.f, 0.35f + 0.45f * float((h >> 8) & 0xFF) / 255.f,
          0.35f + 0.45f * float((h >> 16) & 0xFF) / 255.f};
}

// A path in flight: its throughput, and what each of its rays contributes, by slot (2d: the bounce-d
// ray's sky term when it misses; 2d + 1: its shadow ray's sun term when unoccluded), summed in slot
// order when the path ends, so that arrival order never changes a bit.
struct Path {
  uint64_t id = 0;  // global path index: pixel = id % pixels, sample = id / pixels
  V3 throughput{1, 1, 1};
  uint32_t outstanding = 0;
  std::vector<V3> slot;      // contributions
  std::vector<V3> sun;       // the sun term each shadow ray carries until answered (odd slots)
  std::vector<V3> org, dir;  // each bounce ray's origin and direction (by depth)
};

// The payload of a ray: the path's index in its wave and the slot.
uint64_t payload(uint32_t local, uint32_t slot) { return uint64_t(local) << 8 | slot; }

}  // namespace

PathTraceResult path_trace(const rtpack::Package& pkg, const PathTraceOptions& o) {
  struct Stream final : RayTracer {
    rtpack::RayStream s;
    explicit Stream(rtpack::RayStream&& stream) : s(std::move(stream)) {}
    void submit(const rtpack::StreamRay* rays, size_t count) override { s.submit(rays, count); }
    rtpack::StreamStats flush(const std::function<void(const rtpack::StreamHit*, size_t)>& on_hits) override {
      return s.flush(on_hits);
    }
  };
  rtpack::StreamOptions so = o.stream;
  so.max_in_flight = std::max<uint32_t>(1024, 2 * o.paths_in_flight);
  Stream stream(pkg.stream(so));
  return path_trace(stream, pkg.camera_rays(o.width, o.height, o.camera), pkg.info().bounds, o);
}

PathTraceResult path_trace(RayTracer& stream, const std::vector<rtpack::Ray>& camera, const rtpack::Bounds& b,
                           const PathTraceOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  const size_t pixels = size_t(o.width) * size_t(o.height);
  if (camera.size() != pixels) throw std::invalid_argument("path_trace: the camera has not width x height rays");
  const float diag = std::sqrt((b.hi[0] - b.lo[0]) * (b.hi[0] - b.lo[0]) + (b.hi[1] - b.lo[1]) * (b.hi[1] - b.lo[1]) +
                               (b.hi[2] - b.lo[2]) * (b.hi[2] - b.lo[2]));
  const uint32_t slots = 2 * (o.bounces + 1);
  const uint64_t total_paths = uint64_t(pixels) * o.spp;
  std::vector<float> radiance(size_t(total_paths) * 3);
  PathTraceResult res;
  res.paths = total_paths;
  std::vector<Path> paths(o.paths_in_flight);
  for (Path& p : paths) p.slot.resize(slots), p.sun.resize(slots), p.org.resize(o.bounces + 1), p.dir.resize(o.bounces + 1);
  std::vector<rtpack::StreamRay> batch;
  // Paths start in slot order: a wave's first `paths_in_flight`, or with `refill` the next path whenever
  // one ends (its slot reused; the render one flush).
  uint64_t next = 0, done = 0;
  auto start = [&](uint32_t k) {
    Path& p = paths[k];
    p.id = next++;
    p.throughput = {1, 1, 1};
    p.outstanding = 1;
    std::fill(p.slot.begin(), p.slot.end(), V3{0, 0, 0});
    const rtpack::Ray& r = camera[p.id % pixels];
    p.org[0] = {r.org[0], r.org[1], r.org[2]};
    p.dir[0] = {r.dir[0], r.dir[1], r.dir[2]};
    batch.push_back({r, payload(k, 0), 0, 0});
  };
  auto finish = [&](uint32_t k) {
    const Path& p = paths[k];
    V3 sum{0, 0, 0};
    for (const V3& c : p.slot) sum = add(sum, c);
    float* out = &radiance[size_t(p.id % pixels * o.spp + p.id / pixels) * 3];
    out[0] = sum.x, out[1] = sum.y, out[2] = sum.z;
    ++done;
    if (o.progress && o.refill && done * 10 / total_paths != (done - 1) * 10 / total_paths)
      std::fprintf(stderr, "path-trace: %llu of %llu paths done\n", (unsigned long long)done, (unsigned long long)total_paths);
    if (o.refill && next < total_paths) start(k);
  };
  const uint64_t n_waves = o.refill ? 1 : (total_paths + o.paths_in_flight - 1) / o.paths_in_flight;
  for (uint64_t w = 0; w < n_waves; ++w) {
    batch.clear();
    for (uint32_t k = 0; k < o.paths_in_flight && next < total_paths; ++k) start(k);
    stream.submit(batch.data(), batch.size());
    const rtpack::StreamStats st = stream.flush([&](const rtpack::StreamHit* hits, size_t n) {
      batch.clear();
      for (size_t j = 0; j < n; ++j) {
        const rtpack::StreamHit& h = hits[j];
        const uint32_t local = uint32_t(h.payload >> 8), s = uint32_t(h.payload & 0xFF), depth = s / 2;
        Path& p = paths[local];
        if (s & 1u) {  // a shadow ray
          if (!h.occluded) p.slot[s] = p.sun[s];
        } else if (!(h.hit.t < kInf)) {  // a bounce that left the scene
          p.slot[s] = mul(p.throughput, sky(normalized(p.dir[depth])));
        } else {
          // The hit point, its normal facing the ray, the next rays off the surface.
          const V3 dir = p.dir[depth], org = p.org[depth];
          V3 n{h.normal[0], h.normal[1], h.normal[2]};
          if (!(dot(n, n) > 0)) {  // a degenerate triangle: the path ends here
            if (--p.outstanding == 0) finish(local);
            continue;
          }
          if (dot(n, dir) > 0) n = scale(n, -1);
          const V3 x = add(org, scale(dir, h.hit.t));
          const float eps = 1e-4f * std::max({std::fabs(x.x), std::fabs(x.y), std::fabs(x.z), 1e-2f * diag});
          const V3 off = add(x, scale(n, eps));
          const V3 a = albedo(h.hit.instance);
          if (const float c = dot(n, kSun); c > 0) {
            p.sun[s + 1] = mul(p.throughput, scale(a, c * kSunIrradiance / kPi));
            batch.push_back({{{off.x, off.y, off.z}, 0, {kSun.x, kSun.y, kSun.z}, kInf}, payload(local, s + 1), 1, 0});
            ++p.outstanding;
          }
          if (depth < o.bounces) {
            // Cosine-weighted direction about n (Malley's method): the Lambert BRDF's cos / pi cancels.
            const float u1 = uniform(o.seed, p.id, depth, 0), u2 = uniform(o.seed, p.id, depth, 1);
            const float r = std::sqrt(u1), phi = 2 * kPi * u2;
            const V3 t = std::fabs(n.x) > 0.9f ? normalized({n.z, 0, -n.x}) : normalized({0, -n.z, n.y});
            const V3 bt{n.y * t.z - n.z * t.y, n.z * t.x - n.x * t.z, n.x * t.y - n.y * t.x};
            const V3 d = normalized(
                add(add(scale(t, r * std::cos(phi)), scale(bt, r * std::sin(phi))), scale(n, std::sqrt(std::max(0.0f, 1 - u1)))));
            p.throughput = mul(p.throughput, a);
            p.org[depth + 1] = off, p.dir[depth + 1] = d;
            batch.push_back({{{off.x, off.y, off.z}, 0, {d.x, d.y, d.z}, kInf}, payload(local, s + 2), 0, 0});
            ++p.outstanding;
          }
        }
        if (--p.outstanding == 0) finish(local);
      }
      stream.submit(batch.data(), batch.size());
    });
    res.waves.push_back(st);
    if (o.progress)
      std::fprintf(stderr, "path-trace: wave %llu/%llu, %llu rays, %llu chunks loaded, %.2f s\n", (unsigned long long)w + 1,
                   (unsigned long long)n_waves, (unsigned long long)st.rays, (unsigned long long)st.chunks_loaded, st.seconds);
  }
  // Pixels: the mean of their samples in sample order, clamped, gamma 2.2.
  res.rgb.resize(pixels * 3);
  for (size_t px = 0; px < pixels; ++px)
    for (int c = 0; c < 3; ++c) {
      float sum = 0;
      for (uint32_t s = 0; s < o.spp; ++s) sum += radiance[(px * o.spp + s) * 3 + size_t(c)];
      const float v = std::pow(std::clamp(sum / float(o.spp), 0.0f, 1.0f), 1.0f / 2.2f);
      res.rgb[px * 3 + size_t(c)] = uint8_t(std::lround(v * 255.0f));
    }
  for (const rtpack::StreamStats& st : res.waves) {
    rtpack::StreamStats& t = res.total;
    t.rays += st.rays, t.rounds += st.rounds, t.passes += st.passes, t.batching_point_visits += st.batching_point_visits;
    t.culled_visits += st.culled_visits, t.dag_tests += st.dag_tests, t.chunks_loaded += st.chunks_loaded;
    t.bytes_read += st.bytes_read, t.raw_bytes_loaded += st.raw_bytes_loaded, t.budget_bytes = st.budget_bytes;
    t.peak_resident_bytes = std::max(t.peak_resident_bytes, st.peak_resident_bytes);
    t.seconds += st.seconds, t.load_seconds += st.load_seconds, t.trace_seconds += st.trace_seconds;
    t.walk_seconds += st.walk_seconds;
  }
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace pathtracer
