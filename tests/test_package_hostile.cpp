// The package trust boundary (lib/reader/check_chunks.h, formats/SPEC.md §4 "Structural checks at
// decode"): packages converted from a real sample, then one field patched with every checksum
// re-sealed, so only the structural checks can catch it. Each must be rejected by the in-core tracer
// (what rtpack-trace loads), by rtpack-inspect and by --verify with exit 3 and a message naming the chunk
// and the field: never a crash, a hang, an out-of-range id in the hit file, or gigabytes allocated.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>

#include "formats/bvh_layout.h"
#include "formats/chunk.h"
#include "formats/dag.h"
#include "formats/top_level.h"
#include "hostile_package.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using fmt::ChildRef;
using fmt::SectionType;

// A mesh segment's entry k (with inner nodes) and one lane of its nodes holding an inner child.
struct InnerLane {
  uint64_t entry = 0, node = 0;  // node relative to the entry
  int lane = 0;
  uint32_t id = 0;
};
InnerLane find_inner_lane(uint8_t* chunk, SectionType nodes_type, const fmt::MeshEntry* entries, uint64_t ne, bool want_nonroot) {
  const auto* nodes = section<fmt::WideNode<kW>>(chunk, nodes_type);
  for (uint64_t k = 0; k < ne; ++k)
    for (uint64_t n = want_nonroot ? 1 : 0; n < entries[k].node_count; ++n)
      for (int l = 0; l < kW; ++l) {
        const uint32_t c = nodes[entries[k].node_first + n].child[l];
        if (!ChildRef::is_empty(c) && !ChildRef::is_leaf(c)) return {k, n, l, entries[k].id};
      }
  throw std::runtime_error("no inner lane");
}

// Patches mesh segment 0's BVH: `edit(node, entry)` on the first node holding an inner child lane.
std::string patch_segment(const std::string& path, bool nonroot,
                          const std::function<void(fmt::WideNode<kW>& node, fmt::MeshEntry& e, const InnerLane& at)>& edit,
                          InnerLane* where = nullptr) {
  const auto [index, label] = chunk_of(path, fmt::ChunkKind::kMeshSegment, 0);
  patch_chunk(path, index, [&](uint8_t* chunk, size_t) {
    uint64_t ne = 0;
    auto* entries = section<fmt::MeshEntry>(chunk, SectionType::kMeshEntries, &ne);
    auto* nodes = section<fmt::WideNode<kW>>(chunk, SectionType::kNodes);
    const InnerLane at = find_inner_lane(chunk, SectionType::kNodes, entries, ne, nonroot);
    if (where) *where = at;
    edit(nodes[entries[at.entry].node_first + at.node], entries[at.entry], at);
  });
  return label;
}

std::string entry_name(const InnerLane& at) {
  return "mesh " + std::to_string(at.id) + " (entry " + std::to_string(at.entry) + ")";
}

TEST_F(Hostile, NodeThatIsItsOwnChild) {
  const std::string p = copy(bases().forest);
  InnerLane at;
  const std::string label = patch_segment(
      p, false, [](fmt::WideNode<kW>& n, fmt::MeshEntry&, const InnerLane& a) { n.child[a.lane] = uint32_t(a.node); }, &at);
  expect_everywhere(p, {label, entry_name(at), "node " + std::to_string(at.node) + " lane " + std::to_string(at.lane),
                        "child " + std::to_string(at.node) + " is not after its parent"});
}

TEST_F(Hostile, ChildPointingBackToTheRoot) {
  const std::string p = copy(bases().forest);
  InnerLane at;
  const std::string label = patch_segment(
      p, true, [](fmt::WideNode<kW>& n, fmt::MeshEntry&, const InnerLane& a) { n.child[a.lane] = 0; }, &at);
  expect_everywhere(p, {label, entry_name(at), "child 0 is not after its parent"});
}

TEST_F(Hostile, ChildIndexOutOfRange) {
  const std::string p = copy(bases().forest);
  InnerLane at;
  uint32_t bad = 0;
  const std::string label = patch_segment(
      p, false,
      [&](fmt::WideNode<kW>& n, fmt::MeshEntry& e, const InnerLane& a) {
        bad = e.node_count + 1000;
        n.child[a.lane] = bad;
      },
      &at);
  expect_everywhere(p, {label, entry_name(at), "child " + std::to_string(bad) + " out of range"});
}

TEST_F(Hostile, NodeReferencedTwice) {  // a DAG instead of a tree: exponential walks
  const std::string p = copy(bases().forest);
  InnerLane at;
  const std::string label = patch_segment(
      p, false,
      [](fmt::WideNode<kW>& n, fmt::MeshEntry&, const InnerLane& a) {
        for (int l = 0; l < kW; ++l)
          if (l != a.lane && !ChildRef::is_empty(n.child[l])) {
            n.child[l] = n.child[a.lane];
            return;
          }
      },
      &at);
  expect_everywhere(p, {label, entry_name(at), "is referenced a second time"});
}

TEST_F(Hostile, MeshBvhRootOutOfRange) {
  const std::string p = copy(bases().forest);
  InnerLane at;
  uint32_t bad = 0;
  const std::string label = patch_segment(
      p, false,
      [&](fmt::WideNode<kW>&, fmt::MeshEntry& e, const InnerLane&) {
        bad = e.node_count + 5;
        e.root = bad;
      },
      &at);
  expect_everywhere(p, {label, entry_name(at), "root node " + std::to_string(bad) + " out of range"});
}

TEST_F(Hostile, LeafBlockRangeOutOfRange) {
  const std::string p = copy(bases().forest);
  InnerLane at;
  uint32_t first = 0;
  const std::string label = patch_segment(
      p, false,
      [&](fmt::WideNode<kW>& n, fmt::MeshEntry& e, const InnerLane& a) {
        first = e.block_count - 1;  // 2 blocks from the last one: one past the entry's blocks
        n.child[a.lane] = ChildRef::leaf(first, 2);
      },
      &at);
  expect_everywhere(
      p, {label, entry_name(at), "leaf blocks " + std::to_string(first) + ".." + std::to_string(first + 1) + " out of range"});
}

TEST_F(Hostile, EntryNodeRangeWrapsAndNonFiniteBoxAndBadOrder) {
  {
    const std::string p = copy(bases().forest);
    InnerLane at;
    const std::string label = patch_segment(
        p, false, [](fmt::WideNode<kW>&, fmt::MeshEntry& e, const InnerLane&) { e.node_first = 0xFFFFFFF0u; }, &at);
    expect_everywhere(p, {label, entry_name(at), "node_first 4294967280 + node_count"});
  }
  {
    const std::string p = copy(bases().forest);
    const std::string label = patch_segment(p, false, [](fmt::WideNode<kW>& n, fmt::MeshEntry&, const InnerLane& a) {
      n.hi[1][a.lane] = std::numeric_limits<float>::quiet_NaN();
    });
    expect_everywhere(p, {label, "box not finite or inverted on axis 1"});
  }
  {
    const std::string p = copy(bases().forest);
    const std::string label = patch_segment(p, false, [](fmt::WideNode<kW>& n, fmt::MeshEntry&, const InnerLane& a) {
      n.order[5][a.lane] = 13;  // lane 13 of an 8-wide node: reads past the node
    });
    expect_everywhere(p, {label, "octant order 5 names lane 13"});
  }
}

TEST_F(Hostile, SegmentLeafPrimOutOfRange) {
  const std::string p = copy(bases().forest);
  const auto [index, label] = chunk_of(p, fmt::ChunkKind::kMeshSegment, 0);
  uint64_t tris = 0;
  patch_chunk(p, index, [&](uint8_t* chunk, size_t) {
    auto* e = section<fmt::MeshEntry>(chunk, SectionType::kMeshEntries);
    auto* blocks = section<fmt::LeafBlock<kB>>(chunk, SectionType::kBlocks);
    tris = e[0].triangles;
    blocks[e[0].block_first].prim[0] = uint32_t(tris);
  });
  expect_everywhere(p, {label, "block 0 lane 0: prim " + std::to_string(tris) + " out of range"});
}

TEST_F(Hostile, InstanceLevelOfABatchingPoint) {
  struct Case {
    const char* name;
    std::function<std::string(uint8_t*)> edit;  // returns the expected field text
  };
  const std::vector<Case> cases = {
      {"global id",
       [](uint8_t* c) {
         section<uint32_t>(c, SectionType::kGlobalIds)[1] = 0xFFFFFF00u;
         return std::string("global id 1 = 4294967040 out of range");
       }},
      {"instance id",
       [](uint8_t* c) {
         uint64_t n = 0;
         section<fmt::InstanceRecord>(c, SectionType::kInstances, &n);
         section<uint32_t>(c, SectionType::kInstanceIds)[0] = uint32_t(n);
         return "instance id 0 = " + std::to_string(n) + " out of range";
       }},
      {"duplicated instance leaf",
       [](uint8_t* c) {
         uint32_t* ids = section<uint32_t>(c, SectionType::kInstanceIds);
         ids[1] = ids[0];
         return "instance id 1 = " + std::to_string(ids[0]) + " is referenced a second time";
       }},
      {"instance-leaf range",
       [](uint8_t* c) {
         uint64_t n_ids = 0;
         section<uint32_t>(c, SectionType::kInstanceIds, &n_ids);
         auto* te = section<fmt::MeshEntry>(c, SectionType::kInstanceBvh);
         auto* nodes = section<fmt::WideNode<kW>>(c, SectionType::kInstanceNodes);
         const uint32_t bad = ChildRef::leaf(uint32_t(n_ids), 1);
         if (ChildRef::is_leaf(te->root)) {
           te->root = bad;
         } else {
           for (uint32_t n = 0;; ++n)
             for (int l = 0; l < kW; ++l)
               if (ChildRef::is_leaf(nodes[n].child[l])) {
                 nodes[n].child[l] = bad;
                 return "leaf instance ids " + std::to_string(n_ids) + ".." + std::to_string(n_ids) + " out of range";
               }
         }
         return "root leaf: instance ids " + std::to_string(n_ids) + ".." + std::to_string(n_ids) + " out of range";
       }},
      {"instance BVH sizes",
       [](uint8_t* c) {
         section<fmt::MeshEntry>(c, SectionType::kInstanceBvh)->block_count += 1;
         return std::string("instance BVH entry");
       }},
      {"mesh slot",
       [](uint8_t* c) {
         uint64_t ne = 0, ns = 0;
         section<fmt::MeshEntry>(c, SectionType::kMeshEntries, &ne);
         section<uint32_t>(c, SectionType::kMeshSlots, &ns)[0] = fmt::kPieceBit | uint32_t(ne + 3);
         return "mesh slot 0 names piece entry " + std::to_string(ne + 3) + " out of range";
       }},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string p = copy(bases().forest);
    uint64_t id = 0;
    const size_t index = point_with_instances(p, id);
    const std::string label = chunk_of(p, fmt::ChunkKind::kBatchingPoint, id).second;
    std::string field;
    patch_chunk(p, index, [&](uint8_t* chunk, size_t) { field = c.edit(chunk); });
    expect_everywhere(p, {label, field});
  }
}

TEST_F(Hostile, TopLevelDuplicatedLeafAndCycle) {
  {  // two lanes naming the same batching point: the other one's hits would be lost
    const std::string p = copy(bases().forest);
    const auto [index, label] = chunk_of(p, fmt::ChunkKind::kTopLevelBvh, 0);
    uint32_t point = 0;
    patch_chunk(p, index, [&](uint8_t* chunk, size_t) {
      uint64_t n = 0;
      auto* top = section<fmt::TopNode>(chunk, SectionType::kTopNodes, &n);
      for (uint64_t k = 0; k < n; ++k) {
        int first = -1;
        for (int l = 0; l < 4; ++l) {
          const uint32_t c = top[k].child[l];
          if (c == fmt::TopNode::kEmpty || !(c & fmt::TopNode::kLeafBit)) continue;
          if (first < 0) {
            first = l;
          } else {
            top[k].child[l] = top[k].child[first];
            point = top[k].child[first] & ~fmt::TopNode::kLeafBit;
            return;
          }
        }
      }
      FAIL() << "no top node with two leaves";
    });
    expect_everywhere(p, {label, "batching point " + std::to_string(point) + " is a leaf a second time"});
  }
  {  // the root's inner child made the root itself: every traversal would loop
    const std::string p = copy(bases().forest);
    const auto [index, label] = chunk_of(p, fmt::ChunkKind::kTopLevelBvh, 0);
    patch_chunk(p, index, [&](uint8_t* chunk, size_t) {
      auto* top = section<fmt::TopNode>(chunk, SectionType::kTopNodes);
      for (int l = 0; l < 4; ++l)
        if (top[0].child[l] != fmt::TopNode::kEmpty && !(top[0].child[l] & fmt::TopNode::kLeafBit)) {
          top[0].child[l] = 0;
          return;
        }
      FAIL() << "the top-level root has no inner child";
    });
    expect_everywhere(p, {label, "node 0 lane", "child 0 is not after its parent"});
  }
}

TEST_F(Hostile, CullingGridIsCheckedAtDecode) {  // voxel::check_dags runs when the tracer loads, not only in --verify
  const std::string p = copy(bases().forest);
  const auto [index, label] = chunk_of(p, fmt::ChunkKind::kBatchingPoints, 0);
  const std::string pool = chunk_of(p, fmt::ChunkKind::kDagPool, 0).second;
  patch_chunk(p, index,
              [](uint8_t* chunk, size_t) { section<fmt::DagGrid>(chunk, SectionType::kPointGrids)[2].resolution = 48; });
  expect_tracer_rejects(p, {pool, "culling DAG of batching point 2: resolution 48 is not a power of two"});
  expect_inspect_problem(p, {label, "batching point 2", "resolution 48 is not a power of two"}, true);
  expect_inspect_problem(p, {label, "batching point 2", "resolution 48 is not a power of two"});  // plain inspect too
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
