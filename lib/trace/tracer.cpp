// open_tracer (tracer.h): the in-core tracer splits the rays into blocks over TBB workers; the
// out-of-core tracer is parallel inside already.
#include "trace/tracer.h"

#include "trace/out_of_core.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>

namespace rtp {
namespace {

void add_stats(PackageTraceStats& sum, const PackageTraceStats& st) {
  sum.add(st);
  sum.point_visits += st.point_visits;
  sum.culled_visits += st.culled_visits;
}

class InCore final : public Tracer {
 public:
  InCore(std::unique_ptr<PackageTracer> owned, const PackageTracer& t) : owned_(std::move(owned)), t_(t) {}
  TracerStats closest(const fmt::Ray* rays, fmt::Hit* hits, size_t n, const PackageTraceOptions& o) override {
    return blocks(n, [&](size_t first, size_t k) { return t_.closest(rays + first, hits + first, k, o); });
  }
  TracerStats any(const fmt::Ray* rays, uint8_t* occluded, size_t n, const PackageTraceOptions& o) override {
    return blocks(n, [&](size_t first, size_t k) { return t_.any(rays + first, occluded + first, k, o); });
  }
  TracerStats multi(const fmt::Ray* rays, size_t n, uint32_t max_hits, fmt::Hit* hits, uint32_t* counts,
                    const PackageTraceOptions& o) override {
    check_multi_hit_count(max_hits);
    return blocks(n, [&](size_t first, size_t k) {
      return t_.multi(rays + first, k, max_hits, hits + first * max_hits, counts + first, o);
    });
  }
  bool has_dags() const override { return t_.has_dags(); }
  bool out_of_core() const override { return false; }
  PackageLoadStats load_stats() const override { return t_.load_stats(); }

 private:
  // Blocks of kBlock rays: a multiple of every packet size, so a block's rays start at a multiple of 16
  // and the packets are the caller's runs whatever the thread count.
  static constexpr size_t kBlock = 256;
  template <class F>
  TracerStats blocks(size_t n, F&& f) const {
    tbb::enumerable_thread_specific<PackageTraceStats> part;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, (n + kBlock - 1) / kBlock), [&](const tbb::blocked_range<size_t>& r) {
      const size_t first = r.begin() * kBlock, last = std::min(n, r.end() * kBlock);
      add_stats(part.local(), f(first, last - first));
    });
    TracerStats sum;
    for (const PackageTraceStats& p : part) add_stats(sum, p);
    return sum;
  }
  std::unique_ptr<PackageTracer> owned_;
  const PackageTracer& t_;
};

}  // namespace

std::unique_ptr<Tracer> open_tracer(const PackageReader& reader, const TracerConfig& config) {
  if (config.memory_budget == 0) {
    std::unique_ptr<PackageTracer> loaded = load_package_in_core(reader);
    const PackageTracer& ref = *loaded;
    return std::make_unique<InCore>(std::move(loaded), ref);
  }
  std::unique_ptr<OutOfCoreTracer> t = open_out_of_core(reader, config.memory_budget);
  t->set_prefetch(config.prefetch);
  t->set_speculation(config.speculation);
  return t;
}

std::unique_ptr<Tracer> in_core_tracer(const PackageTracer& loaded) { return std::make_unique<InCore>(nullptr, loaded); }

}  // namespace rtp
