// Counting a section of a chunk without holding the chunk: the stored bytes stream through the CRC in
// 1 MiB pieces and through zstd only until the chunk header and section table are out (SPEC §3, §4).
#include <fcntl.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <memory>

#include "core/error.h"
#include "formats/chunk.h"
#include "reader/reader.h"

namespace rtp {

uint64_t PackageReader::section_count(size_t index, uint32_t type, uint32_t elem_size) const {
  const fmt::TocEntry& e = toc_[index];
  const std::string label = chunk_label(e, index);
  constexpr size_t kPiece = size_t(1) << 20;  // a multiple of 4096: aligned reads also under O_DIRECT
  struct Free {
    void operator()(void* p) const { std::free(p); }
  };
  std::unique_ptr<uint8_t, Free> buf(static_cast<uint8_t*>(std::aligned_alloc(fmt::kAlignment, kPiece)));
  if (!buf) throw std::bad_alloc();
  const bool zstd = e.compression == uint32_t(fmt::Compression::kZstd);
  if (!zstd && e.compression != uint32_t(fmt::Compression::kNone))
    fail_invalid(label + ": unknown compression " + std::to_string(e.compression));
  std::unique_ptr<ZSTD_DCtx, size_t (*)(ZSTD_DCtx*)> dctx(zstd ? ZSTD_createDCtx() : nullptr, ZSTD_freeDCtx);
  if (zstd && !dctx) throw std::bad_alloc();
  // The head: the 16-byte chunk header, then up to 4096 section entries' worth of table.
  std::vector<uint8_t> head;
  size_t head_want = sizeof(fmt::ChunkHeader);
  uint32_t crc = 0;
  bool head_done = false;
  for (uint64_t done = 0; done < e.stored_size;) {
    const size_t want = size_t(std::min<uint64_t>(kPiece, e.stored_size - done));
    const size_t ask = direct_ ? (want + fmt::kAlignment - 1) / fmt::kAlignment * fmt::kAlignment : want;
    const ssize_t n = ::pread(fd_, buf.get(), ask, off_t(e.offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw Error(ExitCode::kInputIo, label + ": read error: " + std::strerror(errno));
    if (n == 0) fail_invalid(label + ": truncated file");
    const size_t got = std::min(size_t(n), want);
    crc = crc32c(buf.get(), got, crc);
    // Grows head_want from the chunk header to the header plus its section table once that is known.
    auto update_want = [&] {
      if (head.size() >= sizeof(fmt::ChunkHeader) && head_want == sizeof(fmt::ChunkHeader)) {
        fmt::ChunkHeader h;
        std::memcpy(&h, head.data(), sizeof h);
        head_want = sizeof h + size_t(std::min<uint32_t>(h.section_count, 4096)) * sizeof(fmt::SectionEntry);
      }
      head_done = head.size() >= head_want && head_want > sizeof(fmt::ChunkHeader);
    };
    if (!zstd && done == 0) {  // the head (at most 16 + 4096·24 bytes) lies inside the first piece
      head.assign(buf.get(), buf.get() + std::min(got, head_want));
      update_want();
      head.assign(buf.get(), buf.get() + std::min(got, head_want));
      update_want();
    } else if (!head_done) {
      ZSTD_inBuffer in{buf.get(), got, 0};
      while (!head_done) {
        const size_t old = head.size();
        head.resize(head_want);
        ZSTD_outBuffer ob{head.data() + old, head_want - old, 0};
        const size_t ret = ZSTD_decompressStream(dctx.get(), &ob, &in);
        head.resize(old + ob.pos);
        if (ZSTD_isError(ret)) fail_invalid(label + ": zstd decompression failed (" + ZSTD_getErrorName(ret) + ")");
        update_want();
        if (ret == 0 || head.size() >= head_want || (ob.pos == 0 && in.pos == in.size)) break;  // ended, enough, or used up
      }
    }
    done += got;
  }
  if (crc != e.crc32c) fail_invalid(label + ": checksum mismatch: corrupt chunk");
  fmt::ChunkHeader h{};
  if (head.size() >= sizeof h) std::memcpy(&h, head.data(), sizeof h);
  if (head.size() < sizeof h || h.magic != fmt::kChunkMagic || h.kind != e.kind) fail_invalid(label + ": bad chunk header");
  if (h.section_count > 4096 || head.size() < sizeof h + size_t(h.section_count) * sizeof(fmt::SectionEntry))
    fail_invalid(label + ": section table of " + std::to_string(h.section_count) + " entries is cut short");
  for (uint32_t k = 0; k < h.section_count; ++k) {
    fmt::SectionEntry s;
    std::memcpy(&s, head.data() + sizeof h + k * sizeof s, sizeof s);
    if (s.type != type) continue;
    if (s.elem_size != elem_size)
      fail_invalid(label + ": section " + std::to_string(type) + " has elements of " + std::to_string(s.elem_size) +
                   " bytes, expected " + std::to_string(elem_size));
    if (s.offset > e.raw_size || s.count > (e.raw_size - s.offset) / elem_size)
      fail_invalid(label + ": section " + std::to_string(type) + " lies outside the chunk");
    return s.count;
  }
  return 0;
}

}  // namespace rtp
