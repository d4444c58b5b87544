// LRU chunk cache under a byte budget (Molenaar 2019 §4.3); loads run as parallel TBB tasks (pread).
#include "reader/chunk_cache.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>

#include "core/error.h"

namespace rtp {

ChunkCache::ChunkCache(const PackageReader& reader, uint64_t budget_bytes) : reader_(reader), budget_(budget_bytes) {}

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
void ChunkCache::evict_until(uint64_t incoming) {
  for (auto it = lru_.end(); it != lru_.begin() && stats_.resident_bytes + incoming > budget_;) {
    --it;
    auto e = entries_.find(*it);
    if (e->second.pinned) continue;
    stats_.resident_bytes -= e->second.bytes.size();
    ++stats_.evictions;
    entries_.erase(e);
    it = lru_.erase(it);
  }
}

void ChunkCache::acquire(const std::vector<uint32_t>& toc_indices,
                         const std::function<void(uint32_t, const AlignedBytes&)>& on_load) {
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
    ++stats_.hits;
    it->second.pinned = true;
    lru_.splice(lru_.begin(), lru_, it->second.lru);  // most recently used
  }
  for (const auto& [index, e] : entries_) pinned += e.pinned ? e.bytes.size() : 0;
  if (pinned + incoming > budget_)
    throw Error(ExitCode::kUsage, "memory budget of " + std::to_string(budget_) + " bytes is too small: this round needs " +
                                      std::to_string(pinned + incoming) + " bytes of chunks at once");
  evict_until(incoming);
  if (missing.empty()) return;
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<AlignedBytes> loaded(missing.size());
  tbb::parallel_for(size_t(0), missing.size(), [&](size_t k) { loaded[k] = reader_.read(missing[k]); }, tbb::simple_partitioner());
  stats_.load_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (size_t k = 0; k < missing.size(); ++k) {
    const uint32_t i = missing[k];
    on_load(i, loaded[k]);
    stats_.bytes_read += reader_.toc()[i].stored_size;
    stats_.raw_bytes_loaded += loaded[k].size();
    ++stats_.loads;
    stats_.resident_bytes += loaded[k].size();
    lru_.push_front(i);
    Entry& e = entries_[i];
    e.bytes = std::move(loaded[k]);
    e.lru = lru_.begin();
    e.pinned = true;
  }
  stats_.peak_resident_bytes = std::max(stats_.peak_resident_bytes, stats_.resident_bytes);
}

}  // namespace rtp
