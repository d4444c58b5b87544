// The .rtp container alone: round trip, alignment, checksums, and every corruption → a clear error.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <random>

#include "core/aligned.h"
#include "core/error.h"
#include "gltf_builder.h"
#include "package/writer.h"
#include "reader/reader.h"
#include "layout/chunk_io.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

std::vector<uint8_t> pattern(size_t n, uint32_t seed) {
  std::vector<uint8_t> v(n);
  std::mt19937 rng(seed);
  for (size_t i = 0; i < n; ++i) v[i] = uint8_t(i % 7 == 0 ? rng() : i / 64);  // compressible but not trivial
  return v;
}

// Writes a package with a few chunks of various sizes; returns their contents by TOC order.
std::vector<std::vector<uint8_t>> write_sample(const std::string& path, int level = 3) {
  std::vector<std::vector<uint8_t>> chunks = {pattern(100, 1), pattern(5000, 2), pattern(0, 3), pattern(70000, 4),
                                              pattern(4096, 5)};
  PackageWriter w(path, level);
  w.add_chunk(fmt::ChunkKind::kMetadata, 0, chunks[0].data(), chunks[0].size());
  for (size_t i = 1; i < chunks.size(); ++i)
    w.add_chunk(fmt::ChunkKind::kBatchingPoint, i - 1, chunks[i].data(), chunks[i].size());
  fmt::Header h{};
  h.unique_triangles = 7;
  h.bvh_width = 8;
  w.finish(h);
  return chunks;
}

class Container : public ::testing::Test {
 protected:
  fs::path dir = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  void TearDown() override { fs::remove_all(dir); }
};

TEST_F(Container, Crc32cMatchesKnownValueAndPortablePath) {
  const char* s = "123456789";
  EXPECT_EQ(crc32c(s, 9), 0xE3069283u);  // the standard CRC-32C check value
  const auto v = pattern(10007, 9);
  EXPECT_EQ(crc32c(v.data(), v.size()), crc32c_portable(v.data(), v.size()));
  // Inputs long enough for the three interleaved streams (3 x 32 KiB steps), at every remainder around
  // a step, from unaligned starts, and continued from an earlier CRC.
  const auto big = pattern(1 << 20, 3);
  for (size_t size : {size_t(98303), size_t(98304), size_t(98305), size_t(196607), size_t(196615), size_t(1 << 20) - 5})
    for (size_t start : {size_t(0), size_t(1), size_t(5)}) {
      EXPECT_EQ(crc32c(big.data() + start, size), crc32c_portable(big.data() + start, size)) << size << " from " << start;
      const uint32_t head = crc32c(big.data() + start, 1000);
      EXPECT_EQ(crc32c(big.data() + start + 1000, size - 1000, head), crc32c_portable(big.data() + start, size)) << size;
    }
}

TEST_F(Container, RoundTripAlignedAndNoTemporaryLeft) {
  const std::string p = (dir / "a.rtp").string();
  const auto chunks = write_sample(p);
  for (const auto& e : fs::directory_iterator(dir)) EXPECT_EQ(e.path().filename(), "a.rtp");
  PackageReader r(p);
  EXPECT_EQ(r.header().unique_triangles, 7u);
  ASSERT_EQ(r.toc().size(), chunks.size());
  for (size_t i = 0; i < chunks.size(); ++i) {
    EXPECT_EQ(r.toc()[i].offset % 4096, 0u);
    const AlignedBytes got = r.read(i);
    EXPECT_TRUE(std::equal(chunks[i].begin(), chunks[i].end(), got.begin(), got.end()));
  }
  EXPECT_EQ(r.find(fmt::ChunkKind::kBatchingPoint, 2), 3);
  EXPECT_EQ(r.find(fmt::ChunkKind::kMeshSegment, 0), -1);
  EXPECT_EQ(r.toc()[4].compression, uint32_t(fmt::Compression::kZstd));
  PackageReader d(p, /*direct_io=*/true);  // O_DIRECT or its clean fallback: same bytes
  for (size_t i = 0; i < chunks.size(); ++i) {
    const AlignedBytes got = d.read(i);
    EXPECT_TRUE(std::equal(chunks[i].begin(), chunks[i].end(), got.begin(), got.end()));
  }
}

TEST_F(Container, SameInputSameBytes) {
  write_sample((dir / "a.rtp").string());
  write_sample((dir / "b.rtp").string());
  std::ifstream a(dir / "a.rtp", std::ios::binary), b(dir / "b.rtp", std::ios::binary);
  EXPECT_TRUE(std::equal(std::istreambuf_iterator<char>(a), {}, std::istreambuf_iterator<char>(b)));
}

// Large chunks: zstd's own threads give the same frame for any number of workers >= 1 (the late
// resident chunks follow --threads), and packages past the writer's writeback step (8 MiB) read back
// whole.
TEST_F(Container, LargeChunksSameBytesForAnyWorkersAndReadBack) {
  const std::vector<uint8_t> big = pattern(PackageWriter::kWorkersMinBytes + 1234567, 6);
  fmt::Compression c1{}, c2{}, c3{};
  const AlignedBytes one = PackageWriter::compress(big.data(), big.size(), 1, c1, false, 0, 1);
  const AlignedBytes two = PackageWriter::compress(big.data(), big.size(), 1, c2, false, 0, 2);
  const AlignedBytes three = PackageWriter::compress(big.data(), big.size(), 1, c3, false, 0, 3);
  ASSERT_EQ(c1, fmt::Compression::kZstd);
  EXPECT_EQ(c2, c1);
  EXPECT_EQ(c3, c1);
  EXPECT_TRUE(std::equal(one.begin(), one.end(), two.begin(), two.end()));
  EXPECT_TRUE(std::equal(one.begin(), one.end(), three.begin(), three.end()));
  const std::string p = (dir / "big.rtp").string();
  const std::vector<uint8_t> other = pattern(size_t(9) << 20, 7);
  {
    PackageWriter w(p, 1);
    w.add_packed(fmt::ChunkKind::kBatchingPoint, 0, two, c2, big.size());
    w.add_chunk(fmt::ChunkKind::kBatchingPoint, 1, other.data(), other.size());
    w.add_chunk(fmt::ChunkKind::kBatchingPoint, 2, big.data(), 100);
    w.finish(fmt::Header{});
  }
  PackageReader r(p);
  ASSERT_EQ(r.toc().size(), 3u);
  const AlignedBytes a = r.read(0), b = r.read(1), c = r.read(2);
  EXPECT_TRUE(std::equal(big.begin(), big.end(), a.begin(), a.end()));
  EXPECT_TRUE(std::equal(other.begin(), other.end(), b.begin(), b.end()));
  EXPECT_TRUE(std::equal(big.begin(), big.begin() + 100, c.begin(), c.end()));
}

TEST_F(Container, WriterThatIsNotFinishedLeavesNothing) {
  {
    PackageWriter w((dir / "x.rtp").string());
    const auto v = pattern(100, 1);
    w.add_chunk(fmt::ChunkKind::kMetadata, 0, v.data(), v.size());
  }  // e.g. an exception during conversion
  EXPECT_TRUE(fs::is_empty(dir));
  try {
    PackageWriter w((dir / "no" / "such" / "x.rtp").string());
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ExitCode::kOutput);
  }
}

// Opens the package and reads every chunk; returns the error message, or "" when all is fine.
std::string open_and_read_all(const std::string& p) {
  try {
    PackageReader r(p);
    for (size_t i = 0; i < r.toc().size(); ++i) r.read(i);
  } catch (const Error& e) {
    EXPECT_NE(e.code(), ExitCode::kInternal);
    return e.what();
  }
  return "";
}

TEST_F(Container, TruncationAtTwentyOffsets) {
  const std::string p = (dir / "a.rtp").string();
  write_sample(p);
  std::ifstream in(p, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  for (int k = 0; k < 20; ++k) {
    const size_t cut = bytes.size() * size_t(k) / 20 + (k % 3);
    std::ofstream(dir / "t.rtp", std::ios::binary).write(bytes.data(), std::streamsize(cut));
    const std::string msg = open_and_read_all((dir / "t.rtp").string());
    EXPECT_NE(msg.find("truncated file"), std::string::npos) << "cut " << cut << ": " << msg;
  }
}

TEST_F(Container, ThousandRandomBitFlipsAreAllCaught) {
  const std::string p = (dir / "a.rtp").string();
  write_sample(p);
  std::ifstream in(p, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  PackageReader clean(p);
  // Bytes that matter: header, every chunk's stored bytes, the TOC (the zero padding is not read).
  std::vector<std::pair<uint64_t, uint64_t>> ranges = {{0, 128}, {clean.header().toc_offset, clean.header().toc_count * 48}};
  for (const auto& e : clean.toc()) ranges.push_back({e.offset, e.stored_size});
  std::mt19937_64 rng(42);
  int caught = 0;
  for (int trial = 0; trial < 1000; ++trial) {
    auto [off, len] = ranges[rng() % ranges.size()];
    if (len == 0) {
      --trial;
      continue;
    }
    const uint64_t pos = off + rng() % len;
    std::string s = bytes;
    s[pos] = char(s[pos] ^ (1 << (rng() % 8)));
    std::ofstream(dir / "f.rtp", std::ios::binary) << s;
    const std::string msg = open_and_read_all((dir / "f.rtp").string());
    caught += !msg.empty();
    EXPECT_FALSE(msg.empty()) << "flip at byte " << pos << " went unnoticed";
  }
  EXPECT_EQ(caught, 1000);
}

TEST_F(Container, WrongVersionNamesBothVersions) {
  const std::string p = (dir / "a.rtp").string();
  write_sample(p);
  std::fstream f(p, std::ios::binary | std::ios::in | std::ios::out);
  const uint32_t v = rtp::fmt::kVersionMajor + 1;  // a newer major
  f.seekp(8);
  f.write(reinterpret_cast<const char*>(&v), 4);
  f.close();
  EXPECT_EQ(open_and_read_all(p), "package version " + std::to_string(v) + "." + std::to_string(rtp::fmt::kVersionMinor) +
                                      " is not supported by this reader (version " + std::to_string(rtp::fmt::kVersionMajor) +
                                      ".x)");
}

TEST_F(Container, CorruptChunkIsNamed) {
  const std::string p = (dir / "a.rtp").string();
  write_sample(p);
  uint64_t off;
  {
    PackageReader r(p);
    off = r.toc()[3].offset;
  }
  std::fstream f(p, std::ios::binary | std::ios::in | std::ios::out);
  f.seekg(std::streamoff(off + 10));
  char c;
  f.read(&c, 1);
  c ^= 4;
  f.seekp(std::streamoff(off + 10));
  f.write(&c, 1);
  f.close();
  const std::string msg = open_and_read_all(p);
  EXPECT_EQ(msg.rfind("batching point 2 (chunk #3 at offset " + std::to_string(off) + "): checksum mismatch", 0), 0u) << msg;
}

// Chunk buffers of 4 MiB and more are huge-page mappings kept after a free and resized for the next one
// (core/aligned.cpp): every size must come back 2 MiB aligned, whole and writable, whether it is fresh,
// a shrunk kept mapping or a grown one, and release_kept_large() must leave new allocations working.
TEST(AlignedLarge, KeptMappingsComeBackWholeAndAligned) {
  std::mt19937 rng(7);
  std::vector<AlignedBytes> live;
  for (int round = 0; round < 40; ++round) {
    const size_t size = kHugeThreshold + size_t(rng() % (24u << 20));
    AlignedBytes b(size);
    ASSERT_EQ(reinterpret_cast<uintptr_t>(b.data()) % (size_t(2) << 20), 0u) << "round " << round;
    const uint8_t tag = uint8_t(round + 1);
    std::memset(b.data(), tag, b.size());
    EXPECT_EQ(b[0], tag);
    EXPECT_EQ(b[b.size() - 1], tag);
    live.push_back(std::move(b));
    if (rng() % 2) live.erase(live.begin() + std::ptrdiff_t(rng() % live.size()));  // freed: kept for reuse
    if (round == 20) release_kept_large();
  }
  for (size_t i = 0; i < live.size(); ++i) {  // no later allocation took a live buffer's pages
    const uint8_t tag = live[i][0];
    EXPECT_EQ(std::count(live[i].begin(), live[i].end(), tag), std::ptrdiff_t(live[i].size())) << "buffer " << i;
  }
  live.clear();
  release_kept_large();
  AlignedBytes small(1000);  // below the threshold: the ordinary aligned heap
  EXPECT_EQ(reinterpret_cast<uintptr_t>(small.data()) % 64, 0u);
}

// A freed large buffer's pages move into the next large buffers (mremap), whatever their sizes: the
// bytes left in them are the old ones (a fresh page would read as zeros), and pieces of two freed
// buffers fill one larger buffer.
TEST(AlignedLarge, FreedPagesMoveIntoTheNextBuffers) {
  release_kept_large();
  constexpr size_t kMiB = size_t(1) << 20;
  {
    AlignedBytes a(10 * kMiB), b(6 * kMiB);
    std::memset(a.data(), 0xA1, a.size());
    std::memset(b.data(), 0xB2, b.size());
  }                             // freed: b then a are kept (a the most recent)
  AlignedBytes big(16 * kMiB);  // a's 10 MiB first, then b's 6
  EXPECT_EQ(std::count(big.begin(), big.begin() + 10 * kMiB, uint8_t(0xA1)), std::ptrdiff_t(10 * kMiB));
  EXPECT_EQ(std::count(big.begin() + 10 * kMiB, big.end(), uint8_t(0xB2)), std::ptrdiff_t(6 * kMiB));
  std::memset(big.data(), 0xC3, big.size());
  big = AlignedBytes();                          // freed: 16 MiB kept
  AlignedBytes head(6 * kMiB), rest(10 * kMiB);  // a larger kept mapping serves two smaller buffers
  EXPECT_EQ(std::count(head.begin(), head.end(), uint8_t(0xC3)), std::ptrdiff_t(head.size()));
  EXPECT_EQ(std::count(rest.begin(), rest.end(), uint8_t(0xC3)), std::ptrdiff_t(rest.size()));
  std::memset(head.data(), 1, head.size());  // still two separate buffers
  EXPECT_EQ(std::count(rest.begin(), rest.end(), uint8_t(0xC3)), std::ptrdiff_t(rest.size()));
  release_kept_large();
  AlignedBytes after(8 * kMiB);  // nothing kept: fresh, zero pages
  EXPECT_EQ(std::count(after.begin(), after.end(), uint8_t(0)), std::ptrdiff_t(after.size()));
}

TEST_F(Container, NotAPackage) {
  std::ofstream(dir / "x.rtp", std::ios::binary) << std::string(8192, 'x');
  EXPECT_EQ(open_and_read_all((dir / "x.rtp").string()), "not an rtpack package (bad magic)");
}

// What a refusal says about a file that is not a whole package: a short file that does not start like one
// is not a package (a glTF handed to rtpack-inspect was a "truncated file"), a short one that does is
// truncated, and bytes after the header's file_size are appended data, not a truncation.
TEST_F(Container, ShortFilesAndAppendedBytesSayWhatTheyAre) {
  std::ofstream(dir / "s.gltf", std::ios::binary) << R"({"asset":{"version":"2.0"}})";
  EXPECT_EQ(open_and_read_all((dir / "s.gltf").string()), "not an rtpack package (bad magic; 27 bytes)");
  std::ofstream(dir / "m.rtp", std::ios::binary) << std::string(fmt::kMagic, 8) << std::string(100, '\0');
  EXPECT_EQ(open_and_read_all((dir / "m.rtp").string()), "truncated file: 108 bytes, smaller than the 4096-byte header block");
  const std::string p = (dir / "a.rtp").string();
  write_sample(p);
  const uint64_t size = fs::file_size(p);
  std::ofstream(p, std::ios::binary | std::ios::app) << std::string(100, 'x');
  EXPECT_EQ(open_and_read_all(p),
            "the file has 100 bytes more than the header's " + std::to_string(size) + " (data appended after the package?)");
}

// ChunkBuilder borrows its sections and gathers one from several arrays: the chunk equals the one built
// from the concatenation, whatever buffer it is finished into (a reused one keeps no old bytes).
TEST(ChunkBuilder, GatheredSectionsEqualTheConcatenationInAnyBuffer) {
  const std::vector<uint32_t> a = {1, 2, 3}, b = {}, c = {4, 5, 6, 7, 8}, whole = {1, 2, 3, 4, 5, 6, 7, 8};
  const std::vector<uint64_t> other = {0x0123456789a0cdefull, 42};  // no 0xAB byte (see below)
  ChunkBuilder gathered{7};
  gathered.add(fmt::SectionType::kGlobalIds, other);
  gathered.begin_section(fmt::SectionType::kMeshSlots, sizeof(uint32_t));
  for (const auto* v : {&a, &b, &c}) gathered.append_to_section(v->data(), v->size());
  ChunkBuilder concatenated{7};
  concatenated.add(fmt::SectionType::kGlobalIds, other);
  concatenated.add(fmt::SectionType::kMeshSlots, whole);
  const AlignedBytes want = concatenated.finish();
  EXPECT_EQ(gathered.size(), want.size());
  AlignedBytes reused(3 * want.size());
  std::memset(reused.data(), 0xAB, reused.size());  // a larger chunk's bytes were here
  gathered.finish_into(reused);
  ASSERT_EQ(reused.size(), want.size());
  EXPECT_EQ(std::memcmp(reused.data(), want.data(), want.size()), 0);
  for (size_t i = 0; i < reused.size(); ++i) ASSERT_NE(reused[i], 0xAB) << "old byte at " << i;  // padding zeroed
  ChunkView v(reused.data(), reused.size(), 7, "gathered");
  uint64_t n = 0;
  const uint32_t* slots = v.get<uint32_t>(fmt::SectionType::kMeshSlots, n);
  ASSERT_EQ(n, whole.size());
  EXPECT_TRUE(std::equal(whole.begin(), whole.end(), slots));
  EXPECT_EQ(v.copy<uint64_t>(fmt::SectionType::kGlobalIds), other);

  ChunkBuilder none{1};
  EXPECT_THROW(none.append_to_section(a.data(), a.size()), Error);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
