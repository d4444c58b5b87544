// rtpack-bench: rtpack's timed answers against Embree's, ray by ray (bench_agreement.h).
#include "bench_agreement.h"

#include "oracle/compare.h"
#include "oracle/instance_reference.h"

namespace rtp::bench {

// TESTING.md: where rtpack and Embree disagree, a double reference from the glTF's own values decides.
// The instance-wise one: it costs nothing until a ray is disputed, and it works at any scene size.
Agreement agreement_closest(const Scene& scene, const KindData& k, const std::vector<fmt::Hit>& got) {
  const InstanceReference judge(scene);
  CompareOptions opt;
  opt.scene = &scene;
  opt.exact = &judge;
  const CompareReport r = compare_closest(k.rays.data(), k.ref_hits.data(), got.data(), k.rays.size(), opt, k.skip.data());
  Agreement a{r.agree(), r.edge_ties, r.precision_ties, r.failures, r.skipped, {}, r.reference_errors};
  if (!r.first_failures.empty()) a.first_failure = r.first_failures[0].describe();
  return a;
}

Agreement agreement_any(const Scene& scene, const KindData& k, const std::vector<uint8_t>& occ,
                        const std::vector<fmt::Hit>& own_closest) {
  const InstanceReference judge(scene);
  CompareOptions opt;
  opt.scene = &scene;
  opt.exact = &judge;
  const size_t n = k.rays.size();
  const AnyHitReport r = check_any_hit(k.rays.data(), k.ref_hits.data(), occ.data(), n, opt, k.skip.data(), own_closest.data());
  const AnyHitReport own = check_any_hit(k.rays.data(), own_closest.data(), occ.data(), n, opt);
  Agreement a{r.consistent, r.edge_ties, r.precision_ties, r.failures + own.failures, r.skipped, {}, r.reference_errors};
  if (!r.first_failures.empty())
    a.first_failure = r.first_failures[0].describe();
  else if (!own.first_failures.empty())
    a.first_failure = "(any hit vs rtpack's own closest hit)\n" + own.first_failures[0].describe();
  return a;
}

}  // namespace rtp::bench
