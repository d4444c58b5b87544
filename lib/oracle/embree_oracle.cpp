#include "core/math.h"
#include "oracle/embree_oracle.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <string>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "layout/hit_order.h"

namespace rtp {
namespace {

constexpr size_t kGrain = 256;  // rays per TBB task
constexpr size_t kBatch = 64;   // rays per rtcIntersect1M call (stack buffer)

struct ErrorSink {
  std::mutex mutex;
  std::string first;
};

void on_embree_error(void* user, RTCError code, const char* message) {
  auto* sink = static_cast<ErrorSink*>(user);
  std::lock_guard<std::mutex> lock(sink->mutex);
  if (sink->first.empty())
    sink->first = "Embree error " + std::to_string(int(code)) + ": " + (message ? message : "(no message)");
}

RTCBuildQuality to_rtc(OracleQuality q) {
  switch (q) {
    case OracleQuality::kLow: return RTC_BUILD_QUALITY_LOW;
    case OracleQuality::kMedium: return RTC_BUILD_QUALITY_MEDIUM;
    case OracleQuality::kHigh: return RTC_BUILD_QUALITY_HIGH;
  }
  return RTC_BUILD_QUALITY_HIGH;
}

bool finite_and_small(float x) { return std::abs(x) <= kEmbreeMaxMagnitude; }  // false for NaN/Inf

void set_miss(fmt::Hit& h) {
  h.t = kInf;
  h.instance = fmt::Hit::kNone;
  h.prim = fmt::Hit::kNone;
  h.u = 0;
  h.v = 0;
}

void load_ray(const fmt::Ray& r, RTCRay& e) {
  e.org_x = r.org[0];
  e.org_y = r.org[1];
  e.org_z = r.org[2];
  e.tnear = r.tnear;
  e.dir_x = r.dir[0];
  e.dir_y = r.dir[1];
  e.dir_z = r.dir[2];
  e.time = 0;
  e.tfar = r.tfar;
  e.mask = 0xFFFFFFFFu;
  e.id = 0;
  e.flags = 0;
}

}  // namespace

RayStatus ray_status(const fmt::Ray& r) {
  bool finite = true;
  for (int i = 0; i < 3; ++i) finite = finite && std::isfinite(r.org[i]) && std::isfinite(r.dir[i]);
  // NaN compares false: !(tnear <= tfar) covers NaN tnear/tfar and tnear > tfar.
  if (!finite || !(r.tnear <= r.tfar) || r.tnear == kInf) return RayStatus::kInvalid;
  for (int i = 0; i < 3; ++i)
    if (!finite_and_small(r.org[i]) || !finite_and_small(r.dir[i])) return RayStatus::kUnsupported;
  if (r.tnear < 0) return RayStatus::kUnsupported;
  return RayStatus::kValid;
}

const char* quality_name(OracleQuality q) {
  switch (q) {
    case OracleQuality::kLow: return "low";
    case OracleQuality::kMedium: return "medium";
    case OracleQuality::kHigh: return "high";
  }
  return "?";
}

struct EmbreeOracle::Impl {
  ErrorSink errors;
  RTCDevice device = nullptr;
  RTCScene top = nullptr;
  std::vector<RTCScene> mesh_scenes;  // per rtp mesh (nullptr for meshes without triangles)

  void check(const char* what) {
    const RTCError code = rtcGetDeviceError(device);
    std::lock_guard<std::mutex> lock(errors.mutex);
    if (code != RTC_ERROR_NONE || !errors.first.empty())
      throw Error(ExitCode::kInternal, std::string("Embree oracle: ") + what + ": " +
                                           (errors.first.empty() ? "error " + std::to_string(int(code)) : errors.first));
  }

  ~Impl() {
    if (top) rtcReleaseScene(top);
    for (RTCScene s : mesh_scenes)
      if (s) rtcReleaseScene(s);
    if (device) rtcReleaseDevice(device);
  }
};

EmbreeOracle::EmbreeOracle(const Scene& scene, OracleQuality quality, bool gather_filter)
    : quality_(quality), gather_filter_(gather_filter) {
  const auto start = std::chrono::steady_clock::now();
  impl_ = new Impl;
  try {
    Impl& im = *impl_;
    im.device = rtcNewDevice("verbose=0");
    if (!im.device) throw Error(ExitCode::kInternal, "Embree oracle: rtcNewDevice failed");
    rtcSetDeviceErrorFunction(im.device, on_embree_error, &im.errors);
    const RTCBuildQuality q = to_rtc(quality);
    const auto flags = RTCSceneFlags(RTC_SCENE_FLAG_ROBUST | (gather_filter ? RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION : 0));

    im.mesh_scenes.assign(scene.meshes.size(), nullptr);
    for (size_t m = 0; m < scene.meshes.size(); ++m) {
      const Mesh& mesh = scene.meshes[m];
      const size_t tris = mesh.indices.size() / 3;
      if (tris == 0 || mesh.positions.empty()) continue;
      RTCGeometry g = rtcNewGeometry(im.device, RTC_GEOMETRY_TYPE_TRIANGLE);
      // Embree allocates these with the padding its SSE loads need (a shared std::vector would not).
      auto* v = static_cast<float*>(
          rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.positions.size()));
      auto* ix = static_cast<uint32_t*>(
          rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), tris));
      im.check("allocating geometry buffers");
      for (size_t i = 0; i < mesh.positions.size(); ++i) {
        v[3 * i + 0] = mesh.positions[i].x;
        v[3 * i + 1] = mesh.positions[i].y;
        v[3 * i + 2] = mesh.positions[i].z;
      }
      std::memcpy(ix, mesh.indices.data(), tris * 3 * sizeof(uint32_t));
      rtcSetGeometryBuildQuality(g, q);
      rtcCommitGeometry(g);
      RTCScene s = rtcNewScene(im.device);
      rtcSetSceneFlags(s, flags);
      rtcSetSceneBuildQuality(s, q);
      rtcAttachGeometryByID(s, g, 0);
      rtcReleaseGeometry(g);
      rtcCommitScene(s);
      im.mesh_scenes[m] = s;
      im.check("building a mesh scene");
    }

    im.top = rtcNewScene(im.device);
    rtcSetSceneFlags(im.top, flags);
    rtcSetSceneBuildQuality(im.top, q);
    for (size_t i = 0; i < scene.instances.size(); ++i) {
      const Instance& inst = scene.instances[i];
      if (inst.mesh >= im.mesh_scenes.size() || !im.mesh_scenes[inst.mesh]) continue;
      RTCGeometry g = rtcNewGeometry(im.device, RTC_GEOMETRY_TYPE_INSTANCE);
      rtcSetGeometryInstancedScene(g, im.mesh_scenes[inst.mesh]);
      rtcSetGeometryTimeStepCount(g, 1);
      // Embree takes float matrices: far from the origin its answer moves by the rounding of the
      // translation (TESTING.md: where rtpack and Embree disagree there, the double reference decides).
      const std::array<float, 12> m = inst.transform.to_float();
      rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, m.data());
      rtcCommitGeometry(g);
      rtcAttachGeometryByID(im.top, g, static_cast<unsigned>(i));
      rtcReleaseGeometry(g);
      ++geometries_;
    }
    im.check("attaching instances");
    rtcCommitScene(im.top);
    im.check("building the instance scene");
  } catch (...) {
    delete impl_;
    impl_ = nullptr;
    throw;
  }
  build_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

EmbreeOracle::~EmbreeOracle() { delete impl_; }

namespace {

RTCIntersectContextFlags context_flags(RayCoherence coherence) {
  return coherence == RayCoherence::kCoherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
}

// The block loop of both queries: per TBB task, blocks of kBatch rays; the valid ones are packed into a
// stack buffer of Embree rays (slot[] remembers where each came from), traced in one call, unpacked.
// Invalid and unsupported rays are counted and answered by skip(i).
template <class EmbreeRay, class Skip, class Load, class Trace, class Store>
OracleStats in_batches(const fmt::Ray* rays, size_t n, RayCoherence coherence, Skip skip, Load load, Trace trace, Store store) {
  std::atomic<uint64_t> invalid{0}, unsupported{0};
  const RTCIntersectContextFlags cflags = context_flags(coherence);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kGrain), [&](const tbb::blocked_range<size_t>& range) {
    alignas(64) EmbreeRay buf[kBatch];
    uint32_t slot[kBatch];
    uint64_t bad = 0, unsup = 0;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = cflags;
    for (size_t b = range.begin(); b < range.end(); b += kBatch) {
      const size_t e = std::min(range.end(), b + kBatch);
      unsigned m = 0;
      for (size_t i = b; i < e; ++i) {
        const RayStatus st = ray_status(rays[i]);
        if (st != RayStatus::kValid) {
          (st == RayStatus::kInvalid ? bad : unsup) += 1;
          skip(i);
          continue;
        }
        load(rays[i], buf[m]);
        slot[m++] = uint32_t(i - b);
      }
      if (m > 0) trace(&ctx, buf, m);
      for (unsigned k = 0; k < m; ++k) store(b + slot[k], buf[k]);
    }
    if (bad) invalid.fetch_add(bad, std::memory_order_relaxed);
    if (unsup) unsupported.fetch_add(unsup, std::memory_order_relaxed);
  });
  return {n, invalid.load(), unsupported.load()};
}

// Packets of 16 neighbouring valid rays (Embree's packet traversal; ray order decides coherence), loaded
// straight from fmt::Ray into Embree's SoA layout and answered straight into the hits.
class Packet16 {
 public:
  explicit Packet16(RTCIntersectContext* ctx) : ctx_(ctx) {}
  bool add(const fmt::Ray& r, size_t index) {
    const unsigned j = m_;
    pk_.ray.org_x[j] = r.org[0];
    pk_.ray.org_y[j] = r.org[1];
    pk_.ray.org_z[j] = r.org[2];
    pk_.ray.tnear[j] = r.tnear;
    pk_.ray.dir_x[j] = r.dir[0];
    pk_.ray.dir_y[j] = r.dir[1];
    pk_.ray.dir_z[j] = r.dir[2];
    pk_.ray.time[j] = 0;
    pk_.ray.tfar[j] = r.tfar;
    pk_.ray.mask[j] = 0xFFFFFFFFu;
    pk_.ray.id[j] = 0;
    pk_.ray.flags[j] = 0;
    pk_.hit.geomID[j] = RTC_INVALID_GEOMETRY_ID;
    pk_.hit.primID[j] = RTC_INVALID_GEOMETRY_ID;
    pk_.hit.instID[0][j] = RTC_INVALID_GEOMETRY_ID;
    index_[j] = index;
    return ++m_ == 16;
  }
  void trace(RTCScene top, fmt::Hit* hits) {
    if (m_ == 0) return;
    alignas(64) int valid[16];
    for (unsigned j = 0; j < 16; ++j) valid[j] = j < m_ ? -1 : 0;
    // Inactive lanes carry a copy of the packet's first ray: Embree's AVX-512 rtcOccluded16 was seen to
    // spin forever on zeroed inactive lanes (zero direction).
    for (unsigned j = m_; j < 16; ++j) copy_lane(0, j);
    rtcIntersect16(valid, top, ctx_, &pk_);
    for (unsigned j = 0; j < m_; ++j) {
      fmt::Hit& h = hits[index_[j]];
      if (pk_.hit.geomID[j] == RTC_INVALID_GEOMETRY_ID) {
        set_miss(h);
      } else {
        h.t = pk_.ray.tfar[j];
        h.instance = pk_.hit.instID[0][j];
        h.prim = pk_.hit.primID[j];
        h.u = pk_.hit.u[j];
        h.v = pk_.hit.v[j];
      }
    }
    m_ = 0;
  }

 private:
  void copy_lane(unsigned from, unsigned to) {
    pk_.ray.org_x[to] = pk_.ray.org_x[from];
    pk_.ray.org_y[to] = pk_.ray.org_y[from];
    pk_.ray.org_z[to] = pk_.ray.org_z[from];
    pk_.ray.tnear[to] = pk_.ray.tnear[from];
    pk_.ray.dir_x[to] = pk_.ray.dir_x[from];
    pk_.ray.dir_y[to] = pk_.ray.dir_y[from];
    pk_.ray.dir_z[to] = pk_.ray.dir_z[from];
    pk_.ray.time[to] = 0;
    pk_.ray.tfar[to] = pk_.ray.tfar[from];
    pk_.ray.mask[to] = 0xFFFFFFFFu;
    pk_.ray.id[to] = 0;
    pk_.ray.flags[to] = 0;
  }

  alignas(64) RTCRayHit16 pk_;
  RTCIntersectContext* ctx_;
  size_t index_[16] = {};
  unsigned m_ = 0;
};

OracleStats closest_packets16(RTCScene top, const fmt::Ray* rays, fmt::Hit* hits, size_t n) {
  std::atomic<uint64_t> invalid{0}, unsupported{0};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kGrain), [&](const tbb::blocked_range<size_t>& range) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    Packet16 packet(&ctx);
    uint64_t counts[2] = {0, 0};  // invalid, unsupported
    for (size_t i = range.begin(); i < range.end(); ++i) {
      const RayStatus st = ray_status(rays[i]);
      if (st == RayStatus::kValid) {
        if (packet.add(rays[i], i)) packet.trace(top, hits);
      } else {
        counts[st == RayStatus::kInvalid ? 0 : 1] += 1;
        set_miss(hits[i]);
      }
    }
    packet.trace(top, hits);
    invalid.fetch_add(counts[0], std::memory_order_relaxed);
    unsupported.fetch_add(counts[1], std::memory_order_relaxed);
  });
  return {n, invalid.load(), unsupported.load()};
}

}  // namespace

OracleStats EmbreeOracle::closest(const fmt::Ray* rays, fmt::Hit* hits, size_t n, RayCoherence coherence) const {
  RTCScene top = impl_->top;
  if (coherence == RayCoherence::kCoherent) return closest_packets16(top, rays, hits, n);
  return in_batches<RTCRayHit>(
      rays, n, coherence, [&](size_t i) { set_miss(hits[i]); },
      [](const fmt::Ray& r, RTCRayHit& rh) {
        load_ray(r, rh.ray);
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      },
      [&](RTCIntersectContext* ctx, RTCRayHit* buf, unsigned m) {
        if (coherence == RayCoherence::kSingle)
          for (unsigned j = 0; j < m; ++j) rtcIntersect1(top, ctx, &buf[j]);
        else
          rtcIntersect1M(top, ctx, buf, m, sizeof(RTCRayHit));
      },
      [&](size_t i, const RTCRayHit& rh) {
        fmt::Hit& h = hits[i];
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
          set_miss(h);
        } else {
          h.t = rh.ray.tfar;
          h.instance = rh.hit.instID[0];
          h.prim = rh.hit.primID;
          h.u = rh.hit.u;
          h.v = rh.hit.v;
        }
      });
}

OracleStats EmbreeOracle::occluded(const fmt::Ray* rays, uint8_t* occluded, size_t n, RayCoherence coherence) const {
  RTCScene top = impl_->top;
  return in_batches<RTCRay>(
      rays, n, coherence, [&](size_t i) { occluded[i] = 0; }, [](const fmt::Ray& r, RTCRay& e) { load_ray(r, e); },
      // A stream in both cases (the COHERENT flag lets Embree form packets). Not rtcOccluded16: the
      // Debian 3.13.5 AVX-512 build spins forever in it after an rtcIntersect1M call made inside a
      // one-thread tbb::task_arena (reproduced on samples/generated/gallery.glb).
      [&](RTCIntersectContext* ctx, RTCRay* buf, unsigned m) {
        if (coherence == RayCoherence::kSingle)
          for (unsigned j = 0; j < m; ++j) rtcOccluded1(top, ctx, &buf[j]);
        else
          rtcOccluded1M(top, ctx, buf, m, sizeof(RTCRay));
      },
      // Embree sets tfar = -inf on an occluded ray.
      [&](size_t i, const RTCRay& e) { occluded[i] = e.tfar == -kInf ? 1 : 0; });
}

namespace {

// Gribble 2016 §2.2: Embree's multi-hit is a filter that saves each hit and rejects it (valid = 0), so
// the ray's interval never shrinks and every node along it is visited.
struct GatherContext {
  RTCIntersectContext ctx;  // first: Embree passes &ctx back to the filter
  std::vector<fmt::Hit>* hits;
};

void gather_hit(const RTCFilterFunctionNArguments* a) {
  auto* g = reinterpret_cast<GatherContext*>(a->context);
  for (unsigned i = 0; i < a->N; ++i) {
    if (a->valid[i] != -1) continue;
    g->hits->push_back({RTCRayN_tfar(a->ray, a->N, i), RTCHitN_instID(a->hit, a->N, i, 0), RTCHitN_primID(a->hit, a->N, i),
                        RTCHitN_u(a->hit, a->N, i), RTCHitN_v(a->hit, a->N, i)});
    a->valid[i] = 0;
  }
}

}  // namespace

OracleStats EmbreeOracle::multi_hit(const fmt::Ray* rays, size_t n, uint32_t max_hits, fmt::Hit* hits, uint32_t* counts) const {
  if (!gather_filter_) throw Error(ExitCode::kUsage, "Embree oracle: multi_hit needs an oracle built with gather_filter");
  if (max_hits == 0) throw Error(ExitCode::kUsage, "Embree oracle: multi_hit needs N >= 1");
  std::atomic<uint64_t> invalid{0}, unsupported{0};
  RTCScene top = impl_->top;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kGrain), [&](const tbb::blocked_range<size_t>& range) {
    std::vector<fmt::Hit> all;
    GatherContext g;
    rtcInitIntersectContext(&g.ctx);
    g.ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    g.ctx.filter = gather_hit;
    g.hits = &all;
    uint64_t bad = 0, unsup = 0;
    for (size_t i = range.begin(); i < range.end(); ++i) {
      fmt::Hit* out = hits + i * max_hits;
      for (uint32_t k = 0; k < max_hits; ++k) set_miss(out[k]);
      counts[i] = 0;
      const RayStatus st = ray_status(rays[i]);
      if (st != RayStatus::kValid) {
        (st == RayStatus::kInvalid ? bad : unsup) += 1;
        continue;
      }
      RTCRayHit rh;
      load_ray(rays[i], rh.ray);
      rh.hit.geomID = rh.hit.primID = rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      all.clear();
      rtcIntersect1(top, &g.ctx, &rh);
      std::sort(all.begin(), all.end(), hit_order_less);
      all.erase(std::unique(all.begin(), all.end(),
                            [](const fmt::Hit& a, const fmt::Hit& b) { return a.instance == b.instance && a.prim == b.prim; }),
                all.end());
      counts[i] = uint32_t(std::min<size_t>(max_hits, all.size()));
      std::copy(all.begin(), all.begin() + counts[i], out);
    }
    if (bad) invalid.fetch_add(bad, std::memory_order_relaxed);
    if (unsup) unsupported.fetch_add(unsup, std::memory_order_relaxed);
  });
  return {n, invalid.load(), unsupported.load()};
}

}  // namespace rtp
