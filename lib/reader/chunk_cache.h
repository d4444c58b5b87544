#pragma once
// The out-of-core chunk cache (Molenaar 2019 §4.3, "the geometry cache"): decompressed on-demand chunks
// (batching points, mesh segments) held under a byte budget, least recently used first out. A caller
// acquires the chunks one scheduling round needs; they are loaded in parallel (a pool of pread
// workers: TBB tasks, each one chunk's pread + CRC + zstd) and stay pinned until release(). Only
// unpinned chunks are evicted, and the resident bytes never exceed the budget: acquire() refuses a set
// that cannot fit beside the pinned ones. Not thread-safe: one scheduler drives it.
#include <cstdint>
#include <functional>
#include <list>
#include <unordered_map>
#include <vector>

#include "core/aligned.h"
#include "reader/container.h"

namespace rtp {

struct ChunkCacheStats {
  uint64_t requests = 0;       // chunks asked for by acquire()
  uint64_t hits = 0;           // of those, already resident
  uint64_t loads = 0;          // chunks read from the file (misses)
  uint64_t bytes_read = 0;     // stored (compressed) bytes of those reads
  uint64_t raw_bytes_loaded = 0;
  uint64_t evictions = 0;
  uint64_t resident_bytes = 0;       // decompressed bytes held now
  uint64_t peak_resident_bytes = 0;  // the most ever held at once (≤ the budget)
  double load_seconds = 0;           // wall time inside acquire() loading
  double hit_rate() const { return requests ? double(hits) / double(requests) : 0.0; }
};

class ChunkCache {
 public:
  ChunkCache(const PackageReader& reader, uint64_t budget_bytes);
  uint64_t budget() const { return budget_; }
  // The bytes a chunk occupies when resident (its raw size).
  uint64_t cost(uint32_t toc_index) const { return reader_.toc()[toc_index].raw_size; }
  // Makes every chunk of `toc_indices` resident and pinned (duplicates allowed). Chunks newly read are
  // passed to `on_load` (index, bytes) on the calling thread in ascending index order before
  // acquire() returns, so a caller can check and decode them; if it throws, the chunk is dropped.
  // Throws Error(kUsage) when the pinned chunks and these cannot fit in the budget.
  void acquire(const std::vector<uint32_t>& toc_indices,
               const std::function<void(uint32_t, const AlignedBytes&)>& on_load);
  // The bytes of a resident chunk (valid until it is evicted: not before the next acquire()).
  const AlignedBytes& bytes(uint32_t toc_index) const;
  bool resident(uint32_t toc_index) const { return entries_.count(toc_index) != 0; }
  // Unpins everything acquired so far (the chunks stay resident until evicted).
  void release();
  const ChunkCacheStats& stats() const { return stats_; }

 private:
  struct Entry {
    AlignedBytes bytes;
    std::list<uint32_t>::iterator lru;  // position in lru_ (front = most recently used)
    bool pinned = false;
  };
  void evict_until(uint64_t incoming);
  const PackageReader& reader_;
  uint64_t budget_;
  std::unordered_map<uint32_t, Entry> entries_;
  std::list<uint32_t> lru_;
  ChunkCacheStats stats_;
};

}  // namespace rtp
