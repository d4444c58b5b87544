// Verifying package reader: header and TOC are checked on open; each chunk is read with pread
// (O_DIRECT on request, falling back cleanly), its CRC-32C checked, then decompressed.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <memory>

#include "core/error.h"
#include "core/input_file.h"
#include "reader/reader.h"

namespace rtp {
namespace {

std::string hex32(uint32_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "%08x", v);
  return b;
}

}  // namespace

PackageReader::PackageReader(const std::string& path, bool direct_io) : path_(path) {
  // A regular file only (a directory, FIFO or device gets a clear message; a FIFO never blocks).
  fd_ = open_input_file(path, "", direct_io ? O_DIRECT : 0, &file_size_);
  direct_ = direct_io && (::fcntl(fd_, F_GETFL) & O_DIRECT);  // false where O_DIRECT is refused
  // A constructor that throws runs no destructor: close the file here, or every refused package
  // leaks a descriptor (found by fuzz_package, which ran out of them after ~36,000 inputs).
  try {
    check_header_and_toc();
  } catch (...) {
    ::close(fd_);
    fd_ = -1;
    throw;
  }
}

void PackageReader::check_header_and_toc() {
  if (file_size_ < fmt::kAlignment) {
    // A short file that does not even start like a package is something else (a glTF given to inspect).
    char head[8] = {};
    const size_t n = size_t(std::min<uint64_t>(file_size_, sizeof head));
    if (n && ::pread(fd_, head, n, 0) == ssize_t(n) && std::memcmp(head, fmt::kMagic, n) != 0)
      fail_invalid("not an rtpack package (bad magic; " + std::to_string(file_size_) + " bytes)");
    fail_invalid("truncated file: " + std::to_string(file_size_) + " bytes, smaller than the " + std::to_string(fmt::kAlignment) +
                 "-byte header block");
  }
  // The header block through the same aligned path as chunks.
  fmt::TocEntry hb{};
  hb.offset = 0;
  hb.stored_size = fmt::kAlignment;
  toc_.push_back(hb);
  const AlignedBytes block = read_stored(0);
  toc_.clear();
  std::memcpy(&header_, block.data(), sizeof header_);
  if (std::memcmp(header_.magic, fmt::kMagic, 8) != 0) fail_invalid("not an rtpack package (bad magic)");
  if (header_.version_major != fmt::kVersionMajor)
    fail_invalid("package version " + std::to_string(header_.version_major) + "." + std::to_string(header_.version_minor) +
                 " is not supported by this reader (version " + std::to_string(fmt::kVersionMajor) + ".x)" +
                 (header_.version_major < fmt::kVersionMajor
                      ? ": it was written by an older rtpack-convert; convert the source again"
                      : ""));
  const uint32_t hcrc = crc32c(&header_, offsetof(fmt::Header, header_crc32c));
  if (hcrc != header_.header_crc32c)
    fail_invalid("header checksum mismatch (stored " + hex32(header_.header_crc32c) + ", computed " + hex32(hcrc) +
                 "): corrupt header");
  if (header_.file_size > file_size_)
    fail_invalid("truncated file: header says " + std::to_string(header_.file_size) + " bytes, the file has " +
                 std::to_string(file_size_));
  if (header_.file_size < file_size_)
    fail_invalid("the file has " + std::to_string(file_size_ - header_.file_size) + " bytes more than the header's " +
                 std::to_string(header_.file_size) + " (data appended after the package?)");
  if (header_.toc_entry_size < sizeof(fmt::TocEntry) || header_.toc_offset % fmt::kAlignment ||
      header_.toc_offset < fmt::kAlignment || header_.toc_offset > file_size_ ||
      header_.toc_count > (file_size_ / header_.toc_entry_size) ||
      header_.toc_count * header_.toc_entry_size > file_size_ - header_.toc_offset)
    fail_invalid("table of contents out of bounds (offset " + std::to_string(header_.toc_offset) + ", " +
                 std::to_string(header_.toc_count) + " entries)");
  // Read the TOC (the entries may be longer than ours in a newer minor version: keep our prefix).
  fmt::TocEntry tb{};
  tb.offset = header_.toc_offset;
  tb.stored_size = header_.toc_count * header_.toc_entry_size;
  toc_.push_back(tb);
  const AlignedBytes raw = read_stored(0);
  toc_.clear();
  const uint32_t tcrc = crc32c(raw.data(), raw.size());
  if (tcrc != header_.toc_crc32c)
    fail_invalid("table of contents checksum mismatch (stored " + hex32(header_.toc_crc32c) + ", computed " + hex32(tcrc) + ")");
  toc_.resize(header_.toc_count);
  for (size_t i = 0; i < toc_.size(); ++i) {
    std::memcpy(&toc_[i], raw.data() + i * header_.toc_entry_size, sizeof(fmt::TocEntry));
    const fmt::TocEntry& e = toc_[i];
    if (e.offset % fmt::kAlignment || e.offset < fmt::kAlignment || e.stored_size > header_.toc_offset ||
        e.offset > header_.toc_offset - e.stored_size)
      fail_invalid(chunk_label(e, i) + ": out of bounds (" + std::to_string(e.stored_size) + " bytes)");
    check_sizes(e, i);
  }
}

// Every chunk's declared raw size, checked when the TOC is read, so nothing (a memory budget, a buffer)
// is ever computed from a size the reader would refuse at decode (formats/SPEC.md §3).
void PackageReader::check_sizes(const fmt::TocEntry& e, size_t index) {
  if (e.compression == uint32_t(fmt::Compression::kNone)) {
    if (e.raw_size != e.stored_size)
      fail_invalid(chunk_label(e, index) + ": raw_size " + std::to_string(e.raw_size) + " differs from the " +
                   std::to_string(e.stored_size) + " stored bytes of an uncompressed chunk");
    return;
  }
  if (e.raw_size > kMaxChunkRatio * e.stored_size + kMaxChunkSlack)
    fail_invalid(chunk_label(e, index) + ": raw_size " + std::to_string(e.raw_size) + " is more than " +
                 std::to_string(kMaxChunkRatio) + " times the " + std::to_string(e.stored_size) +
                 " stored bytes (the limit of formats/SPEC.md §3)");
}

PackageReader::~PackageReader() {
  if (fd_ >= 0) ::close(fd_);
}

int64_t PackageReader::find(fmt::ChunkKind kind, uint64_t id) const {
  for (size_t i = 0; i < toc_.size(); ++i)
    if (toc_[i].kind == uint32_t(kind) && toc_[i].id == id) return int64_t(i);
  return -1;
}

AlignedBytes PackageReader::read_stored(size_t index) const {
  AlignedBytes out;
  read_stored_into(index, out);
  return out;
}

void PackageReader::read_stored_into(size_t index, AlignedBytes& out) const {
  const fmt::TocEntry& e = toc_[index];
  out.resize(e.stored_size);
  if (!direct_) {
    size_t done = 0;
    while (done < out.size()) {
      const ssize_t n = ::pread(fd_, out.data() + done, out.size() - done, off_t(e.offset + done));
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) throw Error(ExitCode::kInputIo, chunk_label(e, index) + ": read error: " + std::strerror(errno));
      if (n == 0) fail_invalid(chunk_label(e, index) + ": truncated file");
      done += size_t(n);
    }
    return;
  }
  // O_DIRECT: aligned buffer, offset and length (the chunk starts on a 4 KiB boundary).
  const size_t len = (e.stored_size + fmt::kAlignment - 1) / fmt::kAlignment * fmt::kAlignment;
  void* buf = std::aligned_alloc(fmt::kAlignment, len ? len : fmt::kAlignment);
  if (!buf) throw std::bad_alloc();
  size_t done = 0;
  while (done < e.stored_size) {
    const ssize_t n = ::pread(fd_, static_cast<char*>(buf) + done, len - done, off_t(e.offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      std::free(buf);
      if (n == 0) fail_invalid(chunk_label(e, index) + ": truncated file");
      throw Error(ExitCode::kInputIo, chunk_label(e, index) + ": read error: " + std::strerror(errno));
    }
    done += size_t(n);
  }
  if (e.stored_size) std::memcpy(out.data(), buf, e.stored_size);
  std::free(buf);
}

void PackageReader::verify(size_t index) const {
  const AlignedBytes stored = read_stored(index);
  const uint32_t c = crc32c(stored.data(), stored.size());
  if (c != toc_[index].crc32c)
    fail_invalid(chunk_label(toc_[index], index) + ": checksum mismatch (stored " + hex32(toc_[index].crc32c) + ", computed " +
                 hex32(c) + "): corrupt chunk");
}

AlignedBytes PackageReader::read(size_t index) const {
  AlignedBytes out;
  read_into(index, out);
  return out;
}

void PackageReader::read_into(size_t index, AlignedBytes& out) const {
  const fmt::TocEntry& e = toc_[index];
  if (e.compression == uint32_t(fmt::Compression::kNone)) {
    read_stored_into(index, out);  // raw_size = stored_size (check_sizes)
    const uint32_t c = crc32c(out.data(), out.size());
    if (c != e.crc32c)
      fail_invalid(chunk_label(e, index) + ": checksum mismatch (stored " + hex32(e.crc32c) + ", computed " + hex32(c) +
                   "): corrupt chunk");
    return;
  }
  // The compressed bytes go to a per-thread buffer that keeps its pages: a fresh one per chunk was faulted
  // in and zeroed by the kernel each time (as much time as the copy from the page cache). It holds the
  // largest chunk this thread has read, until the thread ends.
  thread_local AlignedBytes stored;
  read_stored_into(index, stored);
  const uint32_t c = crc32c(stored.data(), stored.size());
  if (c != e.crc32c)
    fail_invalid(chunk_label(e, index) + ": checksum mismatch (stored " + hex32(e.crc32c) + ", computed " + hex32(c) +
                 "): corrupt chunk");
  if (e.compression != uint32_t(fmt::Compression::kZstd))
    fail_invalid(chunk_label(e, index) + ": unknown compression " + std::to_string(e.compression));
  // The frame's declared size must equal the TOC's raw size, and neither is believed before the bytes
  // exist: the output buffer grows with what the frame really decodes to (never more than 2x of it),
  // so a small frame declaring gigabytes fails after a few megabytes, not after allocating them;
  // and raw_size was capped by kMaxChunkRatio times the stored size when the TOC was read.
  const unsigned long long declared = ZSTD_getFrameContentSize(stored.data(), stored.size());
  if (declared != e.raw_size)
    fail_invalid(chunk_label(e, index) + ": zstd frame declares " +
                 (declared == ZSTD_CONTENTSIZE_UNKNOWN ? std::string("no size")
                  : declared == ZSTD_CONTENTSIZE_ERROR ? std::string("an invalid header")
                                                       : std::to_string(declared) + " bytes") +
                 ", the table of contents raw_size " + std::to_string(e.raw_size));
  thread_local std::unique_ptr<ZSTD_DCtx, size_t (*)(ZSTD_DCtx*)> ctx(ZSTD_createDCtx(), ZSTD_freeDCtx);
  if (!ctx) throw std::bad_alloc();
  ZSTD_DCtx* dctx = ctx.get();
  ZSTD_DCtx_reset(dctx, ZSTD_reset_session_only);
  const size_t reuse = out.capacity();  // memory the caller already holds: no new commitment
  out.clear();
  ZSTD_inBuffer in{stored.data(), stored.size(), 0};
  size_t done = 0, ret = 1;
  std::string error;
  while (ret != 0) {
    if (done == out.size()) {
      if (out.size() == e.raw_size) {
        error = "the frame decodes to more than raw_size";
        break;
      }
      // First 16x the stored bytes (at least 1 MiB: most chunks fit at once), then doubling.
      const uint64_t want = std::max<uint64_t>({uint64_t(1) << 20, 16 * e.stored_size, 2 * uint64_t(out.size()), reuse});
      out.resize(size_t(std::min<uint64_t>(e.raw_size, want)));
    }
    ZSTD_outBuffer ob{out.data(), out.size(), done};
    ret = ZSTD_decompressStream(dctx, &ob, &in);
    done = ob.pos;
    if (ZSTD_isError(ret)) {
      error = ZSTD_getErrorName(ret);
      break;
    }
    if (ret != 0 && in.pos == in.size && ob.pos < ob.size) {
      error = "the frame ends early";
      break;
    }
  }
  if (error.empty() && (done != e.raw_size || in.pos != in.size)) error = "short";
  if (!error.empty()) fail_invalid(chunk_label(e, index) + ": zstd decompression failed (" + error + ")");
  // Growing by doubling (a chunk over 16x its stored size) can leave up to twice the bytes allocated:
  // give that slack back (the cache holds these buffers under its budget).
  if (out.capacity() - out.size() > out.size() / 16 && out.capacity() > reuse) out.shrink_to_fit();
}

uint64_t PackageReader::first_nonzero(uint64_t offset, uint64_t size) const {
  std::vector<uint8_t> buf(size_t(std::min<uint64_t>(size, uint64_t(1) << 20)));
  for (uint64_t done = 0; done < size;) {
    const size_t want = size_t(std::min<uint64_t>(buf.size(), size - done));
    const ssize_t n = ::pread(fd_, buf.data(), want, off_t(offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0)
      throw Error(ExitCode::kInputIo, "read error at offset " + std::to_string(offset + done) + ": " + std::strerror(errno));
    if (n == 0) return offset + done;  // past the end: not zeros
    for (ssize_t k = 0; k < n; ++k)
      if (buf[size_t(k)]) return offset + done + uint64_t(k);
    done += uint64_t(n);
  }
  return kAllZero;
}

}  // namespace rtp
