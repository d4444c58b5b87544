#pragma once
// The ray stream (ray_stream.h) over the batched out-of-core tracer: a fixed table of ray slots (the rays
// in flight), the scheduler of batch_scheduler.h run over them with a feed that, between passes, hands
// the answered slots back to the renderer and refills them from what it submitted. Closest and any hits
// share the slots; a block of visits at a point is split by kind into the two kernels. Internal to
// lib/trace (out_of_core.cpp instantiates it per BVH width).
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <atomic>
#include <limits>
#include <string>
#include <vector>

#include "core/error.h"
#include "trace/batch_scheduler.h"
#include "trace/hit_normal.h"
#include "trace/ray_stream.h"
#include "trace/trace.h"

namespace rtp::batched {

template <int W, int B, class Host>
class HostStream final : public RayStream {
 public:
  HostStream(Host& host, const StreamOptions& o) : h_(host), o_(o) {
    if (o.max_in_flight < 1 || o.max_in_flight >= kNone)
      throw Error(ExitCode::kUsage, "rays in flight: " + std::to_string(o.max_in_flight) + " (1 .. 2^32 - 2)");
    if (o.speculation < 1 || o.speculation > 64)
      throw Error(ExitCode::kUsage, "speculation depth " + std::to_string(o.speculation) + ": must be 1..64");
    const size_t n = o.max_in_flight;
    rays_.resize(n);
    payload_.resize(n);
    any_.resize(n);
    occluded_.resize(n);
    hits_.resize(n);
    normals_.resize(n);
    best_walk_.resize(n);
    free_.resize(n);
    for (size_t i = 0; i < n; ++i) free_[i] = uint32_t(n - 1 - i);  // slot 0 taken first
  }

  void submit(const StreamRay* rays, size_t n) override { pending_.insert(pending_.end(), rays, rays + n); }

  TracerStats flush(const Deliver& deliver) override {
    if (flushing_) throw Error(ExitCode::kUsage, "RayStream::flush called from its own callback");
    flushing_ = true;
    deliver_ = &deliver;
    admitted_ = 0;
    struct Reset {
      HostStream& s;
      ~Reset() { s.flushing_ = false, s.deliver_ = nullptr; }
    } reset{*this};
    auto trace_block = [&](const SceneView<W, B>& view, const uint32_t* global_ids, const Visit* visits, const fmt::Ray* local,
                           size_t k, RayLocks& locks) { trace_visits(view, global_ids, visits, local, k, locks); };
    auto current_tfar = [&](size_t i) { return !any_[i] && hits_[i].t < kInfinity ? hits_[i].t : rays_[i].tfar; };
    auto stopped = [&](size_t i) {
      return any_[i] && std::atomic_ref<uint32_t>(occluded_[i]).load(std::memory_order_relaxed) != 0;
    };
    Feed feed(this);
    Scheduler<Host, decltype(trace_block), decltype(current_tfar), decltype(stopped), Feed> s(
        h_, rays_.data(), rays_.size(), o_.trace.cull, o_.speculation, trace_block, current_tfar, stopped, &feed);
    try {
      TracerStats st = s.run();
      st.rays = admitted_;
      return st;
    } catch (...) {  // a refused chunk or the callback's exception: the stream starts over empty
      pending_.clear();
      pending_head_ = 0;
      free_.clear();
      for (size_t i = 0; i < rays_.size(); ++i) free_.push_back(uint32_t(rays_.size() - 1 - i));
      throw;
    }
  }

 private:
  static constexpr float kInfinity = std::numeric_limits<float>::infinity();

  struct Feed {
    static constexpr bool kStreaming = true;
    explicit Feed(HostStream* stream) : s(stream) {}
    HostStream* s;
    tbb::enumerable_thread_specific<std::vector<uint32_t>> done_slots;
    void done(uint32_t i) { done_slots.local().push_back(i); }
    template <class Admit>
    bool exchange(Admit&& admit) {
      return s->exchange(*this, admit);
    }
  };

  // One block of visits at a point: closest hits merged by (t, walk order) with their normals computed
  // here, where the point is resident; any hits set their ray's flag.
  void trace_visits(const SceneView<W, B>& view, const uint32_t* global_ids, const Visit* visits, const fmt::Ray* local, size_t k,
                    RayLocks& locks) {
    fmt::Ray rc[kBlock], ra[kBlock];
    uint32_t jc[kBlock], ja[kBlock];
    size_t nc = 0, na = 0;
    for (size_t j = 0; j < k; ++j) {
      if (any_[visits[j].ray])
        ra[na] = local[j], ja[na++] = uint32_t(j);
      else
        rc[nc] = local[j], jc[nc++] = uint32_t(j);
    }
    if (nc > 0) {
      fmt::Hit h[kBlock];
      trace_closest<W, B>(view, rc, h, nc, o_.trace);
      for (size_t q = 0; q < nc; ++q) {
        if (!(h[q].t < kInfinity)) continue;
        const Visit& v = visits[jc[q]];
        float n[3];
        hit_geometric_normal<W, B>(view, rays_[v.ray], h[q], n);
        auto lock = locks.hold(v.ray);
        fmt::Hit& best = hits_[v.ray];
        if (h[q].t < best.t || (h[q].t == best.t && v.walk < best_walk_[v.ray])) {
          best = h[q];
          best.instance = global_ids[h[q].instance];
          best_walk_[v.ray] = v.walk;
          std::copy(n, n + 3, normals_[v.ray].v);
        }
      }
    }
    if (na > 0) {
      uint8_t occ[kBlock];
      trace_any<W, B>(view, ra, occ, na, o_.trace);
      for (size_t q = 0; q < na; ++q)
        if (occ[q]) std::atomic_ref<uint32_t>(occluded_[visits[ja[q]].ray]).store(1, std::memory_order_relaxed);
    }
  }

  // Between passes: the answered slots to the renderer (in slot order), then as many submitted rays as
  // there are free slots into the scheduler. True when either happened.
  template <class Admit>
  bool exchange(Feed& feed, Admit& admit) {
    done_.clear();
    for (std::vector<uint32_t>& d : feed.done_slots) done_.insert(done_.end(), d.begin(), d.end()), d.clear();
    if (!done_.empty()) {
      std::sort(done_.begin(), done_.end());
      results_.resize(done_.size());
      for (size_t j = 0; j < done_.size(); ++j) {
        const uint32_t i = done_[j];
        StreamResult& r = results_[j];
        r.payload = payload_[i];
        if (any_[i]) {
          r.hit = {kInfinity, fmt::Hit::kNone, fmt::Hit::kNone, 0, 0};
          r.occluded = occluded_[i];
          r.normal[0] = r.normal[1] = r.normal[2] = 0.f;
        } else {
          r.hit = hits_[i];
          r.occluded = hits_[i].t < kInfinity ? 1 : 0;
          std::copy(normals_[i].v, normals_[i].v + 3, r.normal);
        }
      }
      free_.insert(free_.end(), done_.rbegin(), done_.rend());
      (*deliver_)(results_.data(), results_.size());
    }
    const size_t k = std::min(free_.size(), pending_.size() - pending_head_);
    slots_.resize(k);
    for (size_t j = 0; j < k; ++j) {
      const uint32_t i = free_.back();
      free_.pop_back();
      const StreamRay& in = pending_[pending_head_ + j];
      rays_[i] = in.ray;
      payload_[i] = in.payload;
      any_[i] = in.any != 0;
      occluded_[i] = 0;
      hits_[i] = {kInfinity, fmt::Hit::kNone, fmt::Hit::kNone, 0, 0};
      normals_[i] = {};
      best_walk_[i] = kNone;
      slots_[j] = i;
    }
    pending_head_ += k;
    if (pending_head_ == pending_.size() || pending_head_ > (1u << 20)) {  // drop what has been admitted
      pending_.erase(pending_.begin(), pending_.begin() + ptrdiff_t(pending_head_));
      pending_head_ = 0;
    }
    admitted_ += k;
    if (k > 0) admit(slots_.data(), k);
    return !done_.empty() || k > 0;
  }

  struct Normal {
    float v[3] = {0, 0, 0};
  };
  Host& h_;
  StreamOptions o_;
  // Per slot: the ray, its payload and kind, its answer so far (closest: hit, its normal and the walk
  // index of the point that gave it; any: the flag).
  std::vector<fmt::Ray> rays_;
  std::vector<uint64_t> payload_;
  std::vector<uint8_t> any_;
  std::vector<uint32_t> occluded_;
  std::vector<fmt::Hit> hits_;
  std::vector<Normal> normals_;
  std::vector<uint32_t> best_walk_;
  std::vector<uint32_t> free_, done_, slots_;
  std::vector<StreamRay> pending_;
  size_t pending_head_ = 0;
  std::vector<StreamResult> results_;
  const Deliver* deliver_ = nullptr;
  uint64_t admitted_ = 0;
  bool flushing_ = false;
};

}  // namespace rtp::batched
