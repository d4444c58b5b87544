// Chunk payloads: a header, a section table, then each section's array at a 64-byte boundary.
#include "layout/chunk_io.h"

namespace rtp {

const char* chunk_kind_name(uint32_t kind) {
  switch (fmt::ChunkKind(kind)) {
    case fmt::ChunkKind::kMetadata: return "metadata";
    case fmt::ChunkKind::kTopLevelBvh: return "top-level BVH";
    case fmt::ChunkKind::kBatchingPoints: return "batching-point descriptors";
    case fmt::ChunkKind::kInstances: return "instance table";
    case fmt::ChunkKind::kMeshes: return "mesh table";
    case fmt::ChunkKind::kSourceMap: return "source map";
    case fmt::ChunkKind::kDagPool: return "DAG pool";
    case fmt::ChunkKind::kBatchingPoint: return "batching point";
    case fmt::ChunkKind::kMeshSegment: return "mesh segment";
    case fmt::ChunkKind::kSegmentAttributes: return "mesh segment attributes";
    case fmt::ChunkKind::kPointAttributes: return "batching point attributes";
  }
  return "unknown kind";
}

std::string chunk_label(const fmt::TocEntry& e, size_t i) {
  return std::string(chunk_kind_name(e.kind)) + " " + std::to_string(e.id) + " (chunk #" + std::to_string(i) + " at offset " +
         std::to_string(e.offset) + ")";
}

void ChunkBuilder::add_raw(fmt::SectionType type, const void* data, size_t count, size_t elem_size) {
  begin_section(type, elem_size);
  append_to_section(data, count);
}

void ChunkBuilder::begin_section(fmt::SectionType type, size_t elem_size) {
  Pending p;
  p.e.type = uint32_t(type);
  p.e.elem_size = uint32_t(elem_size);
  p.e.count = 0;
  p.e.offset = 0;
  sections_.push_back(std::move(p));
}

void ChunkBuilder::append_to_section(const void* data, size_t count) {
  if (sections_.empty()) throw Error(ExitCode::kInternal, "ChunkBuilder: append_to_section before begin_section");
  Pending& p = sections_.back();
  p.e.count += count;
  if (count) p.pieces.push_back({static_cast<const uint8_t*>(data), count * size_t(p.e.elem_size)});
}

void ChunkBuilder::add_reserved(fmt::SectionType type, size_t count, size_t elem_size) {
  begin_section(type, elem_size);
  Pending& p = sections_.back();
  p.e.count = count;
  if (count) p.pieces.push_back({nullptr, count * elem_size});
}

uint8_t* ChunkBuilder::section_data(AlignedBytes& chunk, size_t index) {
  fmt::ChunkHeader h{};
  if (chunk.size() < sizeof h) throw Error(ExitCode::kInternal, "ChunkBuilder::section_data: no chunk");
  std::memcpy(&h, chunk.data(), sizeof h);
  if (index >= h.section_count) throw Error(ExitCode::kInternal, "ChunkBuilder::section_data: no such section");
  fmt::SectionEntry e{};
  std::memcpy(&e, chunk.data() + sizeof h + index * sizeof e, sizeof e);
  return chunk.data() + e.offset;
}

namespace {
uint64_t align64(uint64_t v) { return (v + 63) / 64 * 64; }
}  // namespace

uint64_t ChunkBuilder::size() const {
  uint64_t off = align64(sizeof(fmt::ChunkHeader) + sections_.size() * sizeof(fmt::SectionEntry));
  for (const auto& s : sections_) off = align64(off + s.e.count * s.e.elem_size);
  return off;
}

AlignedBytes ChunkBuilder::finish() const {
  AlignedBytes out;
  finish_into(out);
  return out;
}

void ChunkBuilder::finish_into(AlignedBytes& out) const {
  uint64_t off = align64(sizeof(fmt::ChunkHeader) + sections_.size() * sizeof(fmt::SectionEntry));
  std::vector<fmt::SectionEntry> table;
  table.reserve(sections_.size());
  for (const auto& s : sections_) {
    fmt::SectionEntry e = s.e;
    e.offset = off;
    table.push_back(e);
    off = align64(off + e.count * e.elem_size);
  }
  // Not zero-filled and then overwritten (a convert spent 3 % of its time in that memset): each byte is
  // written once, the padding to every 64-byte boundary as zeros (the package's bytes are deterministic).
  out.resize(off);
  const fmt::ChunkHeader h{fmt::kChunkMagic, kind_, uint32_t(sections_.size()), 0};
  std::memcpy(out.data(), &h, sizeof h);
  if (!table.empty()) std::memcpy(out.data() + sizeof h, table.data(), table.size() * sizeof(fmt::SectionEntry));
  size_t written = sizeof h + table.size() * sizeof(fmt::SectionEntry);
  for (size_t i = 0; i < sections_.size(); ++i) {
    std::memset(out.data() + written, 0, table[i].offset - written);
    written = table[i].offset;
    for (const Piece& piece : sections_[i].pieces) {
      if (piece.data) std::memcpy(out.data() + written, piece.data, piece.bytes);  // null: add_reserved
      written += piece.bytes;
    }
  }
  std::memset(out.data() + written, 0, out.size() - written);
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
