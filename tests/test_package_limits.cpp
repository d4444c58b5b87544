// Package reader limits and rtpack-inspect --verify on hostile packages (formats/SPEC.md §1/§3,
// docs/exit-codes.md): declared sizes never believed before the bytes exist (zstd frame sizes, mesh
// table and attribute counts), 64-bit wrapped ranges, a changed mesh-entry id, a wrapped TOC offset,
// a directory or FIFO given as package, non-zero bytes where only zeros may be, and plain rtpack-trace
// on a hostile package: each exit 3 with a message naming the chunk and field, none a crash or hang.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstring>
#include <limits>
#include <fstream>
#include <iterator>

#include "formats/chunk.h"
#include "formats/ray_file.h"
#include "hostile_package.h"
#include "reader/attribute_lookup.h"
#include "reader/camera.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using fmt::SectionType;

class Limits : public Hostile {};

// The zstd frame header's content-size field of `frame` (RFC 8878 §3.1.1.1): its offset and width.
std::pair<size_t, size_t> frame_content_size_field(const uint8_t* frame) {
  const uint8_t fhd = frame[4];
  const bool single = fhd & 0x20;
  const size_t dict[4] = {0, 1, 2, 4}, fcs[4] = {size_t(single ? 1 : 0), 2, 4, 8};
  return {5 + (single ? 0 : 1) + dict[fhd & 3], fcs[fhd >> 6]};
}

// A compressed chunk of at least 70000 raw bytes (its frame stores the size in 4 or 8 bytes).
size_t big_zstd_chunk(const std::string& path) {
  const PackageReader r(path);
  for (size_t i = 0; i < r.toc().size(); ++i)
    if (r.toc()[i].compression == uint32_t(fmt::Compression::kZstd) && r.toc()[i].raw_size >= 70000) return i;
  throw std::runtime_error("no compressed chunk of 70000 raw bytes or more");
}

// Makes chunk `index`'s frame and TOC entry both declare `declared` raw bytes; returns its label.
std::string lie_about_size(const std::string& path, size_t index, uint64_t declared) {
  std::string label;
  {
    const PackageReader r(path);
    label = chunk_label(r.toc()[index], index);
  }
  patch_stored(path, index, [&](uint8_t* chunk, fmt::TocEntry& te) {
    const auto [at, width] = frame_content_size_field(chunk);
    ASSERT_TRUE(width == 4 || width == 8) << width;
    if (width == 4) {
      const uint32_t v = uint32_t(declared);
      std::memcpy(chunk + at, &v, 4);
    } else {
      std::memcpy(chunk + at, &declared, 8);
    }
    te.raw_size = declared;
  });
  return label;
}

TEST_F(Limits, ZstdFrameDeclaringGigabytesIsRejectedBeforeAllocating) {
  const std::string p = copy(bases().forest_zstd);
  // The compressed chunk of 70000 raw bytes or more (a 4- or 8-byte frame size) with the fewest stored bytes: 3 GB is beyond the limit (32768 x stored + 1 MiB) there.
  size_t index = big_zstd_chunk(p);
  {
    const PackageReader r(p);
    for (size_t i = 0; i < r.toc().size(); ++i)
      if (r.toc()[i].compression == uint32_t(fmt::Compression::kZstd) && r.toc()[i].raw_size >= 70000 &&
          r.toc()[i].stored_size < r.toc()[index].stored_size)
        index = i;
    ASSERT_LT(PackageReader::kMaxChunkRatio * r.toc()[index].stored_size + PackageReader::kMaxChunkSlack, 3000000000ull);
  }
  const std::string label = lie_about_size(p, index, 3000000000ull);
  try {  // refused with the table of contents, before anything (a memory budget, a buffer) is sized by it
    const PackageReader r(p);
    FAIL() << "opened a package whose chunk declares 3 GB";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ExitCode::kInputInvalid);
    EXPECT_TRUE(contains_all(e.what(), {label, "raw_size 3000000000 is more than 32768 times"})) << e.what();
  }
  expect_tools_reject(p, {label, "raw_size 3000000000 is more than 32768 times"});
  // Sized from that raw_size, the out-of-core minimum budget used to refuse --memory-budget (exit 1, a usage error).
  const ToolResult ooc =
      run_tool("rtpack-trace",
               {p, "--rays", (dir / "tools.rays").string(), "--hits", (dir / "ooc.hits").string(), "--memory-budget", "64MiB"},
               dir, {}, 20);
  EXPECT_EQ(ooc.code, 3) << ooc.err;
  EXPECT_TRUE(contains_all(ooc.err, {label, "raw_size 3000000000"})) << ooc.err;
  EXPECT_FALSE(fs::exists(dir / "ooc.hits"));
}

TEST_F(Limits, ZstdFrameDeclaringMoreThanItHoldsFailsWhileDecoding) {
  const std::string p = copy(bases().forest_zstd);
  const size_t index = big_zstd_chunk(p);
  uint64_t declared = 0;
  {
    const PackageReader r(p);
    const fmt::TocEntry& e = r.toc()[index];
    declared = std::min<uint64_t>(e.raw_size + (uint64_t(64) << 20), 1024 * e.stored_size);  // inside the ratio cap
    ASSERT_GT(declared, e.raw_size);
  }
  const std::string label = lie_about_size(p, index, declared);
  try {
    PackageReader(p).read(index);
    FAIL() << "decoded a frame that declares more than it holds";
  } catch (const Error& err) {
    EXPECT_EQ(err.code(), ExitCode::kInputInvalid);
    EXPECT_TRUE(contains_all(err.what(), {label, "zstd decompression failed"})) << err.what();
  }
}

TEST_F(Limits, WrappedTocOffsetDirectoryAndFifo) {
  {
    const std::string p = copy(bases().forest);
    patch_header(p, [](fmt::Header& h) { h.toc_offset = ~uint64_t(0) - 4095; });  // offset + size wraps to small
    try {
      PackageReader r(p);
      FAIL() << "opened";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ExitCode::kInputInvalid) << e.what();
      EXPECT_NE(std::string(e.what()).find("table of contents out of bounds"), std::string::npos) << e.what();
    }
  }
  // Not a regular file: the input cannot be read as a package (docs/exit-codes.md: 2).
  const ToolRun d = run(tool("rtpack-inspect") + " " + dir.string(), dir);
  EXPECT_EQ(d.code, 2) << d.err;
  EXPECT_NE(d.err.find("is a directory"), std::string::npos) << d.err;
  const fs::path fifo = dir / "fifo.rtp";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // Without a writer, a blocking open() would never return: `timeout` turns a hang into exit 124.
  const ToolRun f = run("timeout 20 " + tool("rtpack-inspect") + " " + fifo.string(), dir);
  EXPECT_EQ(f.code, 2) << f.err;
  EXPECT_NE(f.err.find("FIFO"), std::string::npos) << f.err;
}

TEST_F(Limits, MeshTableSourceRangeThatWrapsIsRejected) {
  const std::string p = copy(bases().forest);
  const auto [index, label] = chunk_of(p, fmt::ChunkKind::kMeshes, 0);
  patch_chunk(p, index, [](uint8_t* chunk, size_t) {
    section<fmt::MeshInfo>(chunk, SectionType::kMeshTable)[1].source_tri_first = ~uint64_t(0) - 2;  // + triangles wraps
  });
  expect_inspect_problem(p, {label, "mesh 1: source_tri_first 18446744073709551613 + triangles"}, true);
  const ToolRun t = run(tool("rtpack-inspect") + " --verify " + p, dir);
  EXPECT_EQ(t.code, 3) << t.out << t.err;
  // A declared triangle count of 2^40 (a 1 TB coverage table in --verify): not backed by the source map.
  const std::string q = copy(bases().forest);
  patch_chunk(q, index, [](uint8_t* chunk, size_t) {
    section<fmt::MeshInfo>(chunk, SectionType::kMeshTable)[0].triangles = uint64_t(1) << 40;
  });
  const ToolRun u = run(tool("rtpack-inspect") + " --verify " + q, dir);
  EXPECT_EQ(u.code, 3) << u.out << u.err;
  EXPECT_NE(u.out.find(label + ": mesh 0: source_tri_first 0 + triangles 1099511627776 outside"), std::string::npos) << u.out;
}

TEST_F(Limits, VerifyStopsEarlyOnAChangedMeshEntryId) {
  const std::string p = copy(bases().lantern);
  size_t index = 0;
  {  // a batching point holding pieces
    const PackageReader r(p);
    for (index = 0; index < r.toc().size(); ++index) {
      if (r.toc()[index].kind != uint32_t(fmt::ChunkKind::kBatchingPoint)) continue;
      AlignedBytes b = r.read(index);
      uint64_t n = 0;
      section<fmt::MeshEntry>(b.data(), SectionType::kMeshEntries, &n);
      if (n) break;
    }
    ASSERT_LT(index, r.toc().size());
  }
  patch_chunk(p, index, [](uint8_t* chunk, size_t) {
    section<fmt::MeshEntry>(chunk, SectionType::kMeshEntries)[0].id = 0xFFFFFFF0u;  // a piece id
  });
  const PackageReader r(p);
  InspectOptions o;
  o.verify = true;
  const InspectResult res = inspect_package(r, o);
  EXPECT_GT(res.problems, 0u);
  EXPECT_LT(res.problems, 100u) << res.report["problems"].dump(2);  // not 4,294,967,280
  bool named = false;
  for (const std::string& m : res.listed) named |= m.find("piece ids are in no batching point") != std::string::npos;
  EXPECT_TRUE(named) << res.report["problems"].dump(2);
}

// An attribute chunk of Lantern with entry 0's triangle_first patched by `edit`.
std::string patch_attributes(const std::string& p, const std::function<void(fmt::AttributeEntry&)>& edit) {
  const PackageReader r(p);
  for (size_t i = 0; i < r.toc().size(); ++i)
    if (r.toc()[i].kind == uint32_t(fmt::ChunkKind::kSegmentAttributes) ||
        r.toc()[i].kind == uint32_t(fmt::ChunkKind::kPointAttributes)) {
      patch_chunk(p, i, [&](uint8_t* chunk, size_t) {
        uint64_t n = 0;
        fmt::AttributeEntry* e = section<fmt::AttributeEntry>(chunk, SectionType::kAttrEntries, &n);
        for (uint64_t k = 0; k < n; ++k)
          if (e[k].triangle_count) return edit(e[k]);
      });
      return chunk_label(r.toc()[i], i);
    }
  throw std::runtime_error("no attribute chunk");
}

TEST_F(Limits, AttributeTriangleRangeThatWrapsIsRejected) {
  const std::string p = copy(bases().lantern);
  const std::string label = patch_attributes(p, [](fmt::AttributeEntry& e) { e.triangle_first = ~uint64_t(0) - 1; });
  try {
    const PackageReader r(p);
    const AttributeLookup lookup(r);  // rtpack-trace --shading
    FAIL() << "loaded";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ExitCode::kInputInvalid);
    EXPECT_TRUE(contains_all(e.what(), {label, "triangle_first 18446744073709551614 + triangle_count"})) << e.what();
  }
  expect_inspect_problem(p, {label, "triangle_first 18446744073709551614 + triangle_count"}, true);
}

TEST_F(Limits, AttributeMeshIdDoesNotSizeTables) {
  // A mesh id of 2^32-1 used to size a table of 2^32 entries (48 GB); later it cost one entry and its
  // mesh shaded as zeros with exit 0. Now it is refused against the mesh table before anything is sized.
  const std::string p = copy(bases().lantern);
  const std::string label = patch_attributes(p, [](fmt::AttributeEntry& e) { e.mesh = 0xFFFFFFFFu; });
  try {
    const PackageReader r(p);
    const AttributeLookup lookup(r);
    FAIL() << "loaded an attribute entry of mesh 2^32-1";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ExitCode::kInputInvalid);
    EXPECT_TRUE(contains_all(e.what(), {label, "mesh 4294967295 out of range"})) << e.what();
  }
  expect_inspect_problem(p, {label, "mesh 4294967295 out of range"}, true);
}

// The header's world bounds frame the automatic camera: NaN or inverted ones, with every checksum intact,
// gave a blank image and exit 0; --verify names them.
TEST_F(Limits, VerifyReportsBadWorldBounds) {
  const std::string p = copy(bases().forest);
  patch_header(p, [](fmt::Header& h) { h.bounds_lo[1] = std::numeric_limits<float>::quiet_NaN(); });
  expect_inspect_problem(p, {"header: world bounds on y are [nan,", "not finite with min <= max"}, true);
  const std::string q = copy(bases().forest);
  patch_header(q, [](fmt::Header& h) { std::swap(h.bounds_lo[2], h.bounds_hi[2]); });
  expect_inspect_problem(q, {"header: world bounds on z are", "not finite with min <= max"}, true);
}

// A camera's world transform must be what the converter writes (finite, a rotation): all zeros gave zero
// directions and 1e300 infinite ones, both a blank image with exit 0.
TEST(CameraWorld, MustBeAFiniteRotation) {
  const double good[12] = {0, 0, 1, 5, 0, 1, 0, -2, -1, 0, 0, 3};  // a turn about y, translated
  EXPECT_NO_THROW(check_camera_world(good, "/cameras/0/world"));
  double zero[12] = {}, huge[12], nan[12];
  for (int i = 0; i < 12; ++i) huge[i] = good[i], nan[i] = good[i];
  huge[7] = 1e300;
  nan[5] = std::numeric_limits<double>::quiet_NaN();
  for (const auto& [m, want] : {std::pair<const double*, std::string>{zero, "/cameras/0/world: the 3x3 part has determinant 0"},
                                {huge, "/cameras/0/world/7: 1e+300 is not a finite coordinate"},
                                {nan, "/cameras/0/world/5: nan is not a finite coordinate"}}) {
    try {
      check_camera_world(m, "/cameras/0/world");
      ADD_FAILURE() << want << ": accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ExitCode::kInputInvalid);
      EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << e.what();
    }
  }
}

TEST_F(Limits, VerifyReportsNonZeroPadding) {
  const std::string p = copy(bases().forest);
  const PackageReader r0(p);
  size_t gap_chunk = r0.toc().size();
  for (size_t i = 0; i < r0.toc().size() && gap_chunk == r0.toc().size(); ++i)
    if (r0.toc()[i].stored_size % fmt::kAlignment) gap_chunk = i;
  ASSERT_LT(gap_chunk, r0.toc().size());
  const uint64_t gap_at = r0.toc()[gap_chunk].offset + r0.toc()[gap_chunk].stored_size;
  const std::string gap_label = chunk_label(r0.toc()[gap_chunk], gap_chunk);
  {
    std::fstream f(p, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(300);
    f.put(char(0x10));  // the header block after the 128-byte header: no checksum covers it
    f.seekp(std::streamoff(gap_at));
    f.put(char(0x01));  // zero padding after a chunk
  }
  expect_inspect_problem(p, {"header block padding", "byte 300 of the file is not 0"}, true);
  expect_inspect_problem(p, {"padding after " + gap_label, "byte " + std::to_string(gap_at)}, true);
  const ToolRun t = run(tool("rtpack-inspect") + " --verify " + p, dir);
  EXPECT_EQ(t.code, 3) << t.out;
}

size_t open_descriptors() { return size_t(std::distance(fs::directory_iterator("/proc/self/fd"), fs::directory_iterator())); }

// A package refused while it is opened (here: a bad magic, then a truncated file) closes its file: a
// renderer or service that is handed many bad packages must not run out of descriptors (fuzz_package did,
// after ~36,000 inputs, when the reader's constructor threw past its open file).
TEST_F(Limits, RefusedPackagesCloseTheirFile) {
  const std::string bad_magic = copy(bases().forest);
  {
    std::fstream f(bad_magic, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(0);
    f.put('X');
  }
  const fs::path truncated = dir / "truncated.rtp";
  std::ofstream(truncated, std::ios::binary) << slurp(bases().forest).substr(0, 5000);
  const size_t before = open_descriptors();
  for (int i = 0; i < 200; ++i)
    for (const std::string& p : {bad_magic, truncated.string()}) EXPECT_THROW(PackageReader r(p), Error);
  EXPECT_EQ(open_descriptors(), before);
}

// Plain rtpack-trace (no --verify) on hostile packages: exit 3 naming the chunk and the field, no
// hit file written.
TEST_F(Limits, PlainTraceExitsThreeOnHostilePackages) {
  std::vector<fmt::Ray> rays(64);
  for (size_t i = 0; i < rays.size(); ++i)
    rays[i] = {{float(i) * 0.5f - 16.f, 50.f, float(i % 8) - 4.f}, 0.f, {0.01f, -1.f, 0.02f}, 1e30f};
  const fs::path ray_file = dir / "rays.bin";
  std::ofstream(ray_file, std::ios::binary)
      .write(reinterpret_cast<const char*>(rays.data()), std::streamsize(rays.size() * sizeof(fmt::Ray)));
  {  // a mesh BVH node that is its own child
    const std::string p = copy(bases().forest);
    const auto [index, label] = chunk_of(p, fmt::ChunkKind::kMeshSegment, 0);
    patch_chunk(p, index, [](uint8_t* chunk, size_t) {
      auto* e = section<fmt::MeshEntry>(chunk, SectionType::kMeshEntries);
      auto* nodes = section<fmt::WideNode<kW>>(chunk, SectionType::kNodes);
      nodes[e[0].node_first].child[0] = 0;  // node 0 (the root) its own child
    });
    const ToolRun t =
        run(tool("rtpack-trace") + " " + p + " --rays " + ray_file.string() + " --hits " + (dir / "h.bin").string(), dir);
    EXPECT_EQ(t.code, 3) << t.err;
    EXPECT_TRUE(contains_all(t.err, {label, "node 0 lane 0: child 0 is not after its parent"})) << t.err;
    EXPECT_FALSE(fs::exists(dir / "h.bin"));
  }
  {  // a global instance id out of range (it would be written into the hit file)
    const std::string p = copy(bases().forest);
    const auto [index, label] = chunk_of(p, fmt::ChunkKind::kBatchingPoint, 0);
    patch_chunk(p, index, [](uint8_t* chunk, size_t) { section<uint32_t>(chunk, SectionType::kGlobalIds)[0] = 0x7FFFFFFFu; });
    const ToolRun t =
        run(tool("rtpack-trace") + " " + p + " --rays " + ray_file.string() + " --hits " + (dir / "h.bin").string(), dir);
    EXPECT_EQ(t.code, 3) << t.err;
    EXPECT_TRUE(contains_all(t.err, {label, "global id 0 = 2147483647 out of range"})) << t.err;
  }
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
