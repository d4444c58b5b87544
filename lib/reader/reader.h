#pragma once
// The .rtp container as the reader sees it (formats/SPEC.md §1–3): header and TOC verified on open,
// chunks read with pread (optional O_DIRECT), CRC-32C checked and zstd-decompressed on demand. The
// chunk *contents* are defined by the modules that produce them; this only finds and checks bytes.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/aligned.h"
#include "formats/package.h"
#include "layout/chunk_io.h"  // chunk_label, ChunkView
#include "layout/crc32c.h"

namespace rtp {

class PackageReader {
 public:
  // Opens (never blocking: a FIFO or any other non-regular file is rejected, exit 3) and verifies the header and TOC (magic, version, sizes, CRCs, every entry inside the file
  // and 4 KiB aligned). Throws Error(kInputInvalid) naming what is wrong; kInputIo when unreadable.
  explicit PackageReader(const std::string& path, bool direct_io = false);
  ~PackageReader();
  PackageReader(const PackageReader&) = delete;
  PackageReader& operator=(const PackageReader&) = delete;

  const fmt::Header& header() const { return header_; }
  const std::vector<fmt::TocEntry>& toc() const { return toc_; }
  bool direct_io() const { return direct_; }  // false if O_DIRECT was asked for but unavailable

  // Index of the chunk (kind, id) in toc(), or -1.
  int64_t find(fmt::ChunkKind kind, uint64_t id) const;
  // Reads, checks the CRC and decompresses chunk toc()[index] into a 64-byte aligned buffer.
  // Throws naming the chunk.
  AlignedBytes read(size_t index) const;
  // The same into `out`, reusing its capacity (the chunk cache recycles evicted buffers: no fresh pages
  // to fault in and zero). On a throw `out` holds garbage.
  void read_into(size_t index, AlignedBytes& out) const;
  // Reads and checks the CRC only (no decompression).
  void verify(size_t index) const;
  // The element count of section `type` of chunk toc()[index] (elements of `elem_size` bytes, inside
  // the chunk's raw_size), or 0 when the chunk has no such section. Streams the chunk in 1 MiB pieces:
  // the CRC covers all of it but only the chunk and section headers are decompressed, so a large
  // resident table (the instance table) is counted without ever being held (chunk_prefix.cpp).
  uint64_t section_count(size_t index, uint32_t type, uint32_t elem_size) const;
  // The offset of the first non-zero byte of [offset, offset + size) of the file, or kAllZero.
  static constexpr uint64_t kAllZero = ~uint64_t(0);
  uint64_t first_nonzero(uint64_t offset, uint64_t size) const;

  // A chunk's raw_size is at most kMaxChunkRatio * stored_size + kMaxChunkSlack (formats/SPEC.md §3):
  // checked before any memory is committed. 32768 is what zstd itself can reach (a 128 KiB RLE block in
  // 4 bytes): 1024 refused the converter's own source map of a 12 M-triangle generated forest (1740x).
  static constexpr uint64_t kMaxChunkRatio = 32768;
  static constexpr uint64_t kMaxChunkSlack = uint64_t(1) << 20;

 private:
  AlignedBytes read_stored(size_t index) const;
  // Into `out` (resized to the stored size, its capacity reused).
  void read_stored_into(size_t index, AlignedBytes& out) const;
  std::string path_;
  void check_header_and_toc();                                    // the constructor's checks (it closes fd_ when they throw)
  static void check_sizes(const fmt::TocEntry& e, size_t index);  // raw_size against stored_size
  int fd_ = -1;
  bool direct_ = false;
  uint64_t file_size_ = 0;
  fmt::Header header_{};
  std::vector<fmt::TocEntry> toc_;
};

}  // namespace rtp
