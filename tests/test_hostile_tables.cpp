// What a geometry chunk says about scene meshes and instances, checked against the resident instance and
// mesh tables at decode (lib/reader/check_references.h, formats/SPEC.md §4.6), and the instance records'
// transforms (§2.4). Each case was an exit-0 wrong answer before: a package converted from a real
// sample, one field patched with every checksum re-sealed; the tracer, rtpack-trace, rtpack-inspect and
// --verify must all refuse it with exit 3, naming the chunk and the field.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "formats/bvh_layout.h"
#include "formats/chunk.h"
#include "hostile_package.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using fmt::SectionType;

class HostileTables : public Hostile {
 protected:
  // A copy of `base` whose batching point `find` picks is patched by `edit(chunk)`, which returns the field
  // text; every reader must refuse it naming the chunk and that field.
  void expect_point_refused(const std::string& base, size_t (*find)(const std::string&, uint64_t&),
                            const std::function<std::string(uint8_t*)>& edit) {
    const std::string p = copy(base);
    uint64_t id = 0;
    const size_t index = find(p, id);
    const std::string label = chunk_of(p, fmt::ChunkKind::kBatchingPoint, id).second;
    std::string field;
    patch_chunk(p, index, [&](uint8_t* chunk, size_t) { field = edit(chunk); });
    expect_everywhere(p, {label, field});
  }
  // The records of a batching point with instances: `edit(records, count)` returns the field text.
  void records_case(const char* name, const std::function<std::string(fmt::InstanceRecord*, uint64_t)>& edit) {
    SCOPED_TRACE(name);
    expect_point_refused(bases().forest, point_with_instances, [&](uint8_t* chunk) {
      uint64_t n = 0;
      auto* records = section<fmt::InstanceRecord>(chunk, SectionType::kInstances, &n);
      return edit(records, n);
    });
  }
};

// Translation 1e308 with a NaN inverse: plain rtpack-trace answered 0 hits instead of 978, exit 0.
TEST_F(HostileTables, InstanceTransformsThatAreNotFiniteOrSingular) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  records_case("far translation", [](fmt::InstanceRecord* r, uint64_t n) {
    r[n - 1].translation[1] = 1e308;
    return "instance " + std::to_string(n - 1) + ": translation";
  });
  records_case("NaN inverse", [&](fmt::InstanceRecord* r, uint64_t) {
    r[0].inverse_linear[4] = nan;
    return std::string("instance 0: inverse linear part element 4 is not finite");
  });
  records_case("singular, not zeros", [](fmt::InstanceRecord* r, uint64_t) {
    for (int c = 0; c < 3; ++c) r[1].inverse_linear[3 + c] = r[1].inverse_linear[c];  // two equal rows
    return std::string("instance 1: inverse linear part is singular but not all zeros");
  });
  records_case("mirrored flag", [](fmt::InstanceRecord* r, uint64_t) {
    r[0].flags ^= 1u;
    return std::string("instance 0: flags");
  });
  records_case("reserved", [](fmt::InstanceRecord* r, uint64_t) {
    r[0].reserved = 7;
    return std::string("instance 0: reserved field is 7");
  });
}

// An instance table naming batching point 0x7FFFFFF0: plain rtpack-trace exited 0.
TEST_F(HostileTables, InstanceTableNamingAPointOutOfRange) {
  const std::string p = copy(bases().forest);
  const auto [index, label] = chunk_of(p, fmt::ChunkKind::kInstances, 0);
  patch_chunk(p, index, [](uint8_t* chunk, size_t) {
    section<fmt::InstanceRef>(chunk, SectionType::kInstanceRefs)[0].point = 0x7FFFFFF0u;
  });
  expect_everywhere(p, {label, "instance 0: batching point 2147483632 out of range"});
}

// An instance table naming a mesh the mesh table does not hold (SPEC §4.6, instance table).
TEST_F(HostileTables, InstanceTableNamingAMeshOutOfRange) {
  const std::string p = copy(bases().forest);
  const auto [index, label] = chunk_of(p, fmt::ChunkKind::kInstances, 0);
  patch_chunk(p, index,
              [](uint8_t* chunk, size_t) { section<fmt::InstanceRef>(chunk, SectionType::kInstanceRefs)[3].mesh = 77; });
  expect_everywhere(p, {label, "instance 3: mesh 77 out of range (5 meshes)"});
}

// An instance in no batching point (its mesh has no triangles) must say local 0 (SPEC §2.5).
TEST_F(HostileTables, InstanceTableLocalWithoutAPoint) {
  const std::string p = copy(bases().forest);
  const auto [index, label] = chunk_of(p, fmt::ChunkKind::kInstances, 0);
  patch_chunk(p, index, [](uint8_t* chunk, size_t) {
    fmt::InstanceRef& r = section<fmt::InstanceRef>(chunk, SectionType::kInstanceRefs)[5];
    r.point = fmt::InstanceRef::kNoPoint;
    r.local = 9;
  });
  expect_everywhere(p, {label, "instance 5: in no batching point but local 9"});
}

// One mesh with two entries in its segment (the second relabelled, with the first's triangle count so
// every other check passes).
TEST_F(HostileTables, MeshSegmentHoldingAMeshTwice) {
  const std::string p = copy(bases().forest);
  const auto [index, label] = chunk_of(p, fmt::ChunkKind::kMeshSegment, 0);
  uint32_t id = 0;
  patch_chunk(p, index, [&](uint8_t* chunk, size_t) {
    uint64_t n = 0;
    auto* e = section<fmt::MeshEntry>(chunk, SectionType::kMeshEntries, &n);
    ASSERT_GE(n, 2u);
    const uint64_t big = e[0].triangles >= e[1].triangles ? 0 : 1, small = 1 - big;
    id = e[big].id;
    e[small].id = e[big].id;
    e[small].triangles = e[big].triangles;  // its prims stay below the count
  });
  expect_everywhere(p, {label, "mesh " + std::to_string(id) + " has two entries"});
}

// Two records' global ids swapped (found by fuzz_structures): every range holds, but each hit reported
// the other instance's id (exit 0); only --verify compared them with the instance table.
TEST_F(HostileTables, GlobalIdsNotWhereTheInstanceTableSays) {
  const std::string p = copy(bases().forest);
  uint64_t point = 0;
  const size_t index = point_with_instances(p, point);
  const std::string label = chunk_of(p, fmt::ChunkKind::kBatchingPoint, point).second;
  uint32_t second = 0;
  patch_chunk(p, index, [&](uint8_t* chunk, size_t) {
    uint64_t n = 0;
    uint32_t* g = section<uint32_t>(chunk, SectionType::kGlobalIds, &n);
    ASSERT_GE(n, 2u);
    second = g[1];
    std::swap(g[0], g[1]);
  });
  expect_everywhere(p,
                    {label, "instance 0: global instance " + std::to_string(second) +
                                ", which the instance table places in batching point " + std::to_string(point) + " (local 1)"});
}

// The instance table's local index of an instance flipped: the point chunk holding it is refused when it
// is decoded (it no longer agrees with the table), by every reader.
TEST_F(HostileTables, InstanceTableLocalIndexFlipped) {
  const std::string p = copy(bases().forest);
  const auto [index, label] = chunk_of(p, fmt::ChunkKind::kInstances, 0);
  fmt::InstanceRef ref{};
  patch_chunk(p, index, [&](uint8_t* chunk, size_t) {
    fmt::InstanceRef& r = section<fmt::InstanceRef>(chunk, SectionType::kInstanceRefs)[3];
    r.local ^= 1;
    ref = r;
  });
  expect_everywhere(p, {chunk_of(p, fmt::ChunkKind::kBatchingPoint, ref.point).second,
                        "which the instance table places in batching point " + std::to_string(ref.point) + " (local " +
                            std::to_string(ref.local) + ")"});
}

// Mesh segment 0's chunk relabelled as segment 1: it then holds meshes the mesh table places in another
// segment. The tracer used them anyway (the hits as if intact, exit 0).
TEST_F(HostileTables, MeshSegmentChunkIdNotTheMeshTables) {
  const std::string p = copy(bases().forest);
  patch_stored(p, chunk_of(p, fmt::ChunkKind::kMeshSegment, 0).first, [](uint8_t*, fmt::TocEntry& e) { e.id = 1; });
  const std::string label = chunk_of(p, fmt::ChunkKind::kMeshSegment, 1).second;
  expect_everywhere(p, {label, "the mesh table places the mesh in segment 0, not in segment 1"});
}

// A mesh-segment entry whose triangle count is not the mesh table's (its leaves index a different mesh).
TEST_F(HostileTables, MeshSegmentEntryTrianglesNotTheMeshTables) {
  const std::string p = copy(bases().forest);
  const auto [index, label] = chunk_of(p, fmt::ChunkKind::kMeshSegment, 0);
  uint64_t tris = 0;
  patch_chunk(p, index, [&](uint8_t* chunk, size_t) {
    auto* e = section<fmt::MeshEntry>(chunk, SectionType::kMeshEntries);
    tris = e[0].triangles;
    e[0].triangles += 5;  // the prims stay in range: only the table can tell
  });
  expect_everywhere(p, {label, std::to_string(tris + 5) + " triangles, the mesh table says " + std::to_string(tris)});
}

// A mesh table naming a segment the package does not hold (SPEC §4.6, mesh table).
TEST_F(HostileTables, MeshTableSegmentOutOfRange) {
  const std::string p = copy(bases().forest);
  const auto [index, label] = chunk_of(p, fmt::ChunkKind::kMeshes, 0);
  std::string field;
  patch_chunk(p, index, [&](uint8_t* chunk, size_t) {
    uint64_t n = 0;
    fmt::MeshInfo* m = section<fmt::MeshInfo>(chunk, SectionType::kMeshTable, &n);
    for (uint64_t k = 0; k < n; ++k)
      if (m[k].segment != 0xFFFFFFFFu) {
        m[k].segment = 1000;
        field = "mesh " + std::to_string(k) + ": segment 1000 out of range";
        return;
      }
    FAIL() << "no mesh in a segment";
  });
  expect_everywhere(p, {label, field});
}

// A batching-point descriptor whose chunk id is not its index (SPEC §4.6, descriptors).
TEST_F(HostileTables, DescriptorChunkIdNotItsIndex) {
  const std::string p = copy(bases().forest);
  const auto [index, label] = chunk_of(p, fmt::ChunkKind::kBatchingPoints, 0);
  patch_chunk(p, index,
              [](uint8_t* chunk, size_t) { section<fmt::BatchingPointDesc>(chunk, SectionType::kPointDescs)[1].chunk_id = 0; });
  expect_everywhere(p, {label, "batching point 1: chunk_id 0 is not its index"});
}

// A descriptor's segment list reaching past the segment references (SPEC §4.6, descriptors): the
// out-of-core loader would read past the list to find the segments a point needs.
TEST_F(HostileTables, DescriptorSegmentRangePastTheReferences) {
  const std::string p = copy(bases().forest);
  const auto [index, label] = chunk_of(p, fmt::ChunkKind::kBatchingPoints, 0);
  uint64_t refs = 0;
  patch_chunk(p, index, [&](uint8_t* chunk, size_t) {
    section<uint32_t>(chunk, SectionType::kSegmentRefs, &refs);
    section<fmt::BatchingPointDesc>(chunk, SectionType::kPointDescs)[1].segment_count = uint32_t(refs) + 1;
  });
  ASSERT_GT(refs, 0u);
  expect_everywhere(p, {label, "batching point 1: segment_first", "outside the " + std::to_string(refs) + " segment references"});
}

// A descriptor whose bounds are inverted (SPEC §4.6): the top level and culling would trust them.
TEST_F(HostileTables, DescriptorBoundsInverted) {
  const std::string p = copy(bases().forest);
  const auto [index, label] = chunk_of(p, fmt::ChunkKind::kBatchingPoints, 0);
  patch_chunk(p, index, [](uint8_t* chunk, size_t) {
    fmt::BatchingPointDesc& d = section<fmt::BatchingPointDesc>(chunk, SectionType::kPointDescs)[2];
    std::swap(d.lo[1], d.hi[1]);
  });
  expect_everywhere(p, {label, "batching point 2: bounds not finite or inverted on axis 1"});
}

// The first batching point with at least `pieces` pieces, and its chunk index.
size_t point_with_n_pieces(const std::string& path, uint64_t& id, uint64_t pieces) {
  PackageReader r(path);
  for (size_t i = 0; i < r.toc().size(); ++i) {
    if (r.toc()[i].kind != uint32_t(fmt::ChunkKind::kBatchingPoint)) continue;
    AlignedBytes b = r.read(i);
    uint64_t n = 0;
    section<fmt::MeshEntry>(b.data(), SectionType::kMeshEntries, &n);
    if (n >= pieces) {
      id = r.toc()[i].id;
      return i;
    }
  }
  throw std::runtime_error("no batching point with " + std::to_string(pieces) + " pieces");
}
size_t point_with_pieces(const std::string& path, uint64_t& id) { return point_with_n_pieces(path, id, 1); }
size_t point_with_two_pieces(const std::string& path, uint64_t& id) { return point_with_n_pieces(path, id, 2); }

// A piece's leaf prim past its scene mesh's triangles: rtpack-trace wrote it into the hit file.
TEST_F(HostileTables, PieceLeafPrimPastItsMesh) {
  expect_point_refused(bases().lantern, point_with_pieces, [](uint8_t* chunk) {  // unique meshes: stored as pieces
    const auto* e = section<fmt::MeshEntry>(chunk, SectionType::kMeshEntries);
    section<fmt::LeafBlock<kB>>(chunk, SectionType::kBlocks)[e[0].block_first].prim[0] = 0x7FFFFFFFu;
    return "piece " + std::to_string(e[0].id) + " (entry 0): block 0 lane 0: prim 2147483647 out of range";
  });
}

// Found by fuzz_structures: a mesh slot naming another piece of the point: that piece traced twice, the
// other never (hits lost, exit 0; only --verify's coverage noticed). Each piece entry has one slot.
TEST_F(HostileTables, PieceEntryNamedByTwoSlots) {
  expect_point_refused(bases().lantern, point_with_two_pieces, [](uint8_t* chunk) {
    uint64_t n = 0;
    uint32_t* slots = section<uint32_t>(chunk, SectionType::kMeshSlots, &n);
    for (uint64_t s = 0; s < n; ++s)
      if ((slots[s] & fmt::kPieceBit) && (slots[s] & ~fmt::kPieceBit) == 1) slots[s] = fmt::kPieceBit | 0u;  // names entry 0
    return std::string("piece entry 0 is named by 2 mesh slots, expected 1");
  });
}

// Found by fuzz_structures: a piece entry's block range moved by one block, still inside the section: its
// leaves held another piece's triangles, outside their boxes (hits lost, exit 0; --verify alone saw it).
// The entries' ranges follow each other in entry order (SPEC §4.2).
TEST_F(HostileTables, PieceBlockRangeMovedInsideItsSection) {
  expect_point_refused(bases().lantern, point_with_two_pieces, [](uint8_t* chunk) {
    auto* e = section<fmt::MeshEntry>(chunk, SectionType::kMeshEntries);
    e[0].block_first = 1;
    return "piece " + std::to_string(e[0].id) + " (entry 0): node_first 0, block_first 1, expected 0 and 0";
  });
}

// Two records on one piece slot: the piece traced twice, the other record's piece never.
TEST_F(HostileTables, PieceSlotUsedByTwoRecords) {
  expect_point_refused(bases().lantern, point_with_two_pieces, [](uint8_t* chunk) {
    uint64_t n = 0;
    fmt::InstanceRecord* r = section<fmt::InstanceRecord>(chunk, SectionType::kInstances, &n);
    const uint32_t slot = std::min(r[0].mesh, r[1].mesh);
    r[0].mesh = r[1].mesh = slot;
    return "mesh slot " + std::to_string(slot) + " (a piece) is used by 2 instances, expected 1";
  });
}

// A mesh slot naming another instanced mesh than the instance table gives its instance.
TEST_F(HostileTables, MeshSlotNotTheInstancesMesh) {
  expect_point_refused(bases().forest, point_with_instances, [](uint8_t* chunk) {
    uint64_t nr = 0;
    uint32_t* slots = section<uint32_t>(chunk, SectionType::kMeshSlots);
    const auto* rec = section<fmt::InstanceRecord>(chunk, SectionType::kInstances, &nr);
    for (uint64_t k = 0; k < nr; ++k) {
      uint32_t& s = slots[rec[k].mesh];
      if (s & fmt::kPieceBit) continue;
      s ^= 1u;  // a neighbouring mesh id
      return "instance " + std::to_string(k) + ": its mesh slot names mesh " + std::to_string(s);
    }
    ADD_FAILURE() << "no instance of an instanced mesh";
    return std::string("?");
  });
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
