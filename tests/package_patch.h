#pragma once
// Test helpers that edit package bytes behind the writer's back: a chunk re-sealed with valid CRCs so
// only the invariant checks (rtpack-inspect --verify, the readers' own checks) can catch the edit.
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "formats/chunk.h"
#include "formats/package.h"
#include "package/writer.h"
#include "reader/reader.h"
#include "chunk_sections.h"

namespace rtp::test {

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

// Rewrites the stored bytes (possibly compressed) of chunk `index` and its TOC entry, re-sealing the
// chunk CRC, the TOC CRC and the header CRC.
inline void patch_stored(const std::string& path, size_t index, const std::function<void(uint8_t*, fmt::TocEntry&)>& edit) {
  std::string f = slurp(path);
  fmt::Header h;
  std::memcpy(&h, f.data(), sizeof h);
  char* entry = f.data() + h.toc_offset + index * h.toc_entry_size;
  fmt::TocEntry e;
  std::memcpy(&e, entry, sizeof e);
  uint8_t* chunk = reinterpret_cast<uint8_t*>(f.data() + e.offset);
  edit(chunk, e);
  e.crc32c = crc32c(chunk, e.stored_size);
  std::memcpy(entry, &e, sizeof e);
  h.toc_crc32c = crc32c(f.data() + h.toc_offset, h.toc_count * h.toc_entry_size);
  h.header_crc32c = crc32c(&h, offsetof(fmt::Header, header_crc32c));
  std::memcpy(f.data(), &h, sizeof h);
  std::ofstream(path, std::ios::binary | std::ios::trunc).write(f.data(), std::streamsize(f.size()));
}

// Edits the stored bytes of uncompressed chunk `index`, then re-seals its CRC, the TOC CRC and the
// header CRC, so the container checks pass and only the invariants can catch the edit.
inline void patch_chunk(const std::string& path, size_t index, const std::function<void(uint8_t*, size_t)>& edit) {
  patch_stored(path, index, [&](uint8_t* chunk, fmt::TocEntry& e) {
    ASSERT_EQ(e.compression, uint32_t(fmt::Compression::kNone));
    edit(chunk, e.stored_size);
  });
}

// Edits the header (at offset 0), then re-seals its CRC.
inline void patch_header(const std::string& path, const std::function<void(fmt::Header&)>& edit) {
  std::string f = slurp(path);
  fmt::Header h;
  std::memcpy(&h, f.data(), sizeof h);
  edit(h);
  h.header_crc32c = crc32c(&h, offsetof(fmt::Header, header_crc32c));
  std::memcpy(f.data(), &h, sizeof h);
  std::ofstream(path, std::ios::binary | std::ios::trunc).write(f.data(), std::streamsize(f.size()));
}

}  // namespace rtp::test
