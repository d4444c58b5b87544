#pragma once
// The out-of-core chunk cache (Molenaar 2019 §4.3, "the geometry cache"): decompressed on-demand chunks
// (batching points, mesh segments) held under a byte budget, least recently used first out. A caller
// acquires the chunks one scheduling round needs; they are loaded in parallel (a pool of pread
// workers: TBB tasks, each one chunk's pread + CRC + zstd) and stay pinned until release(). While a
// round traces, prefetch() reads the next round's likely chunks on a background I/O thread (pread +
// CRC + zstd), their bytes reserved in the budget before the reads start. Only unpinned chunks are
// evicted, and resident plus in-flight bytes never exceed the budget: acquire() refuses a set that
// cannot fit beside the pinned ones. Not thread-safe: one scheduler drives it.
#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <unordered_map>
#include <vector>

#include "core/aligned.h"
#include "reader/reader.h"

namespace rtp {

struct ChunkCacheStats {
  uint64_t requests = 0;    // chunks asked for by acquire()
  uint64_t hits = 0;        // of those, already resident
  uint64_t loads = 0;       // chunks read from the file (misses)
  uint64_t bytes_read = 0;  // stored (compressed) bytes of those reads
  uint64_t raw_bytes_loaded = 0;
  uint64_t evictions = 0;
  uint64_t prefetched = 0;           // of the loads, read ahead on the I/O thread while a round traced
  uint64_t resident_bytes = 0;       // decompressed bytes held now (a reused buffer may hold up to 1/16
                                     // more: allocator slack, in the peak RSS, not in the budget)
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
  // Makes every chunk of `toc_indices` resident and pinned (duplicates allowed). Every chunk newly read
  // (or read ahead) is passed to `on_load` (index, bytes) before acquire() returns, so a caller can check
  // and decode it; on_load runs concurrently on TBB workers, once per chunk, and must be safe for distinct
  // indices. When it throws, acquire() throws and the chunks of that call are dropped.
  // Throws Error(kUsage) when the pinned chunks and these cannot fit in the budget.
  void acquire(const std::vector<uint32_t>& toc_indices, const std::function<void(uint32_t, const AlignedBytes&)>& on_load);
  // The bytes of a resident chunk (valid until it is evicted: not before the next acquire()).
  const AlignedBytes& bytes(uint32_t toc_index) const;
  bool resident(uint32_t toc_index) const { return entries_.count(toc_index) != 0; }
  // Unpins everything acquired so far (the chunks stay resident until evicted).
  void release();
  // Starts reading those of `toc_indices` that are neither resident nor in flight, as many as fit in
  // the budget beside the resident pinned chunks (unpinned ones are evicted for them, least recently
  // used first), in the given order, on a background thread. The next acquire() waits for them and
  // passes them to its on_load like any other loaded chunk (prefetched chunks count as loads).
  void prefetch(const std::vector<uint32_t>& toc_indices);
  ~ChunkCache();
  const ChunkCacheStats& stats() const { return stats_; }

 private:
  struct Entry {
    AlignedBytes bytes;
    std::list<uint32_t>::iterator lru;  // position in lru_ (front = most recently used)
    bool pinned = false;
  };
  // Evicts least recently used unpinned chunks until `incoming` bytes fit; their buffers go to `recycle`
  // when given (acquire() reads the new chunks into them), else are freed.
  void evict_until(uint64_t incoming, std::vector<AlignedBytes>* recycle = nullptr);
  void join_prefetch();  // waits for the background reads; rethrows their error
  void insert(uint32_t index, AlignedBytes bytes, bool pinned);

  std::vector<uint32_t> staged_indices_;  // read ahead, joined, not yet inserted
  std::vector<AlignedBytes> staged_bytes_;
  struct Prefetch;
  std::unique_ptr<Prefetch> prefetch_;
  uint64_t in_flight_ = 0;  // bytes reserved by the running prefetch
  const PackageReader& reader_;
  uint64_t budget_;
  std::unordered_map<uint32_t, Entry> entries_;
  std::list<uint32_t> lru_;
  ChunkCacheStats stats_;
};

}  // namespace rtp
