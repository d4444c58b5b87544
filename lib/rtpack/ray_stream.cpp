// The public API's out-of-core half (rtpack/rtpack.h): Package::open under a memory budget and the
// RayStream over the batched out-of-core tracer's stream (lib/trace/ray_stream.h).
#include <tbb/task_arena.h>

#include <cmath>
#include <cstddef>
#include <cstring>

#include "rtpack/package_impl.h"
#include "rtpack/rtpack.h"
#include "trace/ray_stream.h"

namespace rtpack {
namespace {

static_assert(sizeof(StreamRay) == sizeof(rtp::StreamRay) && offsetof(StreamRay, payload) == offsetof(rtp::StreamRay, payload) &&
              offsetof(StreamRay, any) == offsetof(rtp::StreamRay, any));
static_assert(sizeof(StreamHit) == sizeof(rtp::StreamResult) &&
              offsetof(StreamHit, normal) == offsetof(rtp::StreamResult, normal) &&
              offsetof(StreamHit, occluded) == offsetof(rtp::StreamResult, occluded) &&
              offsetof(StreamHit, payload) == offsetof(rtp::StreamResult, payload));

}  // namespace

void open_tracer_for(Package::Impl& impl, const OpenOptions& o) {
  const rtp::PackageReader& r = *impl.reader;
  if (!(o.memory_fraction >= 0 && o.memory_fraction <= 1))
    throw rtp::Error(rtp::ExitCode::kUsage,
                     "OpenOptions::memory_fraction = " + std::to_string(o.memory_fraction) + ": a fraction is in [0, 1]");
  impl.geometry_bytes = rtp::on_demand_bytes(r);
  impl.minimum_budget = rtp::minimum_budget(r);
  uint64_t budget = o.memory_budget;
  if (budget == 0 && o.memory_fraction > 0)
    budget = std::max(impl.minimum_budget, uint64_t(std::ceil(double(impl.geometry_bytes) * o.memory_fraction)));
  if (budget == 0) {
    impl.tracer = rtp::open_tracer(r);
    return;
  }
  rtp::TracerConfig c;
  c.memory_budget = budget;
  impl.tracer = rtp::open_tracer(r, c);
  impl.ooc = dynamic_cast<rtp::OutOfCoreTracer*>(impl.tracer.get());
  if (!impl.ooc) throw rtp::Error(rtp::ExitCode::kInternal, "open_tracer under a budget did not give the out-of-core tracer");
}

bool Package::out_of_core() const { return impl_->ooc != nullptr && impl_->ooc == impl_->tracer.get(); }
uint64_t Package::geometry_bytes() const { return impl_->geometry_bytes; }
uint64_t Package::minimum_budget() const { return impl_->minimum_budget; }

struct RayStream::Impl {
  Package::Impl* package = nullptr;
  std::unique_ptr<rtp::RayStream> stream;
  int threads = 0;
};

RayStream::RayStream(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
RayStream::~RayStream() = default;
RayStream::RayStream(RayStream&&) noexcept = default;
RayStream& RayStream::operator=(RayStream&&) noexcept = default;

RayStream Package::stream(const StreamOptions& options) const {
  Impl& p = *impl_;
  return guarded(p.path, [&] {
    if (p.ooc != p.tracer.get() || !p.ooc) {  // in core: one whole-package cache for every stream
      std::call_once(p.stream_tracer_once, [&] {
        p.stream_tracer = rtp::open_out_of_core(*p.reader, std::max(p.geometry_bytes, p.minimum_budget));
        p.ooc = p.stream_tracer.get();
      });
    }
    TraceOptions to;
    to.isa = options.isa;
    rtp::StreamOptions so;
    static_cast<rtp::TraceOptions&>(so.trace) = p.trace_options(to);
    so.trace.packet = 0;
    so.trace.cull = options.cull;
    so.max_in_flight = options.max_in_flight;
    auto s = std::make_unique<RayStream::Impl>();
    s->package = &p;
    s->threads = options.threads;
    s->stream = p.ooc->open_stream(so);
    return RayStream(std::move(s));
  });
}

void RayStream::submit(const StreamRay* rays, size_t count) {
  guarded(impl_->package->path, [&] {
    impl_->stream->submit(reinterpret_cast<const rtp::StreamRay*>(rays), count);
    return 0;
  });
}

StreamStats RayStream::flush(const std::function<void(const StreamHit*, size_t)>& on_hits) {
  Package::Impl& p = *impl_->package;
  return guarded(p.path, [&] {
    const Turn turn(p);
    const rtp::TracerStats st = Package::Impl::with_threads(impl_->threads, [&] {
      return impl_->stream->flush(
          [&](const rtp::StreamResult* r, size_t n) { on_hits(reinterpret_cast<const StreamHit*>(r), n); });
    });
    StreamStats out;
    out.rays = st.rays;
    out.rounds = st.rounds;
    out.passes = st.passes;
    out.batching_point_visits = st.point_visits;
    out.culled_visits = st.culled_visits;
    out.dag_tests = st.dag_tests;
    out.chunks_loaded = st.cache.loads;
    out.bytes_read = st.cache.bytes_read;
    out.raw_bytes_loaded = st.cache.raw_bytes_loaded;
    out.budget_bytes = st.budget_bytes;
    out.peak_resident_bytes = st.peak_resident_bytes;
    out.seconds = st.total_seconds;
    out.load_seconds = st.load_seconds;
    out.trace_seconds = st.trace_seconds;
    out.walk_seconds = st.walk_seconds;
    return out;
  });
}

}  // namespace rtpack
