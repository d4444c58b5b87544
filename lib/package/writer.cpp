// Streaming package writer: chunks go to an unnamed output file (core/output_file.h) as they come,
// each zstd-compressed, CRC-32C checksummed and 4 KiB aligned; the TOC and header are written last;
// the file appears at its path only once complete.
#define ZSTD_STATIC_LINKING_ONLY
#include <zstd.h>
#include <memory>

#include <cstring>

#include "core/error.h"
#include "layout/crc32c.h"
#include "package/writer.h"

namespace rtp {

constexpr uint64_t kWritebackBytes = uint64_t(1) << 20;

PackageWriter::PackageWriter(const std::string& path, int zstd_level) : out_(path), level_(zstd_level) {
  if (zstd_level < kMinZstdLevel || zstd_level > ZSTD_maxCLevel())
    throw Error(ExitCode::kUsage, "--zstd-level " + std::to_string(zstd_level) + ": must be " + std::to_string(kMinZstdLevel) +
                                      ".." + std::to_string(ZSTD_maxCLevel()) +
                                      " (0 stores raw, negative levels are zstd's fast ones)");
}

PackageWriter::~PackageWriter() = default;

void PackageWriter::write_at(uint64_t offset, const void* data, size_t size) { out_.write_at(offset, data, size); }
AlignedBytes PackageWriter::compress(const void* data, size_t size, int level, fmt::Compression& used, bool raw_literals,
                                     int min_match, int workers) {
  used = fmt::Compression::kNone;
  if (level != 0 && size > 0) {  // negative: zstd's fast levels (--fast=N)
    // A per-thread scratch of compressBound bytes, reused, never zero-filled (AlignedBytes): a fresh
    // zero-filled one per chunk was faulted in and cleared every time (2 % of a convert in memset alone).
    thread_local AlignedBytes scratch;
    if (scratch.size() < ZSTD_compressBound(size)) {
      scratch = AlignedBytes();  // not resize: that would copy the old bytes over
      scratch.resize(ZSTD_compressBound(size));
    }
    // One context per thread, reused: a fresh one per chunk allocated and cleared its tables every time.
    thread_local std::unique_ptr<ZSTD_CCtx, size_t (*)(ZSTD_CCtx*)> ctx(ZSTD_createCCtx(), ZSTD_freeCCtx);
    if (!ctx) throw std::bad_alloc();
    ZSTD_CCtx* cctx = ctx.get();
    ZSTD_CCtx_reset(cctx, ZSTD_reset_session_and_parameters);
    ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, level);
    // ZSTD_c_literalCompressionMode is in zstd's experimental API (ZSTD_STATIC_LINKING_ONLY), stable in
    // the shared library since 1.4.5 (Debian 12 ships 1.5.4); a library that refuses it leaves the
    // default, which only makes the package a little smaller and its loads slower.
    if (raw_literals) ZSTD_CCtx_setParameter(cctx, ZSTD_c_literalCompressionMode, ZSTD_ps_disable);
    // zstd's fast levels (1 and below) hash every position into a table that the context clears per
    // frame and that misses L1 above 4 KiB: 2^10 entries below 1 MiB, 2^12 above (forest points 255-283
    // MB/s against 204 at zstd's own choice; docs/notes/2026-12-07-writer-measurements.md §6).
    if (level <= 1) ZSTD_CCtx_setParameter(cctx, ZSTD_c_hashLog, size < (size_t(1) << 20) ? 10 : 12);
    // A libzstd built without threads refuses this and compresses the frame itself: the same bytes for
    // any --threads still (Debian's has them).
    if (workers > 0 && size >= kWorkersMinBytes) (void)ZSTD_CCtx_setParameter(cctx, ZSTD_c_nbWorkers, workers);
    if (min_match > 0) {
      const size_t r = ZSTD_CCtx_setParameter(cctx, ZSTD_c_minMatch, min_match);
      if (ZSTD_isError(r))
        throw Error(ExitCode::kUsage, "zstd minimum match " + std::to_string(min_match) + ": " + ZSTD_getErrorName(r));
    }
    const size_t n = ZSTD_compress2(cctx, scratch.data(), scratch.size(), data, size);
    if (ZSTD_isError(n)) throw Error(ExitCode::kInternal, std::string("zstd: ") + ZSTD_getErrorName(n));
    if (n < size) {  // stored raw when compression does not help
      used = fmt::Compression::kZstd;
      if (n >= kHugeThreshold) {
        // A large frame leaves in the scratch itself (its untouched tail is address space only), not
        // copied into a fresh buffer (a 4.x 10^6-record instance table's 69 MB frame was both).
        AlignedBytes out = std::move(scratch);
        scratch = AlignedBytes();
        out.resize(n);
        return out;
      }
      return AlignedBytes(scratch.begin(), scratch.begin() + std::ptrdiff_t(n));
    }
  }
  const uint8_t* p = static_cast<const uint8_t*>(data);
  return AlignedBytes(p, p + size);
}

const fmt::TocEntry& PackageWriter::add_packed(fmt::ChunkKind kind, uint64_t id, const AlignedBytes& stored,
                                               fmt::Compression compression, uint64_t raw_size) {
  fmt::TocEntry e{};
  e.kind = uint32_t(kind);
  e.compression = uint32_t(compression);
  e.id = id;
  e.offset = offset_;
  e.stored_size = stored.size();
  e.raw_size = raw_size;
  e.crc32c = crc32c(stored.data(), stored.size());
  write_at(offset_, stored.data(), stored.size());
  offset_ = (offset_ + stored.size() + fmt::kAlignment - 1) / fmt::kAlignment * fmt::kAlignment;
  // The chunks are flushed to the disk (fdatasync on a thread of OutputFile's own) while later ones are
  // built, each time another MiB is written: the final fsync of forest-1m's 123 MB fell from 314-366 ms
  // to 7 (docs/notes/2026-12-07-writer-measurements.md §7).
  if (offset_ - written_back_ >= kWritebackBytes) {
    out_.start_writeback();
    written_back_ = offset_;
  }
  toc_.push_back(e);
  return toc_.back();
}

const fmt::TocEntry& PackageWriter::add_chunk(fmt::ChunkKind kind, uint64_t id, const void* data, size_t size) {
  fmt::Compression c;
  const AlignedBytes stored = compress(data, size, level_, c);
  return add_packed(kind, id, stored, c, size);
}

void PackageWriter::finish(fmt::Header h) {
  std::memcpy(h.magic, fmt::kMagic, 8);
  h.version_major = fmt::kVersionMajor;
  h.version_minor = fmt::kVersionMinor;
  h.toc_offset = offset_;
  h.toc_count = toc_.size();
  h.toc_entry_size = sizeof(fmt::TocEntry);
  h.toc_crc32c = crc32c(toc_.data(), toc_.size() * sizeof(fmt::TocEntry));
  h.file_size = offset_ + toc_.size() * sizeof(fmt::TocEntry);
  std::memset(h.reserved, 0, sizeof h.reserved);
  h.header_crc32c = crc32c(&h, offsetof(fmt::Header, header_crc32c));
  write_at(offset_, toc_.data(), toc_.size() * sizeof(fmt::TocEntry));
  std::vector<uint8_t> block(fmt::kAlignment, 0);  // the whole first block: header + zeros
  std::memcpy(block.data(), &h, sizeof h);
  write_at(0, block.data(), block.size());
  out_.set_size(h.file_size);
  out_.commit();
  finished_ = true;
  offset_ = h.file_size;  // bytes_written() is now the whole file, TOC included
}

}  // namespace rtp
