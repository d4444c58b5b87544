#pragma once
// The .rtp container's streaming writer (unnamed file linked into place, 4 KiB-aligned zstd chunks with
// CRC-32C, layout/crc32c.h). The verifying reader is lib/reader/reader.h.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/aligned.h"
#include "core/output_file.h"  // check_output_path, OutputFile
#include "formats/package.h"

namespace rtp {

// zstd's fast levels (negative, its --fast=N) go down to -131072; the options stop at -7, where the
// instance-heavy chunks already shrink little (docs/user-guide.md gives the measured trade).
inline constexpr int kMinZstdLevel = -7;

class PackageWriter {
 public:
  // Writes through an OutputFile (core/output_file.h): nothing appears at `path` before finish(),
  // and no temporary name is left by any failure or signal. Throws Error(kOutput) when it cannot.
  explicit PackageWriter(const std::string& path, int zstd_level = 9);
  ~PackageWriter();  // without finish(): nothing appears at the path
  PackageWriter(const PackageWriter&) = delete;
  PackageWriter& operator=(const PackageWriter&) = delete;

  // Compresses (zstd level != 0: 1..22, or -1..kMinZstdLevel for zstd's fast levels, its --fast=N; stores
  // raw when level == 0 or compression does not help),
  // checksums and appends one chunk at the next 4 KiB boundary. Chunks are written in call order.
  const fmt::TocEntry& add_chunk(fmt::ChunkKind kind, uint64_t id, const void* data, size_t size);
  // The same in two steps, so compression can run on other threads: compress() is thread-safe
  // and deterministic (its bytes depend on the data and the arguments, never on timing or on how many
  // threads run it); add_packed() appends in call order.
  // raw_literals: zstd stores literals as they are, without Huffman coding; min_match > 0: zstd's
  // shortest match (3..7) instead of the level's own (see ConvertOptions). workers > 0: a chunk of at
  // least kWorkersMinBytes is compressed by that many zstd threads of its own (zstd's multithreaded
  // mode, whose bytes are the same for any number of workers >= 1: still deterministic).
  static AlignedBytes compress(const void* data, size_t size, int level, fmt::Compression& used, bool raw_literals = false,
                               int min_match = 0, int workers = 0);
  static constexpr size_t kWorkersMinBytes = size_t(4) << 20;
  const fmt::TocEntry& add_packed(fmt::ChunkKind kind, uint64_t id, const AlignedBytes& stored, fmt::Compression compression,
                                  uint64_t raw_size);
  // Writes the TOC and the header (filling magic, version, file size, TOC fields and CRCs of
  // `header`), flushes, and puts the file at `path` (atomically replacing a previous one).
  void finish(fmt::Header header);

  uint64_t bytes_written() const { return offset_; }  // after finish(): the file size
  const std::vector<fmt::TocEntry>& toc() const { return toc_; }

 private:
  void write_at(uint64_t offset, const void* data, size_t size);
  OutputFile out_;
  int level_;
  uint64_t offset_ = fmt::kAlignment;
  uint64_t written_back_ = 0;  // [0, written_back_) handed to start_writeback
  std::vector<fmt::TocEntry> toc_;
  bool finished_ = false;
};

}  // namespace rtp
