#pragma once
// The scheduler of the batched out-of-core tracer (out_of_core.cpp), in the steps of Molenaar 2019: rays
// walk the top level to their next batching points and wait in the points' queues (§4.1), a point's DAG
// culls rays before it is loaded (§4.2), rounds take the points with the most waiting rays that fit in
// the budget (§4.3), and a round traces its points' queues in passes while they are resident. The rays
// are one call's array (FixedRays) or a stream's slots (ray_stream.h), whose feed hands finished rays
// back and admits new ones after every pass, so continuation rays meet the round's points while they
// are still resident. Internal to lib/trace.
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <memory>
#include <numeric>
#include <thread>
#include <vector>

#include "core/clock.h"
#include "core/error.h"
#include "formats/ray_file.h"
#include "trace/out_of_core.h"
#include "trace/top_level_walk.h"

namespace rtp::batched {

inline constexpr uint32_t kNone = 0xFFFFFFFFu;
inline constexpr size_t kBlock = 64;  // rays traced together at one batching point (one kernel call)

// A ray's visit to a batching point: which ray, the point's place in the ray's walk, where the ray
// enters it (the DAG's first set cell, or the point's box).
struct Visit {
  uint32_t ray, walk;
  float tstart;
  uint32_t dag_tested = 0;  // 1: its point's DAG kept it (cull_queues)
};

// Striped spin locks over the rays: visits of one ray to several points of a round may be traced at
// once by different threads; each merges its answer under the ray's lock.
class RayLocks {
 public:
  struct Held {
    std::atomic_flag* f;
    ~Held() { f->clear(std::memory_order_release); }
  };
  Held hold(uint32_t ray) {
    std::atomic_flag& f = flags_[ray % kStripes];
    while (f.test_and_set(std::memory_order_acquire))
      while (f.test(std::memory_order_relaxed)) std::this_thread::yield();
    return {&f};
  }

 private:
  static constexpr size_t kStripes = 4096;
  std::array<std::atomic_flag, kStripes> flags_{};
};

// The points one round makes resident, the chunks they need, and the chunks of the likely next points.
struct Round {
  std::vector<uint32_t> points, chunks, ahead;
};

// The feed of a whole-array call: rays 0..n-1, walked once at the start, nothing handed back.
struct FixedRays {
  static constexpr bool kStreaming = false;
  void done(uint32_t) {}
  template <class Admit>
  bool exchange(Admit&&) {
    return false;
  }
};

// What a stream's cull decision weighs (Molenaar 2019 §4.2 culls to save loads): testing a queue's rays
// against a non-resident point's DAG pays while their tests cost less than loading the point, so a point
// tests up to load_bytes * seconds_per_byte / seconds_per_test rays (at least kBlock) before it is
// loaded. Both costs are measured as the stream runs (priors until then).
struct CullModel {
  double seconds_per_test = 300e-9;  // one ray's DAG walk
  double seconds_per_byte = 1e-9;    // reading, decompressing and checking one raw byte
  uint64_t tests = 0;
  double test_seconds = 0;
  uint64_t allowance(uint64_t load_bytes) const {
    const double per_test = tests >= 1024 ? test_seconds / double(tests) : seconds_per_test;
    return std::max<uint64_t>(kBlock, uint64_t(double(load_bytes) * seconds_per_byte / std::max(per_test, 1e-12)));
  }
};

// Host: the tracer (Batched<W, B>), which owns the resident tables and the cache. It provides
//   n_points(), toc_size(), fixed_bytes(), has_grids(), advance(ray, tfar, pos, tstart, cull, stats), dag_enter(p, ray),
//   point_resident(p), point_chunk(p), point_segment_chunks(p) (a range of TOC indices), cache(),
//   prefetch(), load(chunks, points) and point(p) (a PointSlot: .view, .s.global_ids).
// Speculative batching (an extension of Molenaar 2019 §4.1): a ray is queued at its next `depth` points
// at once, each traced with the tfar the ray had when queued, and the answers are merged by (t, walk
// order). A point's nearest hit below the tfar a one-by-one walk would have used there is the same
// under a larger tfar (pruning only drops farther work), and a hit at or beyond it loses the merge, so
// the answers are those of the one-by-one walk, while every point a round loads serves all its rays at
// once (unique-50m's bounce rays at a 10 % budget: 257 chunk loads one point at a time, 98 here).
// Feed: FixedRays, or a stream's (ray_stream.cpp): done(i) when ray i has every answer (any thread), and
// exchange(admit) between passes, which hands the done rays back, refills their slots and calls
// admit(slots, count) for the new rays (walked there); true when it did anything.
template <class Host, class TraceBlock, class CurrentTfar, class Stopped, class Feed = FixedRays>
class Scheduler {
 public:
  Scheduler(Host& host, const fmt::Ray* rays, size_t n, bool cull, uint32_t depth, TraceBlock& trace_block,
            CurrentTfar& current_tfar, Stopped& stopped, Feed* feed = nullptr)
      : h_(host),
        feed_(feed),
        rays_(rays),
        n_(n),
        cull_(cull),
        depth_(depth),
        trace_block_(trace_block),
        current_tfar_(current_tfar),
        stopped_(stopped),
        pos_(n),
        walk_tfar_(n, 0.f),
        pending_(n, 0),
        next_walk_(n, 0),
        walk_over_(n, 0),
        locks_(std::make_unique<RayLocks>()),
        queue_(host.n_points()),
        tested_(host.n_points(), 0),
        since_(host.n_points(), 0) {}

  // The whole call: first walks, then rounds until no ray waits anywhere.
  OutOfCoreStats run() {
    const auto t_total = Clock::now();
    st_.rays = n_;
    st_.budget_bytes = h_.cache().budget();
    st_.fixed_bytes = h_.fixed_bytes();
    const ChunkCacheStats cache_before = h_.cache().stats();
    timed(st_.walk_seconds, [&] {
      if constexpr (Feed::kStreaming)
        pump();
      else
        start_walks();
      cull_queues();
    });
    for (;;) {
      if constexpr (Feed::kStreaming)
        if (waiting_ == 0) timed(st_.walk_seconds, [&] { pump(), cull_queues(); });
      if (waiting_ == 0) break;
      ++st_.rounds;
      Round round;
      round = choose_round();
      timed(st_.load_seconds, [&] { load_round(round); });
      if (const ChunkCacheStats& c = h_.cache().stats(); c.raw_bytes_loaded > 0)
        model_.seconds_per_byte = c.load_seconds / double(c.raw_bytes_loaded);
      trace_round(round);
      h_.cache().release();
      timed(st_.walk_seconds, [&] { cull_queues(); });
      const uint64_t cache_now = h_.cache().stats().resident_bytes;
      st_.peak_resident_bytes = std::max(st_.peak_resident_bytes, st_.fixed_bytes + cache_now + st_.peak_ray_bytes);
    }
    finish(cache_before);
    st_.total_seconds = seconds_since(t_total);
    return st_;
  }

  OutOfCoreStats& stats() { return st_; }

 private:
  using Moves = std::vector<std::pair<uint32_t, Visit>>;  // (point, visit)

  template <class F>
  static void timed(double& seconds, F&& f) {
    const auto t0 = Clock::now();
    f();
    seconds += seconds_since(t0);
  }

  // Queues ray i at its next points (up to depth_), walking with its current tfar. The caller owns ray i
  // (none of its visits is pending).
  void walk_ahead(uint32_t i, Moves& m, PackageTraceStats& ws) {
    const float tfar = current_tfar_(i);
    walk_tfar_[i] = tfar;
    uint32_t c = 0;
    while (c < depth_) {
      float tstart = 0.f;
      const uint32_t p = h_.advance(rays_[i], tfar, pos_[i], tstart, false, ws);  // DAGs: cull_queues
      if (p == kNone) {
        walk_over_[i] = 1;
        break;
      }
      m.push_back({p, Visit{i, next_walk_[i]++, tstart}});
      ++c;
    }
    pending_[i] = c;
    if (c == 0) feed_done(i);
  }

  // Ray i has every answer: a stream hands it back at the next exchange.
  void feed_done(uint32_t i) {
    if constexpr (Feed::kStreaming) feed_->done(i);
  }
  // The last pending visit of ray i was answered: it walks on, or it is done.
  void visit_answered(uint32_t i, Moves& m, PackageTraceStats& ws) {
    if (!walk_over_[i] && !stopped_(i))
      walk_ahead(i, m, ws);
    else
      feed_done(i);
  }

  // The threads' new visits into the points' queues; counts the waiting visits and the rays' memory.
  void enqueue_moves() {
    uint64_t queued = 0;
    for (Moves& m : moves_) {
      for (const auto& [p, v] : m) {
        if (queue_[p].empty()) since_[p] = st_.rounds;
        queue_[p].push_back(v);
      }
      m.clear();
    }
    uint64_t ray_bytes = n_ * (sizeof(TopPosition) + sizeof(float) + 2 * sizeof(uint32_t) + 1) + sizeof(RayLocks);
    for (const auto& q : queue_) ray_bytes += q.capacity() * sizeof(Visit), queued += q.size();
    for (const Moves& m : moves_) ray_bytes += m.capacity() * sizeof(typename Moves::value_type);
    st_.peak_ray_bytes = std::max(st_.peak_ray_bytes, ray_bytes);
    waiting_ = queued;
  }

  // Molenaar 2019 §4.1: every valid ray walks the top level to its first points and waits there.
  void start_walks() {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n_, 1024), [&](const tbb::blocked_range<size_t>& rg) {
      Moves& m = moves_.local();
      PackageTraceStats& ws = walk_stats_.local();
      for (size_t i = rg.begin(); i != rg.end(); ++i) {
        start_walk(uint32_t(i), m, ws);
      }
    });
    enqueue_moves();
  }

  // A ray's first walk: an invalid one is done at once (a miss).
  void start_walk(uint32_t i, Moves& m, PackageTraceStats& ws) {
    if (!ray_is_valid(rays_[i])) {
      ++ws.invalid_rays;
      walk_over_[i] = 1;
      feed_done(i);
      return;
    }
    walk_ahead(i, m, ws);
  }

  // A stream's rays in freshly filled slots: state reset, first walks in parallel, queued.
  void admit(const uint32_t* slots, size_t k) {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, k, 256), [&](const tbb::blocked_range<size_t>& rg) {
      Moves& m = moves_.local();
      PackageTraceStats& ws = walk_stats_.local();
      for (size_t j = rg.begin(); j != rg.end(); ++j) {
        const uint32_t i = slots[j];
        pos_[i] = TopPosition{};
        walk_tfar_[i] = 0.f;
        pending_[i] = next_walk_[i] = 0;
        walk_over_[i] = 0;
        start_walk(i, m, ws);
      }
    });
  }

  // Hands the done rays back and admits what the feed has until neither happens (a ray can be done at
  // once: invalid, or missing the top level).
  void pump() {
    while (feed_->exchange([&](const uint32_t* slots, size_t k) { admit(slots, k); })) enqueue_moves();
    enqueue_moves();
  }

  // Molenaar 2019 §4.2 culls a ray at a batching point by the point's DAG so that the point need not be
  // loaded for it; culling never changes a hit. Only points that are not resident test rays. A
  // whole-array call tests the rays of queues of at most kBlock: a point with more is loaded anyway (some
  // ray passes its DAG) and there the DAG walk costs more than the BVH traversal it saves (docs/culling).
  // A stream, whose rays keep arriving, tests each point's rays while the tests cost less than loading
  // it (CullModel). Culled visits leave the queue, their rays walk on within the same round, and a point
  // whose rays are all culled is never loaded.
  void cull_queues() {
    if (!cull_ || !h_.has_grids()) return;
    Moves& m = moves_.local();
    const auto t0 = Clock::now();
    uint64_t tests = 0;
    for (bool again = true; again;) {
      again = false;
      for (uint32_t p = 0; p < h_.n_points(); ++p) {
        std::vector<Visit>& q = queue_[p];
        if (q.empty() || h_.point_resident(p)) continue;
        uint64_t allow = ~uint64_t(0);
        if constexpr (Feed::kStreaming) {
          allow = model_.allowance(h_.point_load_bytes(p));
          if (tested_[p] >= allow) continue;
        } else if (q.size() > kBlock) {
          continue;
        }
        size_t kept = 0;
        for (Visit v : q) {
          if (v.dag_tested || tested_[p] >= allow) {
            q[kept++] = v;
            continue;
          }
          ++tested_[p], ++tests;
          fmt::Ray local = rays_[v.ray];
          local.tnear = v.tstart;
          local.tfar = walk_tfar_[v.ray];
          if (h_.dag_enter(p, local)) {
            v.tstart = local.tnear;
            v.dag_tested = 1;
            q[kept++] = v;
            continue;
          }
          ++cull_stats_.culled_visits;
          if (--pending_[v.ray] == 0) visit_answered(v.ray, m, cull_stats_);
        }
        q.resize(kept);
      }
      if (!m.empty()) again = true;
      enqueue_moves();
    }
    st_.dag_tests += tests;
    model_.tests += tests;
    model_.test_seconds += seconds_since(t0);
  }

  // Molenaar 2019 §4.3: the points with the most waiting rays first, as many as fit in the budget; and
  // the chunks of the points likely next (the most waiting rays among those not taken), to read ahead.
  // A stream gives an eighth of the budget to the points that have waited longest first (§4.3's share for
  // the tail: the seed picks it at random; by age it bounds how long a ray can wait), else rays at
  // points that never lead would starve while new rays keep arriving elsewhere.
  Round choose_round() {
    Round round;
    std::vector<uint32_t> order(h_.n_points());
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return queue_[a].size() > queue_[b].size(); });
    in_round_.resize(h_.toc_size(), 0);
    point_mark_.resize(h_.n_points(), 0);
    uint64_t bytes = 0;
    // With reading ahead, a quarter of the budget stays free for the next round's chunks.
    const uint64_t budget = h_.cache().budget();
    const uint64_t round_cap = h_.prefetch() ? budget - budget / 4 : budget;
    auto consider = [&](uint32_t p, uint64_t cap) {
      if (point_mark_[p]) return;
      uint64_t add = in_round_[h_.point_chunk(p)] ? 0 : h_.cache().cost(h_.point_chunk(p));
      for (uint32_t c : h_.point_segment_chunks(p))
        if (!in_round_[c]) add += h_.cache().cost(c);  // a segment named twice counts twice: conservative
      if (!round.points.empty() && bytes + add > cap) return;
      round.points.push_back(p);
      point_mark_[p] = 1;
      bytes += add;
      auto take = [&](uint32_t c) {
        if (!in_round_[c]) in_round_[c] = 1, round.chunks.push_back(c);
      };
      take(h_.point_chunk(p));
      for (uint32_t c : h_.point_segment_chunks(p)) take(c);
    };
    if constexpr (Feed::kStreaming) {
      std::vector<uint32_t> oldest;
      for (uint32_t p : order)
        if (!queue_[p].empty() && since_[p] + 1 < st_.rounds) oldest.push_back(p);
      std::stable_sort(oldest.begin(), oldest.end(), [&](uint32_t a, uint32_t b) { return since_[a] < since_[b]; });
      for (uint32_t p : oldest) consider(p, round_cap / 8);
    }
    for (uint32_t p : order) {
      if (queue_[p].empty()) break;
      consider(p, round_cap);
    }
    for (uint32_t c : round.chunks) in_round_[c] = 0;
    for (uint32_t p : order) {
      if (queue_[p].empty() || round.ahead.size() > 4096) break;
      if (point_mark_[p]) continue;
      round.ahead.push_back(h_.point_chunk(p));
      for (uint32_t c : h_.point_segment_chunks(p)) round.ahead.push_back(c);
    }
    for (uint32_t p : round.points) point_mark_[p] = 0;
    return round;
  }

  // The round's chunks through the cache (read, checked, decoded); while the round traces, the I/O
  // thread reads ahead when prefetching is on.
  void load_round(const Round& round) {
    h_.load(round.chunks, round.points);
    if (h_.prefetch()) h_.cache().prefetch(round.ahead);
  }

  // All threads on the round's visits, kBlock at a time; rays that move on to another point of this
  // round are traced in another pass while it is still resident (no reload).
  void trace_round(const Round& round) {
    std::vector<uint32_t> active = round.points;
    while (!active.empty()) {
      struct Work {
        uint32_t p, first, count;
      };
      std::vector<Work> work;
      for (uint32_t p : active)
        for (size_t f = 0; f < queue_[p].size(); f += kBlock)
          work.push_back({p, uint32_t(f), uint32_t(std::min(kBlock, queue_[p].size() - f))});
      timed(st_.trace_seconds, [&] {
        tbb::parallel_for(size_t(0), work.size(), [&](size_t w) { trace_work(work[w].p, work[w].first, work[w].count); });
      });
      ++st_.passes;
      for (uint32_t p : active) std::vector<Visit>().swap(queue_[p]), tested_[p] = 0;
      enqueue_moves();
      if constexpr (Feed::kStreaming) timed(st_.walk_seconds, [&] { pump(), cull_queues(); });
      active.clear();
      for (uint32_t p : round.points)
        if (!queue_[p].empty()) active.push_back(p);
    }
  }

  // One kernel block of point p's queue; a ray whose last pending visit this was walks on.
  void trace_work(uint32_t p, uint32_t first, uint32_t count) {
    const auto& pt = h_.point(p);
    const Visit* visits = queue_[p].data() + first;
    fmt::Ray local[kBlock];
    for (uint32_t j = 0; j < count; ++j) {
      local[j] = rays_[visits[j].ray];
      local[j].tnear = visits[j].tstart;
      local[j].tfar = walk_tfar_[visits[j].ray];
    }
    trace_block_(pt.view, pt.s.global_ids, visits, local, count, *locks_);
    Moves& m = moves_.local();
    PackageTraceStats& ws = walk_stats_.local();
    for (uint32_t j = 0; j < count; ++j) {
      const uint32_t i = visits[j].ray;
      {
        auto lock = locks_->hold(i);
        if (--pending_[i] != 0) continue;  // its other visits are still to be traced
      }
      // Its last pending visit: every answer of its queued points is merged, the ray is this task's.
      visit_answered(i, m, ws);
    }
  }

  // The walk and cull counts of every thread, and what the cache did during this call.
  void finish(const ChunkCacheStats& before) {
    st_.point_visits += cull_stats_.point_visits;
    st_.culled_visits += cull_stats_.culled_visits;
    for (const PackageTraceStats& ws : walk_stats_) {
      st_.invalid_rays += ws.invalid_rays;
      st_.point_visits += ws.point_visits;
      st_.culled_visits += ws.culled_visits;
    }
    const ChunkCacheStats& c = h_.cache().stats();
    st_.cache = c;
    st_.cache.requests -= before.requests;
    st_.cache.hits -= before.hits;
    st_.cache.loads -= before.loads;
    st_.cache.bytes_read -= before.bytes_read;
    st_.cache.raw_bytes_loaded -= before.raw_bytes_loaded;
    st_.cache.evictions -= before.evictions;
    st_.cache.prefetched -= before.prefetched;
    st_.cache.load_seconds -= before.load_seconds;
    st_.peak_resident_bytes = std::max(st_.peak_resident_bytes, st_.fixed_bytes + c.peak_resident_bytes + st_.peak_ray_bytes);
  }

  Host& h_;
  Feed* feed_;
  const fmt::Ray* rays_;
  size_t n_;
  bool cull_;
  uint32_t depth_;
  TraceBlock& trace_block_;
  CurrentTfar& current_tfar_;
  Stopped& stopped_;
  // Per ray: where its walk stands in the top level, the tfar its queued visits were traced with, how
  // many of them are still to be traced, the walk index of its next point, whether its walk is over.
  std::vector<TopPosition> pos_;
  std::vector<float> walk_tfar_;
  std::vector<uint32_t> pending_, next_walk_;
  std::vector<uint8_t> walk_over_;
  std::unique_ptr<RayLocks> locks_;
  std::vector<std::vector<Visit>> queue_;  // visits waiting at each batching point
  std::vector<uint64_t> tested_;           // DAG tests at each point since it was last traced
  std::vector<uint64_t> since_;            // the round since which each point's queue has been waiting
  CullModel model_;
  tbb::enumerable_thread_specific<Moves> moves_;
  tbb::enumerable_thread_specific<PackageTraceStats> walk_stats_;
  PackageTraceStats cull_stats_;
  uint64_t waiting_ = 0;
  std::vector<uint8_t> in_round_;    // chunks of the round being chosen
  std::vector<uint8_t> point_mark_;  // points of the round being chosen
  OutOfCoreStats st_;
};

}  // namespace rtp::batched
