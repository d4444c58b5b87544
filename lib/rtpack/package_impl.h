#pragma once
// The state behind rtpack::Package (rtpack.h), shared by the files of lib/rtpack: rtpack.cpp (open,
// info, in-core calls) and ray_stream.cpp (out of core, streams). Internal.
#include <tbb/task_arena.h>

#include <atomic>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <thread>
#include <vector>

#include "core/error.h"
#include "reader/attribute_lookup.h"
#include "reader/reader.h"
#include "rtpack/rtpack.h"
#include "trace/out_of_core.h"
#include "trace/tracer.h"

namespace rtpack {

// Runs f, turning the library's internal errors into rtpack::Error prefixed with the package path.
template <class F>
auto guarded(const std::string& path, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const rtp::Error& e) {
    throw Error(int(e.code()), path + ": " + e.what());
  } catch (const std::bad_alloc&) {
    throw Error(int(rtp::ExitCode::kInternal), path + ": out of memory");
  }
}

struct Package::Impl {
  std::string path;
  std::unique_ptr<rtp::PackageReader> reader;
  std::unique_ptr<rtp::Tracer> tracer;  // in core (open_tracer without a budget): takes concurrent calls
  // Out of core: `tracer` is this one; in core: made by the first stream() over a whole-package cache.
  // One call at a time runs on it (`turn`); `owner` is the thread holding the turn (a stream's
  // callback calling trace() would otherwise deadlock or reenter the scheduler).
  rtp::OutOfCoreTracer* ooc = nullptr;
  std::unique_ptr<rtp::OutOfCoreTracer> stream_tracer;
  std::once_flag stream_tracer_once;
  std::mutex turn;
  std::atomic<std::thread::id> owner{};
  uint64_t geometry_bytes = 0, minimum_budget = 0;
  Info info;
  std::vector<BatchingPoint> points;
  std::vector<Mesh> meshes;
  mutable std::once_flag attributes_once;
  mutable std::unique_ptr<rtp::AttributeLookup> attributes;

  rtp::PackageTraceOptions trace_options(const TraceOptions& o) const {
    rtp::PackageTraceOptions opt;
    opt.cull = o.cull;
    const rtp::Isa best = rtp::detect_isa();
    switch (o.isa) {
      case Isa::kBest: opt.isa = best; break;
      case Isa::kScalar: opt.isa = rtp::Isa::kScalar; break;
      case Isa::kAvx2: opt.isa = rtp::Isa::kAvx2; break;
      case Isa::kAvx512: opt.isa = rtp::Isa::kAvx512; break;
    }
    if (int(opt.isa) > int(best))
      throw Error(int(rtp::ExitCode::kUsage),
                  std::string("this CPU runs up to ") + rtp::isa_name(best) + ", not " + rtp::isa_name(opt.isa));
    if (o.packet < 0 || !rtp::packet_size_ok(uint32_t(o.packet)))
      throw Error(int(rtp::ExitCode::kUsage), "TraceOptions::packet = " + std::to_string(o.packet) +
                                                  ": rays per packet are 4, 8 or 16, or 0 for single rays");
    opt.packet = opt.isa == rtp::Isa::kScalar ? 0 : uint32_t(o.packet);  // the scalar reference has no packets
    return opt;
  }

  // Runs f (a whole-array tracer call, parallel inside) with `threads` TBB workers, or the caller's
  // arena for threads <= 0.
  template <class F>
  static auto with_threads(int threads, F&& f) -> decltype(f()) {
    if (threads <= 0) return f();
    tbb::task_arena arena(threads);
    return arena.execute(f);
  }
};

// The out-of-core tracer's turn, held by one call (a trace(), an occluded(), a stream's flush); throws
// Error(1) when the calling thread already holds it.
class Turn {
 public:
  explicit Turn(Package::Impl& p) : p_(p) {
    if (p_.owner.load() == std::this_thread::get_id())
      throw Error(int(rtp::ExitCode::kUsage),
                  p_.path + ": a RayStream callback may not trace through the package it streams (out of core)");
    p_.turn.lock();
    p_.owner.store(std::this_thread::get_id());
  }
  ~Turn() {
    p_.owner.store(std::thread::id{});
    p_.turn.unlock();
  }
  Turn(const Turn&) = delete;
  Turn& operator=(const Turn&) = delete;

 private:
  Package::Impl& p_;
};

// Opens impl.tracer in core or out of core as `options` say, and fills the budget fields (ray_stream.cpp).
void open_tracer_for(Package::Impl& impl, const OpenOptions& options);

}  // namespace rtpack
