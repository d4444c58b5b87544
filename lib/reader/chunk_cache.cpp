// LRU chunk cache under a byte budget (Molenaar 2019 §4.3); loads run as parallel TBB tasks (pread).
#include "reader/chunk_cache.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <numeric>
#include <chrono>
#include <exception>
#include <thread>

#include "core/error.h"

namespace rtp {

struct ChunkCache::Prefetch {
  std::vector<uint32_t> indices;
  std::vector<AlignedBytes> bytes;
  std::exception_ptr error;
  std::thread thread;
};

namespace {
constexpr uint64_t kSlack = 16;  // a recycled buffer holds at most 1/kSlack more than its chunk
}  // namespace

ChunkCache::ChunkCache(const PackageReader& reader, uint64_t budget_bytes) : reader_(reader), budget_(budget_bytes) {}

ChunkCache::~ChunkCache() {
  if (prefetch_ && prefetch_->thread.joinable()) prefetch_->thread.join();
}

void ChunkCache::join_prefetch() {
  if (!prefetch_) return;
  prefetch_->thread.join();
  std::unique_ptr<Prefetch> p = std::move(prefetch_);
  in_flight_ = 0;
  if (p->error) std::rethrow_exception(p->error);
  staged_indices_ = std::move(p->indices);
  staged_bytes_ = std::move(p->bytes);
}

void ChunkCache::prefetch(const std::vector<uint32_t>& toc_indices) {
  join_prefetch();  // (none runs here: acquire() joined it)
  uint64_t pinned = 0;
  for (const auto& [index, e] : entries_) pinned += e.pinned ? e.bytes.size() : 0;
  for (uint32_t i : staged_indices_) pinned += cost(i);
  auto p = std::make_unique<Prefetch>();
  uint64_t bytes = 0;
  for (uint32_t i : toc_indices) {
    if (entries_.count(i) || std::find(p->indices.begin(), p->indices.end(), i) != p->indices.end() ||
        std::find(staged_indices_.begin(), staged_indices_.end(), i) != staged_indices_.end())
      continue;
    if (pinned + bytes + cost(i) > budget_) break;  // in order: the likeliest first
    p->indices.push_back(i);
    bytes += cost(i);
  }
  if (p->indices.empty()) return;
  evict_until(bytes);
  if (stats_.resident_bytes + bytes > budget_) return;  // pinned chunks leave no room: no prefetch
  in_flight_ = bytes;
  stats_.peak_resident_bytes = std::max(stats_.peak_resident_bytes, stats_.resident_bytes + in_flight_);
  p->bytes.resize(p->indices.size());
  Prefetch* raw = p.get();
  const PackageReader* reader = &reader_;
  p->thread = std::thread([raw, reader] {
    try {
      for (size_t k = 0; k < raw->indices.size(); ++k) raw->bytes[k] = reader->read(raw->indices[k]);
    } catch (...) {
      raw->error = std::current_exception();
    }
  });
  prefetch_ = std::move(p);
}

const AlignedBytes& ChunkCache::bytes(uint32_t toc_index) const {
  const auto it = entries_.find(toc_index);
  if (it == entries_.end())
    throw Error(ExitCode::kInternal, chunk_label(reader_.toc()[toc_index], toc_index) + " is not resident in the cache");
  return it->second.bytes;
}

void ChunkCache::release() {
  for (auto& [index, e] : entries_) e.pinned = false;
}

// Least recently used first, pinned chunks skipped, until `incoming` more bytes fit in the budget.
void ChunkCache::evict_until(uint64_t incoming, std::vector<AlignedBytes>* recycle) {
  for (auto it = lru_.end(); it != lru_.begin() && stats_.resident_bytes + in_flight_ + incoming > budget_;) {
    --it;
    auto e = entries_.find(*it);
    if (e->second.pinned) continue;
    stats_.resident_bytes -= e->second.bytes.size();
    ++stats_.evictions;
    if (recycle) recycle->push_back(std::move(e->second.bytes));
    entries_.erase(e);
    it = lru_.erase(it);
  }
}

void ChunkCache::insert(uint32_t i, AlignedBytes bytes, bool pinned) {
  stats_.bytes_read += reader_.toc()[i].stored_size;
  stats_.raw_bytes_loaded += bytes.size();
  ++stats_.loads;
  stats_.resident_bytes += bytes.size();
  lru_.push_front(i);
  Entry& e = entries_[i];
  e.bytes = std::move(bytes);
  e.lru = lru_.begin();
  e.pinned = pinned;
}

void ChunkCache::acquire(const std::vector<uint32_t>& toc_indices,
                         const std::function<void(uint32_t, const AlignedBytes&)>& on_load) {
  const auto t_wait = std::chrono::steady_clock::now();
  join_prefetch();
  stats_.load_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t_wait).count();
  // What the I/O thread read ahead becomes resident (unpinned) like any other load; a request for it
  // below is a miss that did not wait, not a hit.
  std::vector<uint32_t> staged = std::move(staged_indices_);
  tbb::parallel_for(
      size_t(0), staged.size(), [&](size_t k) { on_load(staged[k], staged_bytes_[k]); }, tbb::simple_partitioner());
  for (size_t k = 0; k < staged.size(); ++k) {
    insert(staged[k], std::move(staged_bytes_[k]), false);
    ++stats_.prefetched;
  }
  staged_indices_.clear();
  staged_bytes_.clear();
  std::sort(staged.begin(), staged.end());
  std::vector<uint32_t> want(toc_indices);
  std::sort(want.begin(), want.end());
  want.erase(std::unique(want.begin(), want.end()), want.end());
  std::vector<uint32_t> missing;
  uint64_t incoming = 0, pinned = 0;
  for (uint32_t i : want) {
    ++stats_.requests;
    auto it = entries_.find(i);
    if (it == entries_.end()) {
      missing.push_back(i);
      incoming += cost(i);
      continue;
    }
    if (!std::binary_search(staged.begin(), staged.end(), i)) ++stats_.hits;
    it->second.pinned = true;
    lru_.splice(lru_.begin(), lru_, it->second.lru);  // most recently used
  }
  for (const auto& [index, e] : entries_) pinned += e.pinned ? e.bytes.size() : 0;
  if (pinned + incoming > budget_)
    throw Error(ExitCode::kUsage, "memory budget of " + std::to_string(budget_) + " bytes is too small: this round needs " +
                                      std::to_string(pinned + incoming) + " bytes of chunks at once");
  // The evicted chunks' buffers take the new ones (the smallest that fits, at most 1/kSlack larger) as they
  // are; the unused ones are freed before the reads, and allocate_large moves their pages into the new
  // buffers (core/aligned.h), so memory never holds both and no page is zeroed again.
  std::vector<AlignedBytes> spare;
  evict_until(incoming, &spare);
  if (missing.empty()) return;
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<AlignedBytes> loaded(missing.size());
  for (size_t k = 0; k < missing.size(); ++k) {
    const uint64_t need = cost(missing[k]);
    size_t best = spare.size();
    for (size_t j = 0; j < spare.size(); ++j)
      if (spare[j].capacity() >= need && spare[j].capacity() <= need + need / kSlack &&
          (best == spare.size() || spare[j].capacity() < spare[best].capacity()))
        best = j;
    if (best == spare.size()) continue;
    loaded[k] = std::move(spare[best]);
    spare[best] = std::move(spare.back());
    spare.pop_back();
  }
  spare.clear();
  spare.shrink_to_fit();
  // Largest first, each worker taking the next chunk as it finishes one (greedy longest-processing-time
  // order): a round loads a handful of chunks of 20-50 MB on few cores, and a big chunk started last left
  // the other cores idle while it decompressed.
  std::vector<size_t> by_size(missing.size());
  std::iota(by_size.begin(), by_size.end(), size_t(0));
  std::stable_sort(by_size.begin(), by_size.end(), [&](size_t a, size_t b) { return cost(missing[a]) > cost(missing[b]); });
  std::atomic<size_t> next{0};
  const size_t workers = std::min<size_t>(size_t(std::max(1, tbb::this_task_arena::max_concurrency())), missing.size());
  tbb::parallel_for(
      size_t(0), workers,
      [&](size_t) {
        for (size_t j = next++; j < by_size.size(); j = next++) {
          const size_t k = by_size[j];
          reader_.read_into(missing[k], loaded[k]);
          on_load(missing[k], loaded[k]);
        }
      },
      tbb::simple_partitioner());
  stats_.load_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  release_kept_large();  // evicted buffers no load took: memory is back to what the budget counts
  for (size_t k = 0; k < missing.size(); ++k) insert(missing[k], std::move(loaded[k]), true);
  stats_.peak_resident_bytes = std::max(stats_.peak_resident_bytes, stats_.resident_bytes);
}

}  // namespace rtp
