#pragma once
// A section of a chunk's raw bytes (formats/chunk.h), found through its section table. No gtest: used
// by the tests' package patches (package_patch.h) and by the structure fuzzer (tests/fuzz/).
#include <cstdint>
#include <cstring>

#include "formats/chunk.h"

namespace rtp::test {

// The section-table entry of a section of a chunk's bytes, or null (to edit its count).
inline fmt::SectionEntry* section_entry(uint8_t* chunk, fmt::SectionType type) {
  fmt::ChunkHeader ch;
  std::memcpy(&ch, chunk, sizeof ch);
  for (uint32_t s = 0; s < ch.section_count; ++s) {
    auto* se = reinterpret_cast<fmt::SectionEntry*>(chunk + sizeof ch + s * sizeof(fmt::SectionEntry));
    if (se->type == uint32_t(type)) return se;
  }
  return nullptr;
}

// A section of a chunk's bytes (formats/chunk.h), or null.
template <class T>
inline T* section(uint8_t* chunk, fmt::SectionType type, uint64_t* count = nullptr) {
  fmt::ChunkHeader ch;
  std::memcpy(&ch, chunk, sizeof ch);
  for (uint32_t s = 0; s < ch.section_count; ++s) {
    fmt::SectionEntry se;
    std::memcpy(&se, chunk + sizeof ch + s * sizeof se, sizeof se);
    if (se.type != uint32_t(type)) continue;
    if (count) *count = se.count;
    return reinterpret_cast<T*>(chunk + se.offset);
  }
  return nullptr;
}

}  // namespace rtp::test
