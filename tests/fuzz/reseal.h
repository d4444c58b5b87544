#pragma once
// Re-seals the checksums of a package image so that edits reach the structural checks: every chunk
// whose TOC entry lies inside the image gets its CRC-32C recomputed, then the TOC and header CRCs.
// Used by the package fuzz harness before each input and by tests/test_fuzz_regressions.cpp on the
// saved crash inputs (they are stored as libFuzzer found them, before re-sealing).
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "formats/package.h"
#include "package/writer.h"
#include "reader/reader.h"

namespace rtp::fuzz {

inline void reseal_package(std::vector<uint8_t>& f) {
  if (f.size() < sizeof(fmt::Header)) return;
  fmt::Header h;
  std::memcpy(&h, f.data(), sizeof h);
  const uint64_t n = f.size();
  if (h.toc_entry_size >= sizeof(fmt::TocEntry) && h.toc_offset < n && h.toc_count <= (n - h.toc_offset) / h.toc_entry_size) {
    for (uint64_t i = 0; i < h.toc_count; ++i) {
      uint8_t* entry = f.data() + h.toc_offset + i * h.toc_entry_size;
      fmt::TocEntry e;
      std::memcpy(&e, entry, sizeof e);
      if (e.offset < n && e.stored_size <= n - e.offset) {
        e.crc32c = crc32c(f.data() + e.offset, e.stored_size);
        std::memcpy(entry, &e, sizeof e);
      }
    }
    h.toc_crc32c = crc32c(f.data() + h.toc_offset, h.toc_count * h.toc_entry_size);
  }
  h.header_crc32c = crc32c(&h, offsetof(fmt::Header, header_crc32c));
  std::memcpy(f.data(), &h, sizeof h);
}

}  // namespace rtp::fuzz
