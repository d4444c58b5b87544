#pragma once
// Ray-by-ray comparison of a tracer against a reference (TESTING.md "The oracle").
//
// Verdict for each ray (ref = reference hit, got = candidate hit):
//   agree      both miss; or both hit and |t - t_ref| <= rel_tol * max(1, t_ref). The instance and
//              primitive may then differ (two triangles at the same t: a shared edge or vertex,
//              coincident or overlapping triangles); such rays are agreements, counted in
//              `same_t_other_prim` for information.
//   edge tie   any other outcome where the reference hit or the candidate hit lies within `edge_eps`
//              barycentric distance of a triangle edge (min(u, v, 1-u-v) <= edge_eps): the ray grazes
//              an edge and both answers are defensible. Counted, never a failure.
//   precision tie  (only when `scene` is given) any other outcome where one of the hits lies within
//              delta = precision_rel * M world units of an edge of its triangle, or where both hit and
//              each hit point lies within delta of the other's triangle plane (the same surface, hit
//              at a grazing angle: t is ill-conditioned as 1/cos). M = the largest coordinate magnitude
//              involved (ray origin, hit point, instance translation + scaled local vertex). Float
//              tracers cannot place a point more finely than a few ulp of M, so a small triangle far
//              from the origin is "near an edge" everywhere (samples/generated/far.glb at 3e6:
//              ulp = 0.25). Counted separately from edge ties, never a failure.
//   failure    everything else: a hit only one side sees away from edges, or both hit at different t.
//   skipped    the reference could not answer (e.g. Embree cannot take the ray: RayStatus::kUnsupported).
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "formats/ray_file.h"
#include "scene/scene.h"

namespace rtp {

class ExactReference;

struct CompareOptions {
  double rel_tol = 1e-4;    ///< t tolerance, relative to max(1, t_ref)
  double edge_eps = 1e-5;   ///< barycentric distance to an edge that makes a disagreement a tie
  size_t max_examples = 5;  ///< failures (and edge ties) kept with full details
  /// The scene both hits refer to: enables precision ties (nullptr: edge ties only).
  const Scene* scene = nullptr;
  double precision_rel = 4e-6;  ///< ~32 float ulps of the coordinate magnitude M
  /// TESTING.md: where the candidate and the reference disagree, the double brute-force reference
  /// decides. A ray the candidate answers as the double reference does is a
  /// reference error (Embree's float instance matrices far from the origin), not a failure; any other
  /// disagreement is judged against the double reference. nullptr: the reference alone judges.
  /// (check_any_hit likewise.)
  const ExactReference* exact = nullptr;
};

enum class Verdict : uint8_t { kAgree, kEdgeTie, kPrecisionTie, kFail, kSkipped };
const char* verdict_name(Verdict v);

/// The verdict for one ray (never kSkipped).
Verdict classify_hit(const fmt::Ray& ray, const fmt::Hit& ref, const fmt::Hit& got, const CompareOptions& options = {});

/// True if a hit's barycentrics are within eps of an edge of its triangle.
bool near_edge(const fmt::Hit& hit, double eps);

/// True if the hit point lies within precision_rel * M of an edge of its triangle in world space (see
/// "precision tie"); false for hits that do not name a triangle of `scene`.
bool near_edge_in_precision(const Scene& scene, const fmt::Ray& ray, const fmt::Hit& hit, double precision_rel);

/// True if both hits name triangles of `scene` and each hit point (ray at its t) lies within
/// precision_rel * M of the other hit's triangle plane (see "precision tie").
bool same_surface_in_precision(const Scene& scene, const fmt::Ray& ray, const fmt::Hit& ref, const fmt::Hit& got,
                               double precision_rel);

/// The eight 32-bit words of a ray (org, tnear, dir, tfar), and back: the form failures print so that
/// a ray can be replayed exactly.
std::array<uint32_t, 8> ray_bits(const fmt::Ray& ray);
fmt::Ray ray_from_bits(const std::array<uint32_t, 8>& bits);

/// One ray kept for the report.
struct RayDiff {
  size_t index = 0;
  Verdict verdict = Verdict::kAgree;
  fmt::Ray ray{};
  fmt::Hit ref{}, got{};
  std::string describe() const;  ///< multi-line: values, hex bits, both hits
};

struct CompareReport {
  uint64_t rays = 0;
  uint64_t skipped = 0;
  uint64_t both_miss = 0;
  uint64_t both_hit = 0;           ///< agreeing hits (t within tolerance)
  uint64_t same_t_other_prim = 0;  ///< of both_hit: different instance or primitive
  uint64_t edge_ties = 0;
  uint64_t precision_ties = 0;
  uint64_t failures = 0;
  uint64_t fail_missed = 0;       ///< failures where the reference hits and the candidate misses
  uint64_t fail_extra = 0;        ///< failures where the reference misses and the candidate hits
  uint64_t fail_t = 0;            ///< failures where both hit at different t
  uint64_t reference_errors = 0;  ///< disagreements the double reference settled for the candidate
  std::vector<RayDiff> first_failures;
  std::vector<RayDiff> first_ties;

  uint64_t agree() const { return both_miss + both_hit; }
  bool ok() const { return failures == 0; }
  void merge(const CompareReport& other, size_t max_examples = 5);
  std::string summary() const;  ///< one line of counts
  std::string details() const;  ///< summary + the kept failures and ties
};

/// Compares got[i] with ref[i] for rays[0..n). skip[i] != 0 (optional) marks rays without a reference.
CompareReport compare_closest(const fmt::Ray* rays, const fmt::Hit* ref, const fmt::Hit* got, size_t n,
                              const CompareOptions& options = {}, const uint8_t* skip = nullptr);

/// Any-hit vs closest-hit consistency of one tracer (or of a candidate's any-hit against a reference's
/// closest hit): occluded[i] must equal (closest[i] is a hit). A ray with occluded = 0 whose closest hit
/// is near an edge is an edge (or precision) tie; every other mismatch is a failure. `ref` in the kept
/// RayDiffs is the closest hit, `got.t` is 0 (occluded) or +inf (not occluded).
/// When checking a candidate's any-hit against a reference's closest hit, pass the candidate's own
/// closest hits as `own_closest`: an occluded ray the reference misses is then a tie exactly when the
/// candidate's closest hit is a tie against the reference's (classify_hit). With options.exact, an
/// inconsistent ray is judged against the double reference's closest hit instead.
struct AnyHitReport {
  uint64_t rays = 0, skipped = 0, consistent = 0, edge_ties = 0, precision_ties = 0, failures = 0;
  uint64_t reference_errors = 0;  ///< inconsistent with `closest` but consistent with the double reference
  std::vector<RayDiff> first_failures;
  bool ok() const { return failures == 0; }
  void merge(const AnyHitReport& other, size_t max_examples = 5);
  std::string summary() const;
  std::string details() const;
};
AnyHitReport check_any_hit(const fmt::Ray* rays, const fmt::Hit* closest, const uint8_t* occluded, size_t n,
                           const CompareOptions& options = {}, const uint8_t* skip = nullptr,
                           const fmt::Hit* own_closest = nullptr);

/// skip mask of the rays Embree cannot take (RayStatus::kUnsupported).
std::vector<uint8_t> unsupported_mask(const fmt::Ray* rays, size_t n);

}  // namespace rtp
