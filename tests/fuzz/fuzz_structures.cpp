// libFuzzer harness over the format-7 structures (issue 58, docs/fuzzing.md): an input is not a file but
// an edit script for one of a few valid packages (scripts/fuzz writes them, stored chunks; paths in
// $RTP_FUZZ_BASES): byte 0 picks the package, byte 1 the structure, byte 2 the chunk holding it, then
// 8-byte edits (element index, byte in the element, operation, value) inside that section. The edited
// package is re-sealed (valid CRCs) and read by every reader: rtpack-inspect --verify, the in-core tracer
// (closest and any hit, culling off and on), the --shading lookup, the out-of-core tracer at its minimum
// budget. Besides crashes, UB, hangs and huge allocations, this is a differential test: where a reader
// accepts the edited package, its answers are compared ray by ray with the intact package's.
//  - An edit --verify accepts whose answers differ (from any reader) aborts: a wrong answer with exit 0
//    that nothing catches. Except where the edit is to data any value of which is a valid package (the
//    transform of an instance record, attribute vertex indices), there the answers may differ.
//  - An edit the tracer accepts whose answers differ but --verify refuses is counted, not a failure: the
//    tracers run the cheap checks at decode, --verify the expensive ones (SPEC §4.7: a voxel grid's cells).
// The counts per structure are printed when the process exits.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "../chunk_sections.h"
#include "fuzz_util.h"
#include "inspect/inspect.h"
#include "reader/attribute_lookup.h"
#include "reader/reader.h"
#include "reseal.h"
#include "trace/out_of_core.h"
#include "trace/package_tracer.h"

namespace {

using rtp::fmt::ChunkKind;
using rtp::fmt::SectionType;

// What a structure is, where it lives, and its bytes [0, data_end) of each element that are data: any value
// there makes a valid package with other answers (0: none).
struct Structure {
  const char* name;
  ChunkKind kind;
  SectionType section;
  uint32_t element;  // bytes (0: the package's CullNode<W>)
  uint32_t data_end;
};
const Structure kStructures[] = {
    {"point grids", ChunkKind::kBatchingPoints, SectionType::kPointGrids, 32, 0},
    {"point descriptors", ChunkKind::kBatchingPoints, SectionType::kPointDescs, 64, 0},
    {"DAG node words", ChunkKind::kDagPool, SectionType::kDagNodes, 4, 0},
    {"DAG leaves", ChunkKind::kDagPool, SectionType::kDagLeaves, 8, 0},
    {"instance-box nodes", ChunkKind::kDagPool, SectionType::kCullNodes, 0, 0},
    {"segment attribute entries", ChunkKind::kSegmentAttributes, SectionType::kAttrEntries, 40, 0},
    {"point attribute entries", ChunkKind::kPointAttributes, SectionType::kAttrEntries, 40, 0},
    {"attribute triangle ids", ChunkKind::kPointAttributes, SectionType::kAttrTriIds, 4, 0},
    {"attribute triangles", ChunkKind::kPointAttributes, SectionType::kAttrTriangles, 12, 12},
    {"mesh segment entries", ChunkKind::kMeshSegment, SectionType::kMeshEntries, 32, 0},
    {"piece entries", ChunkKind::kBatchingPoint, SectionType::kMeshEntries, 32, 0},
    {"instance records", ChunkKind::kBatchingPoint, SectionType::kInstances, 72, 60},
    {"mesh slots", ChunkKind::kBatchingPoint, SectionType::kMeshSlots, 4, 0},
    {"global ids", ChunkKind::kBatchingPoint, SectionType::kGlobalIds, 4, 0},
    {"instance table", ChunkKind::kInstances, SectionType::kInstanceRefs, 20, 0},
    {"mesh table", ChunkKind::kMeshes, SectionType::kMeshTable, 32, 0},
};
constexpr size_t kCount = sizeof kStructures / sizeof kStructures[0];

// The answers of every reader; `ok` false where the reader refused the package.
struct Answers {
  bool verify_ok = false, core_ok = false, shade_ok = false, ooc_ok = false;
  std::string verify_first;  // --verify's first problem
  std::vector<rtp::fmt::Hit> plain, culled, ooc;
  std::vector<uint8_t> any_plain, any_culled;
  std::vector<rtp::fmt::Shading> shading;
};

std::vector<rtp::fmt::Ray> rays_for(const rtp::fmt::Header& h) {
  std::vector<rtp::fmt::Ray> rays;
  uint64_t s = 0x9E3779B97F4A7C15ull;
  auto next = [&] {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    return float(double(s >> 11) * 0x1.0p-53);
  };
  float c[3], e = 0;
  for (int a = 0; a < 3; ++a) c[a] = 0.5f * (h.bounds_lo[a] + h.bounds_hi[a]), e = std::max(e, h.bounds_hi[a] - h.bounds_lo[a]);
  for (int i = 0; i < 256; ++i) {
    float o[3], d[3];
    for (int a = 0; a < 3; ++a) {
      const float target = h.bounds_lo[a] + next() * (h.bounds_hi[a] - h.bounds_lo[a]);
      o[a] = i % 4 == 3 ? target : c[a] + (next() - 0.5f) * 3.f * e;
      d[a] = i % 4 == 3 ? next() - 0.5f : target - o[a];
    }
    rays.push_back({{o[0], o[1], o[2]}, 0.f, {d[0], d[1], d[2]}, INFINITY});
  }
  return rays;
}

Answers answers(const std::string& path, const std::vector<rtp::fmt::Ray>& rays) {
  Answers a;
  rtp::fuzz::run_guarded([&] {
    const rtp::PackageReader reader(path);
    rtp::fuzz::run_guarded([&] {
      rtp::InspectOptions o;
      o.verify = true;
      const rtp::InspectResult r = rtp::inspect_package(reader, o);
      a.verify_ok = r.problems == 0;
      if (!r.listed.empty()) a.verify_first = r.listed.front();
    });
    rtp::fuzz::run_guarded([&] {
      const auto tracer = rtp::load_package_in_core(reader);
      rtp::PackageTraceOptions opt;
      a.plain.resize(rays.size()), a.culled.resize(rays.size());
      a.any_plain.resize(rays.size()), a.any_culled.resize(rays.size());
      opt.cull = false;
      tracer->closest(rays.data(), a.plain.data(), rays.size(), opt);
      tracer->any(rays.data(), a.any_plain.data(), rays.size(), opt);
      opt.cull = true;
      tracer->closest(rays.data(), a.culled.data(), rays.size(), opt);
      tracer->any(rays.data(), a.any_culled.data(), rays.size(), opt);
      a.core_ok = true;
      const rtp::AttributeLookup lookup(reader);
      for (const auto& hit : a.plain) a.shading.push_back(lookup.shade(hit));
      a.shade_ok = true;
    });
    rtp::fuzz::run_guarded([&] {
      const auto ooc = rtp::open_out_of_core(reader, rtp::minimum_budget(reader));
      a.ooc.resize(rays.size());
      rtp::PackageTraceOptions opt;
      ooc->closest(rays.data(), a.ooc.data(), rays.size(), opt);
      a.ooc_ok = true;
    });
  });
  return a;
}

template <class T>
bool same(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

// Which answers of an accepted package differ from the intact one's ("" when none).
std::string differences(const Answers& got, const Answers& want) {
  std::string d;
  if (got.core_ok && !same(got.plain, want.plain)) d += " closest";
  if (got.core_ok && !same(got.culled, want.plain)) d += " closest-culled";
  if (got.core_ok && !same(got.any_plain, want.any_plain)) d += " any";
  if (got.core_ok && !same(got.any_culled, want.any_plain)) d += " any-culled";
  if (got.shade_ok && !same(got.shading, want.shading)) d += " shading";
  if (got.ooc_ok && !same(got.ooc, want.plain)) d += " out-of-core";
  return d;
}

struct Base {
  std::vector<uint8_t> bytes;
  std::vector<rtp::fmt::Ray> rays;
  Answers intact;
};

// Per structure: edited packages read; refused by --verify, no reader answering otherwise; accepted by
// --verify, the same answers; other answers after a data edit; a tracer's other answers, --verify refusing.
struct Counts {
  uint64_t inputs = 0, refused = 0, same = 0, differ_data = 0, differ_verify_refused = 0;
};
struct Stats {
  Counts c[kCount];
  ~Stats() {
    std::fprintf(stderr, "fuzz_structures: %-26s %8s %8s %8s %8s %8s\n", "structure", "inputs", "refused", "same", "data",
                 "verify");
    for (size_t s = 0; s < kCount; ++s)
      if (c[s].inputs)
        std::fprintf(stderr, "fuzz_structures: %-26s %8llu %8llu %8llu %8llu %8llu\n", kStructures[s].name,
                     (unsigned long long)c[s].inputs, (unsigned long long)c[s].refused, (unsigned long long)c[s].same,
                     (unsigned long long)c[s].differ_data, (unsigned long long)c[s].differ_verify_refused);
    std::fprintf(stderr,
                 "fuzz_structures: refused: --verify refuses, every accepting reader's answers = intact; same: --verify accepts, "
                 "answers = intact; data: other answers after a data edit; verify: a tracer accepted with other answers, "
                 "--verify refuses\n");
  }
};
Stats stats;

std::vector<Base>& bases() {
  static std::vector<Base> b = [] {
    std::vector<Base> out;
    const char* list = std::getenv("RTP_FUZZ_BASES");
    if (!list || !*list) {
      std::fprintf(stderr, "fuzz_structures: set RTP_FUZZ_BASES to a ':'-separated list of packages (scripts/fuzz does)\n");
      std::abort();
    }
    std::string all = list;
    for (size_t start = 0; start <= all.size();) {
      const size_t end = std::min(all.find(':', start), all.size());
      const std::string path = all.substr(start, end - start);
      start = end + 1;
      if (path.empty()) continue;
      std::ifstream f(path, std::ios::binary);
      Base base;
      base.bytes.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
      const rtp::PackageReader reader(path);  // a base that does not open is a setup error: let it throw
      base.rays = rays_for(reader.header());
      base.intact = answers(path, base.rays);
      if (!base.intact.verify_ok || !base.intact.core_ok || !base.intact.ooc_ok || !same(base.intact.culled, base.intact.plain)) {
        std::fprintf(stderr, "fuzz_structures: base %s is not sound (verify %d, in core %d, out of core %d, culling %s)\n",
                     path.c_str(), base.intact.verify_ok, base.intact.core_ok, base.intact.ooc_ok,
                     same(base.intact.culled, base.intact.plain) ? "same" : "differs");
        std::abort();
      }
      out.push_back(std::move(base));
    }
    return out;
  }();
  return b;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 3) return 0;
  const Base& base = bases()[data[0] % bases().size()];
  const size_t si = data[1] % kCount;
  const Structure& st = kStructures[si];
  std::vector<uint8_t> f = base.bytes;
  rtp::fmt::Header h;
  std::memcpy(&h, f.data(), sizeof h);
  // The chunks of this kind (the bases are small: every TOC entry lies inside the file).
  std::vector<rtp::fmt::TocEntry> chunks;
  for (uint64_t i = 0; i < h.toc_count; ++i) {
    rtp::fmt::TocEntry e;
    std::memcpy(&e, f.data() + h.toc_offset + i * h.toc_entry_size, sizeof e);
    if (e.kind == uint32_t(st.kind) && e.compression == uint32_t(rtp::fmt::Compression::kNone)) chunks.push_back(e);
  }
  if (chunks.empty()) return 0;
  const rtp::fmt::TocEntry& e = chunks[data[2] % chunks.size()];
  uint64_t count = 0;
  uint8_t* sec = rtp::test::section<uint8_t>(f.data() + e.offset, st.section, &count);
  const uint32_t element = st.element ? st.element : uint32_t(rtp::fmt::cull_node_bytes(h.bvh_width));
  if (!sec || count == 0) return 0;
  bool data_edit = false;
  for (size_t k = 3; k + 8 <= size && k < 3 + 8 * 8; k += 8) {
    uint32_t index, value16;
    std::memcpy(&index, data + k, 4);
    const uint32_t byte = data[k + 4] % element, op = data[k + 5] % 4;
    value16 = uint32_t(data[k + 6]) | uint32_t(data[k + 7]) << 8;
    uint8_t* el = sec + uint64_t(index % count) * element;
    data_edit |= (op >= 2 ? byte & ~3u : byte) < st.data_end;
    switch (op) {
      case 0: el[byte] ^= uint8_t(value16 ? value16 : 1); break;  // flip bits
      case 1: el[byte] = uint8_t(value16); break;                 // set a byte
      case 2: {                                                   // set the aligned 32-bit word to a small or huge value
        const uint32_t at = byte & ~3u, v = value16 & 0x8000 ? 0xFFFF0000u | value16 : value16;
        if (at + 4 <= element) std::memcpy(el + at, &v, 4);
        break;
      }
      default: {  // add a small signed delta to the aligned word
        const uint32_t at = byte & ~3u;
        if (at + 4 > element) break;
        uint32_t w;
        std::memcpy(&w, el + at, 4);
        w += uint32_t(int32_t(int8_t(value16)));
        std::memcpy(el + at, &w, 4);
      }
    }
  }
  if (f == base.bytes) return 0;
  rtp::fuzz::reseal_package(f);
  const std::string path = rtp::fuzz::write_input("edited.rtp", f.data(), f.size());
  const Answers got = answers(path, base.rays);
  Counts& c = stats.c[si];
  ++c.inputs;
  const std::string d = differences(got, base.intact);
  if (d.empty()) {
    ++(got.verify_ok ? c.same : c.refused);
  } else if (data_edit) {
    ++c.differ_data;
  } else if (!got.verify_ok) {
    ++c.differ_verify_refused;
    // RTP_FUZZ_VERBOSE=1: what each of these edited and what --verify said, to tell the classes apart.
    if (const char* v = std::getenv("RTP_FUZZ_VERBOSE"); v && *v == '1')
      std::fprintf(stderr, "fuzz_structures: %s (chunk kind %u id %llu) edited: answers differ:%s; --verify: %s\n", st.name,
                   e.kind, (unsigned long long)e.id, d.c_str(), got.verify_first.c_str());
  } else {
    std::fprintf(stderr, "fuzz_structures: %s edited, --verify accepts, answers differ:%s\n", st.name, d.c_str());
    std::abort();
  }
  return 0;
}
