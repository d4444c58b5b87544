// libFuzzer harness: the ray-file reader of rtpack-trace (rtp::read_ray_file), then, when
// $RTP_FUZZ_PACKAGE names a package (scripts/fuzz converts a sample), the rays traced through it in
// core as rtpack-trace does: closest and any hit, every ISA the CPU has, both traversal orders, with
// and without culling. Hostile rays (NaN, Inf, huge, denormal, tnear > tfar) must give misses or hits,
// never a crash or a hang.
#include <cstdlib>
#include <limits>
#include <memory>

#include "fuzz_util.h"
#include "trace/package_tracer.h"
#include "reader/ray_file.h"

namespace {

const rtp::PackageTracer* tracer() {
  static const std::unique_ptr<rtp::PackageTracer> t = []() -> std::unique_ptr<rtp::PackageTracer> {
    const char* p = std::getenv("RTP_FUZZ_PACKAGE");
    if (!p || !*p) return nullptr;
    const rtp::PackageReader reader(p);
    return rtp::load_package_in_core(reader);
  }();
  return t.get();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = rtp::fuzz::write_input("input.rays", data, size);
  rtp::fuzz::run_guarded([&] {
    const std::vector<rtp::fmt::Ray> rays = rtp::read_ray_file(path);
    const rtp::PackageTracer* t = tracer();
    if (!t || rays.empty()) return;
    std::vector<rtp::fmt::Hit> hits(rays.size());
    std::vector<uint8_t> occluded(rays.size());
    const rtp::Isa best = rtp::detect_isa();
    for (int isa = 0; isa <= int(best); ++isa)
      for (auto order : {rtp::TraversalOrder::kOctantStack, rtp::TraversalOrder::kActiveList})
        for (bool cull : {true, false}) {
          rtp::PackageTraceOptions opt;
          opt.isa = rtp::Isa(isa);
          opt.order = order;
          opt.cull = cull;
          t->closest(rays.data(), hits.data(), rays.size(), opt);
          t->any(rays.data(), occluded.data(), rays.size(), opt);
          for (size_t i = 0; i < rays.size(); ++i) {  // formats/ray_file.h: invalid rays are misses
            const bool hit = hits[i].t != std::numeric_limits<float>::infinity();
            if ((hit || occluded[i]) && !rtp::ray_is_valid(rays[i])) std::abort();
            if (hit && !(hits[i].t >= rays[i].tnear && hits[i].t <= rays[i].tfar)) std::abort();
          }
        }
  });
  return 0;
}
