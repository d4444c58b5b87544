// libFuzzer harness: the package reader and every chunk decoder. The input is a whole .rtp file;
// before it is read, the harness re-seals what checksums protect (every in-file chunk's CRC-32C, the
// TOC CRC, the header CRC), so mutations reach the structural checks instead of stopping at a CRC
// mismatch. Then, as the tools do: rtpack-trace's in-core load and a few rays traced through it (every
// ISA, both orders), the attribute lookup of --shading on the hits, the out-of-core tracer at its
// minimum budget (closest, then any hit with read-ahead), and rtpack-inspect --verify.
// Any rtp::Error is a clean rejection; crashes, UB, hangs and huge allocations are bugs.
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "fuzz_util.h"
#include "reseal.h"
#include "reader/attribute_lookup.h"
#include "inspect/inspect.h"
#include "package/writer.h"
#include "reader/reader.h"
#include "trace/out_of_core.h"
#include "trace/package_tracer.h"

namespace {

// Rays from outside the package's bounds toward it and from inside, fixed so runs are reproducible.
std::vector<rtp::fmt::Ray> probe_rays() {
  std::vector<rtp::fmt::Ray> rays;
  const float inf = std::numeric_limits<float>::infinity();
  for (int i = 0; i < 64; ++i) {
    const float a = float(i) * 0.37f, b = float(i % 7) * 0.9f - 3.f;
    rays.push_back({{10.f * std::cos(a), b, 10.f * std::sin(a)}, 0.f, {-std::cos(a), -b * 0.1f, -std::sin(a)}, inf});
    rays.push_back({{0.f, 0.f, 0.f}, 0.f, {std::cos(a), std::sin(a) * 0.5f, std::sin(a)}, inf});
  }
  return rays;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::vector<uint8_t> bytes(data, data + size);
  rtp::fuzz::reseal_package(bytes);
  const std::string path = rtp::fuzz::write_input("input.rtp", bytes.data(), bytes.size());
  rtp::fuzz::run_guarded([&] {
    const rtp::PackageReader reader(path);
    rtp::fuzz::run_guarded([&] {  // rtpack-trace [--shading]
      const auto tracer = rtp::load_package_in_core(reader);
      static const std::vector<rtp::fmt::Ray> rays = probe_rays();
      std::vector<rtp::fmt::Hit> hits(rays.size());
      std::vector<uint8_t> occluded(rays.size());
      const rtp::Isa best = rtp::detect_isa();
      for (int isa = 0; isa <= int(best); ++isa)
        for (auto order : {rtp::TraversalOrder::kOctantStack, rtp::TraversalOrder::kActiveList}) {
          rtp::PackageTraceOptions opt;
          opt.isa = rtp::Isa(isa);
          opt.order = order;
          tracer->closest(rays.data(), hits.data(), rays.size(), opt);
          tracer->any(rays.data(), occluded.data(), rays.size(), opt);
        }
      const rtp::AttributeLookup lookup(reader);
      for (const auto& h : hits) (void)lookup.shade(h);
    });
    rtp::fuzz::run_guarded([&] {  // rtpack-trace --memory-budget: the out-of-core loader and tracer
      const auto ooc = rtp::open_out_of_core(reader, rtp::minimum_budget(reader));
      static const std::vector<rtp::fmt::Ray> rays = probe_rays();
      std::vector<rtp::fmt::Hit> hits(rays.size());
      std::vector<uint8_t> occluded(rays.size());
      rtp::PackageTraceOptions opt;
      ooc->closest(rays.data(), hits.data(), rays.size(), opt);
      ooc->set_prefetch(true);
      ooc->any(rays.data(), occluded.data(), rays.size(), opt);
    });
    rtp::fuzz::run_guarded([&] {  // rtpack-inspect --verify --chunks
      rtp::InspectOptions o;
      o.verify = o.chunks = true;
      (void)rtp::inspect_package(reader, o);
    });
  });
  return 0;
}
