// rtpack-inspect: the occlusion-culling DAGs (formats/dag.h, SPEC §4.5, version 2.0). Statistics of
// the shared pool (bytes, nodes, leaves, resolutions, sharing against each point's DAG built alone,
// set cells) and its invariants, in every mode: the pool chunk exists iff the grids section does iff
// the header says kFlagDag; one grid per batching point; every grid sound (voxel::check_dag: fields,
// every reachable reference in range, no malformed node or leaf), covering its point's bounds and not
// empty for a point with triangles (reader/check_culling.h: what the tracers refuse at open).
#include <bit>
#include <cmath>
#include <map>
#include <unordered_map>
#include <unordered_set>

#include "inspect/inspect.h"
#include "reader/check_culling.h"
#include "layout/dag_query.h"

namespace rtp::inspect_detail {
namespace {

uint32_t grid_levels(uint32_t resolution) {  // levels above the 4^3 leaves: log2(R / 4)
  return uint32_t(std::countr_zero(resolution)) - 2;
}

// Set cells of DAGs that passed check_dag, memoized per (node, level) over the whole pool so shared
// subtrees are counted once: O(distinct nodes reached), never O(R^3). Also collects the union of the
// nodes and leaves reached from every grid.
class CellCounter {
 public:
  explicit CellCounter(const voxel::DagView& v) : v_(v) {}
  uint64_t grid(const fmt::DagGrid& g) {
    if (g.root == fmt::kDagEmpty) return 0;
    if (g.root == fmt::kDagFull) return uint64_t(g.resolution) * g.resolution * g.resolution;
    return count(g.root, grid_levels(g.resolution));
  }
  uint64_t nodes() const { return node_bytes_.size(); }
  uint64_t reached_bytes() const {
    uint64_t b = leaves_.size() * 8;
    for (const auto& [off, bytes] : node_bytes_) b += bytes;
    return b;
  }

 private:
  uint64_t count(uint32_t ref, uint32_t level) {
    if (level == 0) {
      leaves_.insert(ref);
      return uint64_t(std::popcount(v_.leaves[ref]));
    }
    const uint64_t key = uint64_t(ref) << 8 | level;
    if (const auto it = memo_.find(key); it != memo_.end()) return it->second;
    const uint32_t head = v_.words[ref], cm = fmt::dag_child_mask(head), fm = fmt::dag_full_mask(head);
    const uint32_t im = fmt::dag_inline_mask(head);
    node_bytes_.emplace(ref, 4 * uint64_t(fmt::dag_node_words(head)));
    const uint64_t full_child = uint64_t(64) << (3 * (level - 1));  // cells of a level-(L-1) region
    uint64_t sum = 0;
    for (uint32_t c = 0; c < 8; ++c) {
      if (!(cm >> c & 1)) continue;
      const uint32_t* w = v_.words + ref + 1 + fmt::dag_child_slot(head, c);
      sum += (fm >> c & 1)   ? full_child
             : (im >> c & 1) ? uint64_t(std::popcount(w[0] | uint64_t(w[1]) << 32))
                             : count(w[0], level - 1);
    }
    memo_.emplace(key, sum);
    return sum;
  }
  const voxel::DagView& v_;
  std::unordered_map<uint64_t, uint64_t> memo_;
  std::unordered_map<uint32_t, uint64_t> node_bytes_;
  std::unordered_set<uint32_t> leaves_;
};

// SPEC §4.5 presence rules: pool chunk, grids section and header flag all or none; one grid per point.
void check_presence(const PackageReader& r, const Resident& res, Problems& out) {
  const bool flag = (r.header().flags & fmt::kFlagDag) != 0;
  const std::string grids = " the grids section (" + str(uint32_t(fmt::SectionType::kPointGrids)) + ")";
  if (res.dag_present && res.descs_ok && !res.grids_present)
    out.add(res.dag_label + ": a DAG pool, but the batching-point descriptors have no" + grids);
  if (res.grids_present && !res.dag_present)
    out.add(res.descs_label + ":" + grids + " is present but there is no DAG pool chunk");
  const bool has = res.dag_present || res.grids_present;
  if (flag && !has) out.add("header: flag kFlagDag (4) is set, but the package has no DAG pool and no grids section");
  if (!flag && has) out.add("header: the package holds culling DAGs, but flag kFlagDag (4) is not set");
  if (res.grids_ok && res.descs_ok && res.grids.size() != res.descs.size())
    out.add(res.descs_label + ":" + grids + " has " + str(res.grids.size()) + " grids for " + str(res.descs.size()) +
            " batching points");
  if (res.meta_ok && res.meta.contains("dag") && res.meta["dag"] != nlohmann::json(has))
    out.add(res.meta_label + ": \"dag\" is " + res.meta["dag"].dump() + ", but the package " + (has ? "holds" : "has no") +
            " culling DAGs");
}

std::string grid_name(const fmt::DagGrid& g) {
  return "root " +
         (g.root == fmt::kDagEmpty  ? std::string("empty")
          : g.root == fmt::kDagFull ? std::string("full")
                                    : str(g.root)) +
         ", " + str(g.resolution) + "^3";
}

}  // namespace

voxel::DagView dag_view(const PackageReader& r, const Resident& res) {
  voxel::DagView view{res.dag_words.data(), res.dag_words.size(), res.dag_leaves.data(), res.dag_leaves.size()};
  if (res.cull_count) view.cull = res.cull_nodes.data(), view.cull_count = res.cull_count, view.cull_width = r.header().bvh_width;
  return view;
}

nlohmann::json dag_report(const PackageReader& r, const Resident& res, Problems& problems) {
  check_presence(r, res, problems);  // the tracer refuses the same (package_tracer.cpp load_dags)
  const uint64_t pool_bytes = res.dag_ok ? res.dag_words.size() * 4 + res.dag_leaves.size() * 8 : 0;
  nlohmann::json j = {{"present", res.dag_present || res.grids_present},
                      {"pool_bytes", pool_bytes},
                      {"node_words", res.dag_words.size()},
                      {"leaves", res.dag_leaves.size()}};
  const voxel::DagView view = dag_view(r, res);
  CellCounter counter(view);
  std::map<uint32_t, uint64_t> resolutions;
  uint64_t separate = 0, cells = 0, total_cells = 0, sound = 0, malformed = 0, unchecked = 0, empty = 0, full = 0, boxes = 0;
  for (size_t p = 0; p < res.grids.size(); ++p) {
    const fmt::DagGrid& g = res.grids[p];
    // What the tracers refuse at open: a grid that would cull a hit.
    if (const std::string e = p < res.descs.size() ? grid_cover_problem(g, res.descs[p]) : ""; !e.empty())
      problems.add(res.descs_label + ": batching point " + str(p) + ": " + e);
    if (g.resolution == fmt::kDagBoxes) {  // 7.0: the point's instance boxes, no voxels
      ++boxes;
      if (!res.dag_ok) {
        ++unchecked;
        continue;
      }
      const std::string bad = voxel::check_dags(&g, 1, view);
      if (!bad.empty()) {
        ++malformed;
        problems.add(res.dag_label + ": batching point " + str(p) + "'s instance boxes: " + bad.substr(bad.find(": ") + 2));
        continue;
      }
      ++sound;
      continue;
    }
    ++resolutions[g.resolution];
    empty += g.root == fmt::kDagEmpty;
    full += g.root == fmt::kDagFull;
    fmt::DagGrid fields = g;  // the grid's own fields first: problems there name the descriptors chunk
    fields.root = fmt::kDagEmpty;
    std::string bad = voxel::check_dag(fields, view);
    if (!bad.empty()) {
      ++malformed;
      problems.add(res.descs_label + ": batching point " + str(p) + ": grid (" + grid_name(g) + "): " + bad);
      continue;
    }
    const bool needs_pool = g.root != fmt::kDagEmpty && g.root != fmt::kDagFull;
    if (needs_pool && !res.dag_ok) {  // missing or unreadable pool: reported elsewhere
      ++unchecked;
      continue;
    }
    bad = voxel::check_dag(g, view);  // then every reference reachable from its root
    if (!bad.empty()) {
      ++malformed;
      problems.add(res.dag_label + ": batching point " + str(p) + "'s DAG (" + grid_name(g) + "): " + bad);
      continue;
    }
    ++sound;
    separate += voxel::dag_reachable_bytes(g, view);
    cells += counter.grid(g);
    total_cells += uint64_t(g.resolution) * g.resolution * g.resolution;
  }
  if (boxes && res.dag_ok && malformed == 0) {  // each alone was sound: no node may serve two of them
    const std::string e = voxel::check_dags(res.grids.data(), res.grids.size(), view);
    if (!e.empty()) {
      ++malformed;
      problems.add(res.dag_label + ": " + e);
    }
  }
  nlohmann::json hist = nlohmann::json::object();  // {"128": points, ...}, as rtpack-convert --json prints it
  for (const auto& [resolution, points] : resolutions) hist[str(resolution)] = points;
  const uint64_t points = res.grids.size();
  j["grids"] = points;
  j["box_points"] = boxes;
  j["box_node_bytes"] = res.cull_count * fmt::cull_node_bytes(r.header().bvh_width);
  j["grid_bytes"] = points * sizeof(fmt::DagGrid);
  j["resolutions"] = hist;
  j["nodes"] = counter.nodes();
  j["unreachable_bytes"] = sound == points && res.dag_ok
                               ? nlohmann::json(pool_bytes - std::min(pool_bytes, counter.reached_bytes()))
                               : nlohmann::json(nullptr);
  j["separate_bytes"] = separate;
  j["sharing"] = pool_bytes ? double(separate) / double(pool_bytes) : 1.0;
  j["bytes_per_point"] = points ? double(pool_bytes) / double(points) : 0.0;
  j["set_cells"] = cells;
  j["cells"] = total_cells;
  j["empty_roots"] = empty;
  j["full_roots"] = full;
  j["malformed_grids"] = malformed;
  j["unchecked_grids"] = unchecked;
  return j;
}

}  // namespace rtp::inspect_detail
