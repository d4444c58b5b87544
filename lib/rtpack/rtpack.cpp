// The public reader API (rtpack/rtpack.h) over the container (lib/reader) and the in-core package
// tracer (lib/trace): internal errors become rtpack::Error, internal types never cross the header.
#include "rtpack/rtpack.h"
#include "rtpack/package_impl.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <mutex>
#include <new>
#include <optional>

#include "core/error.h"
#include "formats/chunk.h"
#include "reader/attribute_lookup.h"
#include "reader/camera.h"
#include "layout/chunk_io.h"
#include "reader/reader.h"
#include "trace/tracer.h"
#include "reader/tile_order.h"

#ifndef RTP_VERSION
#define RTP_VERSION "unknown"
#endif

namespace rtpack {
namespace {

static_assert(sizeof(Ray) == sizeof(rtp::fmt::Ray) && offsetof(Ray, dir) == offsetof(rtp::fmt::Ray, dir) &&
              offsetof(Ray, tfar) == offsetof(rtp::fmt::Ray, tfar));
static_assert(sizeof(Hit) == sizeof(rtp::fmt::Hit) && offsetof(Hit, prim) == offsetof(rtp::fmt::Hit, prim) &&
              offsetof(Hit, v) == offsetof(rtp::fmt::Hit, v));
static_assert(sizeof(Shading) == sizeof(rtp::fmt::Shading) && offsetof(Shading, uv) == offsetof(rtp::fmt::Shading, uv));
static_assert(Hit::kNone == rtp::fmt::Hit::kNone);

// camera_rays() and tile_order() take 1 to 2^28 pixels.
void check_image_size(const char* what, int width, int height) {
  if (width <= 0 || height <= 0 || int64_t(width) * height > (int64_t(1) << 28))
    throw Error(int(rtp::ExitCode::kUsage), std::string(what) + ": " + std::to_string(width) + "x" + std::to_string(height) +
                                                " is not a size (1 to 2^28 pixels)");
}

Bounds bounds_of(const float lo[3], const float hi[3]) {
  Bounds b{};
  std::memcpy(b.lo, lo, sizeof b.lo);
  std::memcpy(b.hi, hi, sizeof b.hi);
  return b;
}

}  // namespace

const char* version() { return RTP_VERSION; }
const char* format_version() {
  static const std::string v = std::to_string(rtp::fmt::kVersionMajor) + "." + std::to_string(rtp::fmt::kVersionMinor);
  return v.c_str();
}

Package::Package(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Package::~Package() = default;
Package::Package(Package&&) noexcept = default;
Package& Package::operator=(Package&&) noexcept = default;

Package Package::open(const std::string& path) { return open(path, OpenOptions{}); }

Package Package::open(const std::string& path, const OpenOptions& options) {
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  guarded(path, [&] {
    impl->reader = std::make_unique<rtp::PackageReader>(path, options.direct_io);
    const rtp::PackageReader& r = *impl->reader;
    // In core: every chunk read, CRC-checked and structurally checked (reader/check_chunks.h) before
    // any ray; out of core the resident ones now, the others as they load (ray_stream.cpp).
    open_tracer_for(*impl, options);
    const rtp::fmt::Header& h = r.header();
    Info& in = impl->info;
    in.format_major = h.version_major;
    in.format_minor = h.version_minor;
    in.package_bytes = h.file_size;
    in.unique_triangles = h.unique_triangles;
    in.instanced_triangles = h.instanced_triangles;
    in.bvh_width = h.bvh_width;
    in.leaf_width = h.leaf_width;
    in.bounds = bounds_of(h.bounds_lo, h.bounds_hi);
    in.has_normals = h.flags & rtp::fmt::kFlagNormals;
    in.has_uvs = h.flags & rtp::fmt::kFlagUvs;
    in.has_dags = impl->tracer->has_dags();
    in.cameras = uint32_t(rtp::camera_count(r));

    auto view = [&](rtp::fmt::ChunkKind kind, rtp::AlignedBytes& bytes) {
      const int64_t i = r.find(kind, 0);
      if (i < 0) rtp::fail_invalid(std::string("missing ") + rtp::chunk_kind_name(uint32_t(kind)) + " chunk");
      bytes = r.read(size_t(i));
      return rtp::ChunkView(bytes.data(), bytes.size(), uint32_t(kind), rtp::chunk_label(r.toc()[size_t(i)], size_t(i)));
    };
    rtp::AlignedBytes ib, db, mb;
    uint64_t n = 0;
    view(rtp::fmt::ChunkKind::kInstances, ib).get<rtp::fmt::InstanceRef>(rtp::fmt::SectionType::kInstanceRefs, n);
    in.instances = n;
    const rtp::ChunkView dv = view(rtp::fmt::ChunkKind::kBatchingPoints, db);
    const rtp::fmt::BatchingPointDesc* d = dv.get<rtp::fmt::BatchingPointDesc>(rtp::fmt::SectionType::kPointDescs, n);
    for (uint64_t p = 0; p < n; ++p) {
      BatchingPoint bp;
      bp.bounds = bounds_of(d[p].lo, d[p].hi);
      bp.unique_triangles = d[p].unique_triangles;
      bp.instanced_triangles = d[p].instanced_triangles;
      bp.instances = d[p].instance_count;
      if (const int64_t c = r.find(rtp::fmt::ChunkKind::kBatchingPoint, d[p].chunk_id); c >= 0) {
        bp.stored_bytes = r.toc()[size_t(c)].stored_size;
        bp.raw_bytes = r.toc()[size_t(c)].raw_size;
      }
      impl->points.push_back(bp);
    }
    const rtp::ChunkView mv = view(rtp::fmt::ChunkKind::kMeshes, mb);
    const rtp::fmt::MeshInfo* m = mv.get<rtp::fmt::MeshInfo>(rtp::fmt::SectionType::kMeshTable, n);
    for (uint64_t i = 0; i < n; ++i) impl->meshes.push_back({m[i].triangles, m[i].segment});
    return 0;
  });
  return Package(std::move(impl));
}

const Info& Package::info() const { return impl_->info; }
const std::vector<BatchingPoint>& Package::batching_points() const { return impl_->points; }
const std::vector<Mesh>& Package::meshes() const { return impl_->meshes; }

namespace {

// The public TraceStats of one call.
void store_stats(const rtp::PackageTraceStats& st, TraceStats* out) {
  if (out)
    *out = {st.rays,    st.invalid_rays, st.point_visits,      st.culled_visits,
            st.packets, st.packet_rays,  st.packet_node_tests, st.packet_active_lanes};
}

}  // namespace

size_t Package::trace(const Ray* rays, Hit* hits, size_t count, const TraceOptions& options, TraceStats* stats) const {
  const rtp::PackageTraceOptions opt = impl_->trace_options(options);
  rtp::TracerStats sum;
  const size_t n_hit = guarded(impl_->path, [&] {
    auto* h = reinterpret_cast<rtp::fmt::Hit*>(hits);
    std::optional<Turn> turn;
    if (out_of_core()) turn.emplace(*impl_);  // one call at a time on the out-of-core tracer
    sum = Impl::with_threads(options.threads,
                             [&] { return impl_->tracer->closest(reinterpret_cast<const rtp::fmt::Ray*>(rays), h, count, opt); });
    return size_t(std::count_if(h, h + count, [](const rtp::fmt::Hit& x) { return x.instance != rtp::fmt::Hit::kNone; }));
  });
  store_stats(sum, stats);
  return n_hit;
}

size_t Package::occluded(const Ray* rays, uint8_t* occluded, size_t count, const TraceOptions& options, TraceStats* stats) const {
  rtp::PackageTraceOptions opt = impl_->trace_options(options);
  opt.packet = 0;  // any hits through the package go ray by ray
  rtp::TracerStats sum;
  const size_t n_occ = guarded(impl_->path, [&] {
    std::optional<Turn> turn;
    if (out_of_core()) turn.emplace(*impl_);  // one call at a time on the out-of-core tracer
    sum = Impl::with_threads(
        options.threads, [&] { return impl_->tracer->any(reinterpret_cast<const rtp::fmt::Ray*>(rays), occluded, count, opt); });
    return size_t(std::count_if(occluded, occluded + count, [](uint8_t o) { return o != 0; }));
  });
  store_stats(sum, stats);
  return n_occ;
}

void Package::shade(const Hit* hits, Shading* out, size_t count) const {
  guarded(impl_->path, [&] {
    std::call_once(impl_->attributes_once, [&] { impl_->attributes = std::make_unique<rtp::AttributeLookup>(*impl_->reader); });
    for (size_t i = 0; i < count; ++i) {
      const rtp::fmt::Shading s = impl_->attributes->shade(reinterpret_cast<const rtp::fmt::Hit&>(hits[i]));
      std::memcpy(&out[i], &s, sizeof s);
    }
    return 0;
  });
}

std::vector<Ray> Package::camera_rays(int width, int height, int camera, PixelOrder order) const {
  check_image_size("camera_rays", width, height);
  if (order != PixelOrder::kRows && order != PixelOrder::kTiles)
    throw Error(int(rtp::ExitCode::kUsage), "camera_rays: PixelOrder " + std::to_string(int(order)) + " is not an order");
  return guarded(impl_->path, [&] {
    const rtp::CameraRays cr = rtp::camera_rays(*impl_->reader, width, height, camera);
    std::vector<Ray> out(cr.rays.size());
    if (order == PixelOrder::kTiles) {
      const std::vector<uint32_t> pixel = rtp::hilbert_tile_order(width, height);
      for (size_t k = 0; k < out.size(); ++k) std::memcpy(&out[k], &cr.rays[pixel[k]], sizeof(Ray));
    } else if (!out.empty()) {
      std::memcpy(out.data(), cr.rays.data(), out.size() * sizeof(Ray));
    }
    return out;
  });
}

std::vector<uint32_t> tile_order(int width, int height) {
  check_image_size("tile_order", width, height);
  return rtp::hilbert_tile_order(width, height);
}

}  // namespace rtpack
