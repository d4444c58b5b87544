#pragma once
// An open-addressing hash index for the DAG builders' unique-node and unique-leaf tables (Kämpe et
// al. 2013 §3.1: one table of unique nodes, looked up bottom-up). The keys live in the caller's own
// arrays (the DAG's words and leaves); the index stores only (hash, value) pairs, so a lookup
// allocates nothing and a table of millions of nodes is two flat arrays, not a node per entry.
#include <cstdint>
#include <utility>
#include <vector>

namespace rtp::voxel {

// splitmix64's finalizer: every input bit reaches every output bit.
inline uint64_t mix64(uint64_t x) {
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ull;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// Hash of a word sequence with a tag (e.g. a node's level).
inline uint64_t hash_words(const uint32_t* w, size_t n, uint64_t tag) {
  uint64_t h = mix64(tag + 0x9e3779b97f4a7c15ull * (n + 1));
  for (size_t i = 0; i < n; ++i) h = mix64(h ^ w[i]);
  return h;
}

class HashIndex {
 public:
  // The value of an entry whose hash is `h` and for which `same(value)` holds, with false; otherwise
  // `fresh_value` is entered and returned with true. Which equal entry is found never depends on the
  // table's size: values are the caller's offsets, and equal keys are entered once.
  template <class Same>
  std::pair<uint32_t, bool> find_or_insert(uint64_t h, Same&& same, uint32_t fresh_value) {
    if (2 * (count_ + 1) > slots_.size()) grow();
    const uint32_t tag = uint32_t(h >> 32) | 1u;  // never 0: 0 marks an empty slot
    size_t mask = slots_.size() - 1, i = size_t(h) & mask;
    for (;; i = (i + 1) & mask) {
      const uint64_t s = slots_[i];
      if (s == 0) break;
      if (uint32_t(s >> 32) == tag && same(uint32_t(s))) return {uint32_t(s), false};
    }
    slots_[i] = uint64_t(tag) << 32 | fresh_value;
    hashes_low_[i] = uint32_t(h);
    ++count_;
    return {fresh_value, true};
  }
  size_t size() const { return count_; }

 private:
  void grow() {
    const size_t n = slots_.empty() ? 1024 : slots_.size() * 2;
    std::vector<uint64_t> old = std::move(slots_);
    std::vector<uint32_t> old_low = std::move(hashes_low_);
    slots_.assign(n, 0);
    hashes_low_.assign(n, 0);
    for (size_t k = 0; k < old.size(); ++k) {
      if (!old[k]) continue;
      size_t i = old_low[k] & (n - 1);
      while (slots_[i]) i = (i + 1) & (n - 1);
      slots_[i] = old[k];
      hashes_low_[i] = old_low[k];
    }
  }
  std::vector<uint64_t> slots_;       // (high 32 bits of the hash | 1) << 32 | value; 0 = empty
  std::vector<uint32_t> hashes_low_;  // the low 32 bits (the probe start), kept for growing
  size_t count_ = 0;
};

}  // namespace rtp::voxel
