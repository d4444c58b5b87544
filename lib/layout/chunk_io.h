#pragma once
// Chunk framing shared by the writer and the reader (formats/chunk.h, SPEC §3): typed sections built and
// parsed as bounds-checked views, and the names chunks go by in messages.
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "core/aligned.h"
#include "core/error.h"
#include "formats/chunk.h"
#include "formats/package.h"

namespace rtp {

// A readable name for a chunk in messages: "batching point 12 (chunk #30 at offset 4096)".
std::string chunk_label(const fmt::TocEntry& e, size_t toc_index);
const char* chunk_kind_name(uint32_t kind);

class ChunkBuilder {
 public:
  explicit ChunkBuilder(uint32_t kind) : kind_(kind) {}
  // Sections are borrowed, not copied: each array must stay alive and unchanged until finish() has
  // returned (copying them in first was 6 % of a FlightHelmet convert, faults included). A temporary
  // would dangle, so it does not compile.
  template <class T>
  void add(fmt::SectionType type, const std::vector<T>& v) {
    add_raw(type, v.data(), v.size(), sizeof(T));
  }
  template <class T>
  void add(fmt::SectionType type, std::vector<T>&& v) = delete;
  void add_raw(fmt::SectionType type, const void* data, size_t count, size_t elem_size);
  // One section gathered from several borrowed arrays, in call order: begin_section, then one
  // append_to_section per array (e.g. each piece's BVH nodes, without concatenating them first).
  void begin_section(fmt::SectionType type, size_t elem_size);
  void append_to_section(const void* data, size_t count);
  // A section whose `count` elements the caller writes into the finished chunk itself (section_data):
  // finish() leaves its bytes unwritten. For a large array computed in place rather than copied in
  // (the instance table of a 10^6-instance forest: 19 MB less to fault in and copy).
  void add_reserved(fmt::SectionType type, size_t count, size_t elem_size);
  // Where section `index` (in add order) starts in a chunk finish() laid out.
  static uint8_t* section_data(AlignedBytes& chunk, size_t index);
  uint64_t size() const;  // the chunk's bytes, as finish() lays them out
  AlignedBytes finish() const;
  // The same bytes into `out` (resized to size()): a buffer reused chunk after chunk keeps its pages.
  void finish_into(AlignedBytes& out) const;

 private:
  struct Piece {
    const uint8_t* data;
    size_t bytes;
  };
  struct Pending {
    fmt::SectionEntry e;
    std::vector<Piece> pieces;
  };
  uint32_t kind_;
  std::vector<Pending> sections_;
};

// A parsed chunk: every section inside the buffer, 64-byte aligned, element sizes as expected.
class ChunkView {
 public:
  // `label` names the chunk in error messages (e.g. "batching point 3 (chunk #7 ...)").
  // `bytes` must be 64-byte aligned (AlignedBytes) and outlive the view.
  ChunkView(const uint8_t* bytes, size_t size, uint32_t expected_kind, std::string label);
  bool has(fmt::SectionType type) const { return find(type) != nullptr; }
  template <class T>
  const T* get(fmt::SectionType type, uint64_t& count, bool required = true) const {
    return static_cast<const T*>(get_raw(type, sizeof(T), count, required));
  }
  // The same for elements whose type is chosen at run time (e.g. WideNode<W> of the header's W).
  const void* get_raw(fmt::SectionType type, size_t elem_size, uint64_t& count, bool required = true) const {
    const fmt::SectionEntry* e = find(type);
    if (!e) {
      if (required) fail_invalid(label_ + ": missing section " + std::to_string(uint32_t(type)));
      count = 0;
      return nullptr;
    }
    if (e->elem_size != elem_size)
      fail_invalid(label_ + ": section " + std::to_string(uint32_t(type)) + " has elements of " + std::to_string(e->elem_size) +
                   " bytes, expected " + std::to_string(elem_size));
    count = e->count;
    return bytes_ + e->offset;
  }
  template <class T>
  std::vector<T> copy(fmt::SectionType type, bool required = true) const {
    uint64_t n = 0;
    const T* p = get<T>(type, n, required);
    std::vector<T> out(n);
    if (n) std::memcpy(out.data(), p, n * sizeof(T));
    return out;
  }
  const std::string& label() const { return label_; }

 private:
  const fmt::SectionEntry* find(fmt::SectionType type) const;
  const uint8_t* bytes_;
  std::vector<fmt::SectionEntry> sections_;
  std::string label_;
};

}  // namespace rtp
