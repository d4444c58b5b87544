#pragma once
// CRC-32C (Castagnoli), the checksum of every chunk, the TOC and the header (formats/SPEC.md §1):
// written by lib/package, checked by lib/reader.
#include <cstddef>
#include <cstdint>

namespace rtp {

// Hardware-accelerated (SSE4.2) with a table fallback; crc32c_portable is the table alone (the
// reference the tests compare against).
uint32_t crc32c(const void* data, size_t size, uint32_t crc = 0);
uint32_t crc32c_portable(const void* data, size_t size, uint32_t crc = 0);

}  // namespace rtp
