// rtpack-bench's default mode: records, table rows and JSON (bench_records.h).
#include "bench_records.h"

#include <algorithm>
#include <cinttypes>

#include "core/utf8.h"

namespace rtp::bench {

void print_row(FILE* o, const Record& r) {
  const bool any = r.kind == RayKind::kShadow;
  const std::string order = r.packet ? "packet-" + std::to_string(r.packet) : order_name(r.order);
  std::fprintf(o,
               "%-8s %-7s %3d %-12s %3d %14.2f %14.2f %-8s %7.2f %8.1f  %" PRIu64 " / %" PRIu64 " / %" PRIu64 " / %" PRIu64
               " / %" PRIu64 " / %" PRIu64 "\n",
               ray_kind_name(r.kind), any ? "any" : "closest", r.width, order.c_str(), r.threads, r.rtpack_mrays, r.embree_mrays,
               r.embree_path, r.rtpack_mrays / r.embree_mrays, r.bytes_per_triangle, r.agreement.agree, r.agreement.edge_ties,
               r.agreement.precision_ties, r.agreement.failures, r.agreement.skipped, r.agreement.embree_errors);
  std::fflush(o);
}

nlohmann::json trace_record_json(const Record& r, const KindData& k, const std::string& scene_path, Isa isa,
                                 const std::string& cpu, size_t hot_rays) {
  return {{"type", "trace"},
          {"scene", utf8_display(scene_path)},
          {"kind", ray_kind_name(r.kind)},
          {"query", k.any ? "any" : "closest"},
          {"width", r.width},
          {"block", r.width},
          {"order", order_name(r.order)},
          {"packet", r.packet},
          {"isa", isa_name(isa)},
          {"threads", r.threads},
          {"rays", k.rays.size()},
          {"hot_rays", hot_rays},
          {"distinct_rays", k.distinct_rays},
          {"rtpack_mrays", r.rtpack_mrays},
          {"embree_mrays", r.embree_mrays},
          {"embree_path", r.embree_path},
          {"embree_stream_mrays", r.embree_stream_mrays > 0 ? nlohmann::json(r.embree_stream_mrays) : nlohmann::json()},
          {"embree_single_mrays", r.embree_single_mrays > 0 ? nlohmann::json(r.embree_single_mrays) : nlohmann::json()},
          {"ratio", r.rtpack_mrays / r.embree_mrays},
          {"bytes_per_triangle", r.bytes_per_triangle},
          {"agree", r.agreement.agree},
          {"edge_ties", r.agreement.edge_ties},
          {"precision_ties", r.agreement.precision_ties},
          {"failures", r.agreement.failures},
          {"skipped", r.agreement.skipped},
          {"embree_errors", r.agreement.embree_errors},
          {"embree_timed_failures", k.embree_timed_failures},
          {"cpu", cpu}};
}

nlohmann::json build_record_json(const BuildRecord& b, const std::string& scene_path, const std::string& cpu) {
  return {{"type", "build"},
          {"scene", utf8_display(scene_path)},
          {"width", b.width},
          {"block", b.width},
          {"threads", b.threads},
          {"rtpack_build_s", b.rtpack_seconds},
          {"embree_high_build_s", b.embree_seconds},
          {"ratio", b.embree_seconds / b.rtpack_seconds},
          {"bvh_bytes", b.bvh_bytes},
          {"bytes_per_triangle", b.bytes_per_triangle},
          {"cpu", cpu}};
}

nlohmann::json sah_record_json(const BvhStatsRow& r, const std::string& scene_path) {
  return {{"type", "sah"},
          {"scene", utf8_display(scene_path)},
          {"model", r.model},
          {"width", r.width},
          {"block", r.block},
          {"method", method_name(r.method)},
          {"c_box", r.stats.c_box},
          {"c_tri", r.stats.c_tri},
          {"sah", r.stats.sah},
          {"branching", r.stats.branching},
          {"leaf_fill", r.stats.leaf_fill},
          {"max_depth", r.stats.max_depth},
          {"triangles", r.stats.primitives},
          {"nodes", r.stats.nodes},
          {"leaves", r.stats.leaves},
          {"bytes_per_triangle",
           double(r.stats.node_bytes + r.stats.block_bytes) / double(std::max<uint64_t>(1, r.stats.primitives))},
          {"build_s", r.build_seconds}};
}

}  // namespace rtp::bench
