// Chunk payloads: a header, a section table, then each section's array at a 64-byte boundary.
#include "reader/chunk_io.h"

namespace rtp {

void ChunkBuilder::add_raw(fmt::SectionType type, const void* data, size_t count, size_t elem_size) {
  Pending p;
  p.e.type = uint32_t(type);
  p.e.elem_size = uint32_t(elem_size);
  p.e.count = count;
  p.e.offset = 0;
  p.bytes.assign(static_cast<const uint8_t*>(data), static_cast<const uint8_t*>(data) + count * elem_size);
  sections_.push_back(std::move(p));
}

AlignedBytes ChunkBuilder::finish() const {
  auto align = [](uint64_t v) { return (v + 63) / 64 * 64; };
  uint64_t off = align(sizeof(fmt::ChunkHeader) + sections_.size() * sizeof(fmt::SectionEntry));
  std::vector<fmt::SectionEntry> table;
  for (const auto& s : sections_) {
    fmt::SectionEntry e = s.e;
    e.offset = off;
    table.push_back(e);
    off = align(off + s.bytes.size());
  }
  // Not zero-filled and then overwritten (a convert spent 3 % of its time in that memset): each byte is
  // written once, the padding to every 64-byte boundary as zeros (the package's bytes are deterministic).
  AlignedBytes out(off);
  const fmt::ChunkHeader h{fmt::kChunkMagic, kind_, uint32_t(sections_.size()), 0};
  std::memcpy(out.data(), &h, sizeof h);
  if (!table.empty()) std::memcpy(out.data() + sizeof h, table.data(), table.size() * sizeof(fmt::SectionEntry));
  size_t written = sizeof h + table.size() * sizeof(fmt::SectionEntry);
  for (size_t i = 0; i < sections_.size(); ++i) {
    std::memset(out.data() + written, 0, table[i].offset - written);
    if (!sections_[i].bytes.empty()) std::memcpy(out.data() + table[i].offset, sections_[i].bytes.data(), sections_[i].bytes.size());
    written = table[i].offset + sections_[i].bytes.size();
  }
  std::memset(out.data() + written, 0, out.size() - written);
  return out;
}

ChunkView::ChunkView(const uint8_t* bytes, size_t size, uint32_t expected_kind, std::string label)
    : bytes_(bytes), label_(std::move(label)) {
  fmt::ChunkHeader h{};
  if (reinterpret_cast<uintptr_t>(bytes) % 64) fail_invalid(label_ + ": chunk buffer not 64-byte aligned");
  if (size < sizeof h) fail_invalid(label_ + ": too short for a chunk header");
  std::memcpy(&h, bytes, sizeof h);
  if (h.magic != fmt::kChunkMagic) fail_invalid(label_ + ": bad chunk magic");
  if (h.kind != expected_kind) fail_invalid(label_ + ": chunk says kind " + std::to_string(h.kind));
  if (h.section_count > (size - sizeof h) / sizeof(fmt::SectionEntry)) fail_invalid(label_ + ": section table out of bounds");
  sections_.resize(h.section_count);
  if (h.section_count) std::memcpy(sections_.data(), bytes + sizeof h, h.section_count * sizeof(fmt::SectionEntry));
  for (const auto& e : sections_) {
    if (e.offset % 64 || e.offset > size || e.elem_size == 0 || e.count > (size - e.offset) / e.elem_size)
      fail_invalid(label_ + ": section " + std::to_string(e.type) + " out of bounds");
  }
}

const fmt::SectionEntry* ChunkView::find(fmt::SectionType type) const {
  for (const auto& e : sections_)
    if (e.type == uint32_t(type)) return &e;
  return nullptr;
}

}  // namespace rtp
