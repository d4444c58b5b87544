// rtpack-validate: is this package right? Traces test rays of every kind, and a renderer's path workload
// through the ray stream (validate_paths.h), through the package out of core (under a memory budget,
// lib/trace/out_of_core.h) and checks every answer, ray by ray, against an
// independent reference: Embree ROBUST built from the source glTF (--source; prepared with the options
// the package records, TESTING.md verdicts: agree / edge tie / precision tie / failure; where the package
// and Embree disagree, a double reference decides (brute force up to kExactLimit instanced triangles,
// instance by instance above): a ray the package answers as it does is an Embree error, not a failure), or without
// --source the in-core tracer (answers must be byte-identical). Exit 3 when any ray fails.
#include <tbb/global_control.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/progress.h"
#include "core/utf8.h"
#include "oracle/compare.h"
#include "oracle/embree_oracle.h"
#include "oracle/instance_reference.h"
#include "oracle/rays.h"
#include "oracle/reference.h"
#include "package/convert.h"
#include "reader/camera.h"
#include "reader/metadata.h"
#include "trace/out_of_core.h"
#include "trace/tracer.h"
#include "cli_checks.h"
#include "validate_paths.h"
#include "tool_version.h"

namespace {

using rtp::fmt::Hit;
using rtp::fmt::Ray;

// The double reference holds 80 bytes per instanced triangle (160 MB at the limit) and answers only
// the rays on which the package and Embree disagree.
constexpr uint64_t kExactLimit = 2'000'000;

struct KindResult {
  std::string kind;
  rtp::CompareReport closest;
  rtp::AnyHitReport any;
  uint64_t any_differ = 0;  // without --source: occlusion bytes that differ from in core
};

uint64_t mix(uint64_t x) {  // splitmix64: deterministic rays, the same on every machine
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
double unit(uint64_t seed, uint64_t i, int k) {
  return double(mix(seed * 0x100000001B3ull + i * 8 + uint64_t(k)) >> 11) * 0x1.0p-53;
}

// Rays from the package alone (no --source): primary from its camera, random through its bounds, shadow
// rays from the in-core primary hits toward a light above the bounds.
std::vector<Ray> package_rays(const rtp::PackageReader& reader, rtp::Tracer& in_core, const std::string& kind, size_t n,
                              uint64_t seed) {
  const auto& h = reader.header();
  double c[3], r = 0;
  for (int k = 0; k < 3; ++k) c[k] = 0.5 * (double(h.bounds_lo[k]) + double(h.bounds_hi[k]));
  for (int k = 0; k < 3; ++k) r += std::pow(double(h.bounds_hi[k]) - double(h.bounds_lo[k]), 2);
  r = std::max(std::sqrt(r) / 2, 1e-3);
  std::vector<Ray> rays;
  if (kind == "primary" || kind == "shadow") {
    const int w = std::max(1, int(std::ceil(std::sqrt(double(n) * 1.5)))), ht = std::max(1, int((n + size_t(w) - 1) / size_t(w)));
    rays = rtp::camera_rays(reader, w, ht).rays;
    rays.resize(std::min(rays.size(), n));
    if (kind == "primary") return rays;
    std::vector<Hit> hits(rays.size());
    in_core.closest(rays.data(), hits.data(), rays.size(), {});
    const double light[3] = {c[0] + 0.3 * r, c[1] + 1.2 * r, c[2] + 0.2 * r};
    std::vector<Ray> out;
    for (size_t i = 0; i < rays.size(); ++i) {
      if (!(hits[i].t < INFINITY)) continue;
      Ray s{};
      double m = 1;
      for (int k = 0; k < 3; ++k) m = std::max(m, std::fabs(rays[i].org[k] + double(hits[i].t) * rays[i].dir[k]));
      for (int k = 0; k < 3; ++k) {
        const double p = rays[i].org[k] + double(hits[i].t) * rays[i].dir[k] - 1e-5 * m * rays[i].dir[k];
        s.org[k] = float(p);
        s.dir[k] = float(light[k] - p);
      }
      s.tnear = 0;
      s.tfar = 0.999f;
      out.push_back(s);
    }
    return out;
  }
  for (size_t i = 0; i < n; ++i) {  // random: from a sphere of radius 1.5 r to a point inside the bounds
    Ray ray{};
    const double z = 2 * unit(seed, i, 0) - 1, phi = 2 * M_PI * unit(seed, i, 1), s = std::sqrt(1 - z * z);
    const double o[3] = {c[0] + 1.5 * r * s * std::cos(phi), c[1] + 1.5 * r * s * std::sin(phi), c[2] + 1.5 * r * z};
    for (int k = 0; k < 3; ++k) {
      const double t = double(h.bounds_lo[k]) + (double(h.bounds_hi[k]) - double(h.bounds_lo[k])) * unit(seed, i, 2 + k);
      ray.org[k] = float(o[k]);
      ray.dir[k] = float(t - o[k]);
    }
    ray.tnear = 0;
    ray.tfar = INFINITY;
    rays.push_back(ray);
  }
  return rays;
}

// The scene as the converter prepared it: the source through rtpack-convert's own import and
// preparation (a dry run) with the options the package records.
rtp::Scene source_scene(const rtp::PackageReader& reader, const std::string& source, const std::vector<std::string>& allow) {
  std::string label;
  const nlohmann::json meta = rtp::read_metadata(reader, &label);
  const nlohmann::json opt = meta.contains("options") && meta["options"].is_object() ? meta["options"] : nlohmann::json::object();
  rtp::ConvertSettings s;
  s.input = source;
  s.allow_paths = allow;
  s.dry_run = true;
  try {
    s.weld = opt.value("weld", -1.0);
    s.subdivide = opt.value("subdivide", 0);
    s.subdivide_to = opt.value("subdivide_to", 0.0);
    const int64_t scene = opt.value("scene", int64_t(-1));
    if (scene < -1 || scene > int64_t(INT32_MAX))
      throw rtp::Error(rtp::ExitCode::kInputInvalid,
                       label + ": metadata /options/scene: " + std::to_string(scene) + " is not a glTF scene index");
    s.scene = int(scene);
    s.attributes = opt.value("attributes", std::vector<std::string>{});
  } catch (const nlohmann::json::exception& e) {
    throw rtp::Error(rtp::ExitCode::kInputInvalid, label + ": metadata /options: " + e.what());
  }
  rtp::Scene scene;
  try {
    scene = rtp::convert_scene(s).scene;
  } catch (const rtp::Error& e) {
    // The options are the package's, not this command line's: a usage error names options the user never
    // passed ("--subdivide and --subdivide-to exclude each other").
    if (e.code() != rtp::ExitCode::kUsage) throw;
    throw rtp::Error(rtp::ExitCode::kInputInvalid, label + ": metadata /options, the convert options the package records, " +
                                                       "do not apply to --source " + source + ": " + e.what());
  }
  const auto& h = reader.header();
  if (scene.instanced_triangles() != h.instanced_triangles || scene.unique_triangles() != h.unique_triangles)
    throw rtp::Error(rtp::ExitCode::kUsage, "--source " + source + " is not the scene of this package: it has " +
                                                std::to_string(scene.unique_triangles()) + " unique and " +
                                                std::to_string(scene.instanced_triangles()) +
                                                " instanced triangles, the package " + std::to_string(h.unique_triangles) +
                                                " and " + std::to_string(h.instanced_triangles));
  return scene;
}

// The command line, as parsed.
struct Args {
  std::string package, source, budget_text = "25%", kinds_text;
  std::vector<std::string> allow;
  size_t per_kind = 10000;
  uint64_t seed = 1;
  int threads = 0;
  bool json = false, no_cull = false;
  CLI::Option* kinds_opt = nullptr;   // given: an empty --kinds is refused, not the default
  CLI::Option* budget_opt = nullptr;  // not given: the default budget is raised to the package's minimum
};

void add_options(CLI::App& app, Args& a) {
  app.add_option("package", a.package, "the .rtp package")->required();
  app.add_option("--source", a.source,
                 "the glTF the package was converted from: answers are checked against Embree "
                 "(ROBUST) on it; without it, against the in-core tracer (byte for byte)");
  app.add_option("--allow-path", a.allow, "also read the source's external buffers from DIR (as rtpack-convert)");
  app.add_option("--rays", a.per_kind, "rays per kind (default 10000)")->check(CLI::Range(size_t(1), size_t(100000000)));
  a.kinds_opt = app.add_option("--kinds", a.kinds_text,
                               "comma-separated ray kinds (default: all; without --source: primary,random,shadow,path)");
  a.budget_opt = app.add_option("--memory-budget", a.budget_text,
                                "cache budget for batching points and mesh segments: bytes (256MiB, 2GB) or "
                                "a percentage of the package's on-demand bytes (default 25%, raised to the "
                                "package's minimum)");
  app.add_option("--seed", a.seed, "ray seed (default 1)")->check(rtp::tools::unsigned_integer());
  app.add_option("--threads", a.threads, "worker threads (default: all cores)")->check(rtp::tools::positive());
  app.add_flag("--no-cull", a.no_cull, "do not cull with the batching points' DAGs");
  app.add_flag("--json", a.json, "print the table as JSON on stdout");
}

// The ray kinds to check: --kinds, or by default every kind the reference can judge.
std::vector<std::string> ray_kinds(const Args& a, bool embree) {
  if (a.kinds_opt->count() > 0 && a.kinds_text.empty())
    throw rtp::Error(rtp::ExitCode::kUsage,
                     "--kinds: empty; name at least one ray kind, or leave the option out for the default");
  std::vector<std::string> kinds;
  if (a.kinds_text.empty()) {
    if (!embree) return {"primary", "random", "shadow", "path"};
    for (rtp::RayKind k : rtp::kAllRayKinds) kinds.push_back(rtp::ray_kind_name(k));
    kinds.push_back("path");
    return kinds;
  }
  for (size_t i = 0; i <= a.kinds_text.size();) {
    const size_t j = std::min(a.kinds_text.find(',', i), a.kinds_text.size());
    kinds.push_back(a.kinds_text.substr(i, j - i));
    i = j + 1;
  }
  for (const std::string& k : kinds) {
    const bool known =
        k == "path" || (embree ? rtp::parse_ray_kind(k).has_value() : (k == "primary" || k == "random" || k == "shadow"));
    if (!known)
      throw rtp::Error(rtp::ExitCode::kUsage, "--kinds: '" + k + "' is not a ray kind" +
                                                  (embree ? " (primary, random, bounce, shadow, inside, short, path)"
                                                          : " without --source (primary, random, shadow, path)"));
  }
  return kinds;
}

// A scene without triangles converts to a valid, empty package: nothing to validate, and that is no failure.
int report_empty(const Args& a) {
  const char* why = "the package holds no triangles: no ray can hit anything, nothing to validate";
  if (a.json) {
    nlohmann::json j = rtp::tools::json_stamp("rtpack-validate");
    j["package"] = rtp::utf8_display(a.package);
    j["kinds"] = nlohmann::json::array();
    j["failures"] = 0;
    j["ok"] = true;
    j["note"] = why;
    std::cout << j.dump(2) << "\n";
  } else {
    std::printf("%s\n", why);
  }
  return 0;
}

// The references the package's answers are checked against: Embree on the source with a double judge of
// disagreements (--source), or the in-core tracer.
struct References {
  rtp::Scene scene;
  std::unique_ptr<rtp::EmbreeOracle> oracle;
  std::unique_ptr<rtp::ExactReference> exact;
  std::unique_ptr<rtp::Tracer> in_core;
};

References open_references(const rtp::PackageReader& reader, const Args& a) {
  References refs;
  if (a.source.empty()) {
    refs.in_core = rtp::open_tracer(reader);
    return refs;
  }
  refs.scene = source_scene(reader, a.source, a.allow);
  refs.oracle = std::make_unique<rtp::EmbreeOracle>(refs.scene, rtp::OracleQuality::kMedium);
  const uint64_t tris = refs.scene.instanced_triangles();
  // Above kExactLimit the instance-wise judge: nothing flattened, the same answers, slower per ray.
  if (tris <= kExactLimit)
    refs.exact = std::make_unique<rtp::BruteForceReference>(refs.scene, kExactLimit);
  else
    refs.exact = std::make_unique<rtp::InstanceReference>(refs.scene);
  if (!a.json)
    std::fprintf(stderr, "judge of disagreements: %s (%llu instanced triangles)\n",
                 tris <= kExactLimit ? "a double brute-force reference from the glTF's own values"
                                     : "a double reference from the glTF's own values, instance by instance",
                 (unsigned long long)tris);
  return refs;
}

// Without --source: the out-of-core answers must be the in-core tracer's, byte for byte (closest hits,
// then occlusion).
void closest_as_in_core(rtp::Tracer& in_core, const std::vector<Ray>& rays, const std::vector<Hit>& got,
                        const rtp::PackageTraceOptions& opt, KindResult& kr) {
  std::vector<Hit> ref(rays.size());
  in_core.closest(rays.data(), ref.data(), rays.size(), opt);
  kr.closest.rays = rays.size();
  const size_t max_examples = rtp::CompareOptions{}.max_examples;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (std::memcmp(&ref[i], &got[i], sizeof(Hit)) == 0) {
      ++(got[i].t < INFINITY ? kr.closest.both_hit : kr.closest.both_miss);
      continue;
    }
    ++kr.closest.failures;
    if (kr.closest.first_failures.size() < max_examples)
      kr.closest.first_failures.push_back({i, rtp::Verdict::kFail, rays[i], ref[i], got[i]});
  }
}
void any_as_in_core(rtp::Tracer& in_core, const std::vector<Ray>& rays, const std::vector<uint8_t>& occ,
                    const rtp::PackageTraceOptions& opt, KindResult& kr) {
  std::vector<uint8_t> ref_occ(rays.size());
  in_core.any(rays.data(), ref_occ.data(), rays.size(), opt);
  for (size_t i = 0; i < rays.size(); ++i) kr.any_differ += occ[i] != ref_occ[i];
  kr.any.rays = rays.size();
  kr.any.failures = kr.any_differ;
}

// One ray kind: its rays traced out of core (closest and any hit) and every answer checked.
KindResult check_kind(const rtp::PackageReader& reader, rtp::Tracer& ooc, References& refs, const Args& a,
                      const std::string& kind, const rtp::PackageTraceOptions& opt, rtp::OutOfCoreStats& total) {
  std::vector<Ray> rays;
  if (refs.oracle) {
    rtp::RayGenOptions g;
    g.seed = a.seed;
    g.closest = [&](const Ray* r, Hit* h, size_t n) { refs.oracle->closest(r, h, n); };
    rays = rtp::generate_rays(refs.scene, *rtp::parse_ray_kind(kind), a.per_kind, g);
  } else {
    rays = package_rays(reader, *refs.in_core, kind, a.per_kind, a.seed);
  }
  std::vector<Hit> got(rays.size());
  std::vector<uint8_t> occ(rays.size());
  const rtp::TracerStats closest = ooc.closest(rays.data(), got.data(), rays.size(), opt);
  const rtp::TracerStats any = ooc.any(rays.data(), occ.data(), rays.size(), opt);
  rtp::tools::accumulate(total, closest);
  rtp::tools::accumulate(total, any);
  KindResult kr;
  kr.kind = kind;
  if (refs.oracle) {
    std::vector<Hit> ref(rays.size());
    refs.oracle->closest(rays.data(), ref.data(), rays.size());
    rtp::CompareOptions co;
    co.scene = &refs.scene;
    co.exact = refs.exact.get();
    const std::vector<uint8_t> skip = rtp::unsupported_mask(rays.data(), rays.size());
    kr.closest = rtp::compare_closest(rays.data(), ref.data(), got.data(), rays.size(), co, skip.data());
    kr.any = rtp::check_any_hit(rays.data(), ref.data(), occ.data(), rays.size(), co, skip.data(), got.data());
  } else {
    closest_as_in_core(*refs.in_core, rays, got, opt, kr);
    any_as_in_core(*refs.in_core, rays, occ, opt, kr);
  }
  if (!a.json)
    std::fprintf(stderr, "  %-8s %zu rays traced out of core (%llu chunks loaded)\n", kind.c_str(), rays.size(),
                 (unsigned long long)closest.cache.loads + any.cache.loads);
  return kr;
}

// The path workload (validate_paths.h): its rays as the stream answered them, judged as above.
KindResult check_paths(const rtp::PackageReader& reader, rtp::OutOfCoreTracer& ooc, References& refs, const Args& a,
                       const rtp::PackageTraceOptions& opt, rtp::OutOfCoreStats& total) {
  rtp::tools::PathWorkloadOptions po;
  po.paths = a.per_kind, po.seed = a.seed, po.trace = opt;
  const rtp::tools::PathWorkload w = rtp::tools::trace_path_workload(reader, ooc, po);
  rtp::tools::accumulate(total, w.stats);
  KindResult kr;
  kr.kind = "path";
  if (refs.oracle) {
    rtp::CompareOptions co;
    co.scene = &refs.scene;
    co.exact = refs.exact.get();
    std::vector<Hit> ref(w.closest_rays.size());
    refs.oracle->closest(w.closest_rays.data(), ref.data(), ref.size());
    std::vector<uint8_t> skip = rtp::unsupported_mask(w.closest_rays.data(), w.closest_rays.size());
    kr.closest = rtp::compare_closest(w.closest_rays.data(), ref.data(), w.closest_hits.data(), ref.size(), co, skip.data());
    ref.resize(w.shadow_rays.size());
    refs.oracle->closest(w.shadow_rays.data(), ref.data(), ref.size());
    skip = rtp::unsupported_mask(w.shadow_rays.data(), w.shadow_rays.size());
    kr.any = rtp::check_any_hit(w.shadow_rays.data(), ref.data(), w.occluded.data(), ref.size(), co, skip.data());
  } else {
    closest_as_in_core(*refs.in_core, w.closest_rays, w.closest_hits, opt, kr);
    any_as_in_core(*refs.in_core, w.shadow_rays, w.occluded, opt, kr);
  }
  if (!a.json)
    std::fprintf(stderr,
                 "  %-8s %zu paths in %u waves: %zu closest and %zu shadow rays through the ray stream (%llu chunks loaded)\n",
                 "path", w.paths, w.waves, w.closest_rays.size(), w.shadow_rays.size(), (unsigned long long)w.stats.cache.loads);
  return kr;
}

// The budget the out-of-core tracer ran under, and the package's figures it was chosen from.
struct Budget {
  uint64_t budget = 0, minimum = 0, on_demand = 0;
};

nlohmann::json report_json(const Args& a, const std::vector<KindResult>& results, const rtp::OutOfCoreStats& total,
                           const Budget& b, uint64_t failures) {
  nlohmann::json jk = nlohmann::json::array();
  for (const KindResult& k : results) {
    nlohmann::json ex = nlohmann::json::array();
    for (const rtp::RayDiff& d : k.closest.first_failures) ex.push_back({{"ray", d.index}, {"what", d.describe()}});
    jk.push_back({{"kind", k.kind},
                  {"rays", k.closest.rays},
                  {"skipped", k.closest.skipped},
                  {"agree", k.closest.agree()},
                  {"edge_ties", k.closest.edge_ties},
                  {"precision_ties", k.closest.precision_ties},
                  {"reference_errors", k.closest.reference_errors},
                  {"failures", k.closest.failures},
                  {"any_hit_failures", k.any.failures},
                  {"first_failures", ex}});
  }
  nlohmann::json j = rtp::tools::json_stamp("rtpack-validate");
  j["package"] = rtp::utf8_display(a.package);
  j["reference"] = a.source.empty() ? "in_core" : "embree";
  j["kinds"] = jk;
  j["out_of_core"] = {{"memory_budget", b.budget},
                      {"minimum_budget", b.minimum},
                      {"on_demand_bytes", b.on_demand},
                      {"rounds", total.rounds},
                      {"chunks_loaded", total.cache.loads},
                      {"bytes_read", total.cache.bytes_read},
                      {"cache_hit_rate", total.cache.hit_rate()},
                      {"batching_point_visits", total.point_visits},
                      {"culled_visits", total.culled_visits},
                      {"peak_cache_bytes", total.cache.peak_resident_bytes},
                      {"peak_resident_bytes", total.peak_resident_bytes},
                      {"peak_rss_bytes", uint64_t(rtp::peak_rss_mib() * 1048576.0)},
                      {"seconds", total.total_seconds}};
  j["failures"] = failures;
  j["ok"] = failures == 0;
  return j;
}

void print_table(const std::vector<KindResult>& results, const rtp::OutOfCoreStats& total, const Budget& b, uint64_t failures) {
  std::printf("%-8s %9s %9s %9s %10s %13s %9s %9s\n", "kind", "rays", "agree", "edge ties", "prec. ties", "Embree errors",
              "failures", "any-hit");
  for (const KindResult& k : results)
    std::printf("%-8s %9llu %9llu %9llu %10llu %13llu %9llu %9llu\n", k.kind.c_str(), (unsigned long long)k.closest.rays,
                (unsigned long long)k.closest.agree(), (unsigned long long)k.closest.edge_ties,
                (unsigned long long)k.closest.precision_ties, (unsigned long long)k.closest.reference_errors,
                (unsigned long long)k.closest.failures, (unsigned long long)k.any.failures);
  std::printf(
      "out of core: budget %.1f MiB (minimum %.1f, on demand %.1f), %llu chunks loaded, %.1f MiB read, cache hit "
      "rate %.1f%%, peak cache %.1f MiB, peak resident %.1f MiB, peak RSS %.1f MiB\n",
      double(b.budget) / 1048576.0, double(b.minimum) / 1048576.0, double(b.on_demand) / 1048576.0,
      (unsigned long long)total.cache.loads, double(total.cache.bytes_read) / 1048576.0, 100 * total.cache.hit_rate(),
      double(total.cache.peak_resident_bytes) / 1048576.0, double(total.peak_resident_bytes) / 1048576.0, rtp::peak_rss_mib());
  for (const KindResult& k : results)
    for (const rtp::RayDiff& d : k.closest.first_failures)
      std::printf("FAIL %s ray %zu:\n%s\n", k.kind.c_str(), d.index, d.describe().c_str());
  std::printf("%s\n", failures ? "FAILED: some answers are wrong" : "ok: every answer agrees with the reference");
}

int validate(const Args& a) {
  const rtp::PackageReader reader(a.package);
  const std::vector<std::string> kinds = ray_kinds(a, !a.source.empty());
  if (reader.header().unique_triangles == 0) return report_empty(a);
  Budget b;
  b.on_demand = rtp::on_demand_bytes(reader);
  b.minimum = rtp::minimum_budget(reader);
  b.budget = rtp::parse_memory_budget(a.budget_text, b.on_demand);
  if (a.budget_opt->count() == 0) b.budget = std::max(b.budget, b.minimum);  // the default never refuses
  const std::unique_ptr<rtp::OutOfCoreTracer> ooc = rtp::open_out_of_core(reader, b.budget);
  if (!a.json)
    std::fprintf(stderr, "reference: %s\n", a.source.empty() ? "the in-core tracer" : "Embree ROBUST on the source glTF");
  References refs = open_references(reader, a);
  rtp::PackageTraceOptions opt;
  opt.isa = rtp::detect_isa();
  opt.cull = !a.no_cull;
  std::vector<KindResult> results;
  results.reserve(kinds.size());
  rtp::OutOfCoreStats total;
  for (const std::string& kind : kinds)
    results.push_back(kind == "path" ? check_paths(reader, *ooc, refs, a, opt, total)
                                     : check_kind(reader, *ooc, refs, a, kind, opt, total));
  uint64_t failures = 0;
  for (const KindResult& k : results) failures += k.closest.failures + k.any.failures;
  if (a.json)
    std::cout << report_json(a, results, total, b, failures).dump(2) << "\n";
  else
    print_table(results, total, b, failures);
  if (failures)
    return rtp::tools::report_error("rtpack-validate", false, a.package, rtp::ExitCode::kInputInvalid,
                                    std::to_string(failures) + " rays answered wrongly (rays named above)");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rtpack-validate: trace test rays through a package out of core and check every answer"};
  rtp::tools::add_version_flag(app, "rtpack-validate");
  Args a;
  add_options(app, a);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return rtp::tools::parse_error_exit(app, e, "rtpack-validate", argc, argv);
  }
  std::unique_ptr<tbb::global_control> limit;
  if (a.threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, a.threads);
  return rtp::tools::run_reporting_errors("rtpack-validate", a.json, a.package, [&] { return validate(a); });
}
