// rtpack-inspect: what is in a .rtp package (sizes per chunk kind, batching points, mesh segments,
// culling DAGs, per-chunk BVH statistics, metadata) and, with --verify, whether every invariant of the
// format holds.
// Exit: 0 fine, 3 a chunk is corrupt or an invariant fails (or the header/TOC is malformed), 2 unreadable.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <string>
#include <utility>
#include <vector>

#include "core/error.h"
#include "core/utf8.h"
#include "core/progress.h"
#include "inspect/inspect.h"
#include "package/writer.h"
#include "reader/reader.h"
#include "tool_version.h"

namespace {

using nlohmann::json;

std::string group(uint64_t v) {  // 12345678 -> 12,345,678
  const std::string s = std::to_string(v);
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (i && (s.size() - i) % 3 == 0) out.push_back(',');
    out.push_back(s[i]);
  }
  return out;
}

std::string human(double bytes) { return rtp::human_bytes(bytes); }

std::string num(const json& v, const char* f = "%.3f") {
  if (!v.is_number()) return "-";
  char b[48];
  std::snprintf(b, sizeof b, f, v.get<double>());
  return b;
}

uint64_t u64(const json& v) { return v.is_number() ? v.get<uint64_t>() : 0; }

// "min / mean / max" of a Spread, as counts or bytes.
std::string spread(const json& s, bool bytes = false) {
  if (!s["min"].is_number()) return "-";
  auto f = [bytes](const json& v) { return bytes ? human(v.get<double>()) : num(v, "%.1f"); };
  return f(s["min"]) + " / " + f(s["mean"]) + " / " + f(s["max"]);
}

void histogram(const char* title, const json& h, bool bytes) {
  if (h.empty()) return;
  std::printf("  %s\n", title);
  uint64_t most = 1;
  for (const auto& b : h) most = std::max(most, u64(b["count"]));
  for (const auto& b : h) {
    const std::string lo = bytes ? human(double(u64(b["min"]))) : group(u64(b["min"]));
    const std::string hi = b["max"].is_null() ? "inf" : (bytes ? human(double(u64(b["max"]))) : group(u64(b["max"])));
    const uint64_t n = u64(b["count"]);
    std::printf("    [%10s, %10s)  %8s  %s\n", lo.c_str(), hi.c_str(), group(n).c_str(),
                std::string(size_t((n * 40 + most - 1) / most), '#').c_str());
  }
}

// The culling-DAG block: pool size, resolutions, sharing, set cells (or one line without DAGs).
void print_dag(const json& d) {
  if (!d.value("present", false)) {
    std::printf("\nculling DAGs    none (converted with --no-dag)\n");
    return;
  }
  const uint64_t pool = u64(d["pool_bytes"]), points = u64(d["grids"]);
  std::printf("\nculling DAGs    pool %s (%s bytes): %s nodes in %s words, %s leaves; %s per batching point\n",
              human(double(pool)).c_str(), group(pool).c_str(), group(u64(d["nodes"])).c_str(),
              group(u64(d["node_words"])).c_str(), group(u64(d["leaves"])).c_str(),
              human(points ? double(pool) / double(points) : 0.0).c_str());
  std::vector<std::pair<uint64_t, uint64_t>> by_res;  // {"128": points, ...} -> finest first
  for (const auto& [r, n] : d["resolutions"].items()) by_res.emplace_back(std::stoull(r), u64(n));
  std::sort(by_res.rbegin(), by_res.rend());
  std::string res;
  for (const auto& [r, n] : by_res) res += (res.empty() ? "" : ", ") + group(n) + " at " + std::to_string(r) + "^3";
  std::printf("  resolutions   %s (%s grid%s, %s in the descriptors chunk)\n", res.empty() ? "-" : res.c_str(),
              group(points).c_str(), points == 1 ? "" : "s", human(double(u64(d["grid_bytes"]))).c_str());
  if (const uint64_t boxes = d.value("box_points", uint64_t(0)))
    std::printf("  instance boxes %s point%s culled by their instance BVH with 8-bit boxes (%s of nodes)\n", group(boxes).c_str(),
                boxes == 1 ? "" : "s", human(double(d.value("box_node_bytes", uint64_t(0)))).c_str());
  const uint64_t sep = u64(d["separate_bytes"]);
  std::printf("  sharing       %s built alone per point -> %s shared pool: %sx", human(double(sep)).c_str(),
              human(double(pool)).c_str(), num(d["sharing"], "%.2f").c_str());
  if (sep) std::printf(" (%.1f%% saved)", 100.0 * (1.0 - double(pool) / double(sep)));
  std::printf("\n");
  const uint64_t cells = u64(d["cells"]), set = u64(d["set_cells"]);
  std::printf("  set cells     %s of %s (%.2f%%); %s empty, %s full roots\n", group(set).c_str(), group(cells).c_str(),
              cells ? 100.0 * double(set) / double(cells) : 0.0, group(u64(d["empty_roots"])).c_str(),
              group(u64(d["full_roots"])).c_str());
  if (u64(d["malformed_grids"]) || u64(d["unchecked_grids"]))
    std::printf("  not counted   %s malformed grids, %s without a readable pool\n", group(u64(d["malformed_grids"])).c_str(),
                group(u64(d["unchecked_grids"])).c_str());
  if (d["unreachable_bytes"].is_number() && u64(d["unreachable_bytes"]))
    std::printf("  unreachable   %s of the pool are reached from no grid\n", human(double(u64(d["unreachable_bytes"]))).c_str());
}

void print_text(const std::string& path, const json& j) {
  const json& h = j["header"];
  std::printf("package         %s\n", path.c_str());
  std::printf("  file          %s bytes (%s), %s chunks\n", group(u64(j["package_bytes"])).c_str(),
              human(double(u64(j["package_bytes"]))).c_str(), group(u64(h["toc_entries"])).c_str());
  std::printf("  version       %s; W = %llu (BVH width), B = %llu (leaf block)\n", h["version"].get<std::string>().c_str(),
              (unsigned long long)u64(h["bvh_width"]), (unsigned long long)u64(h["leaf_width"]));
  std::string attrs;
  for (const auto& a : h["attributes"]) attrs += (attrs.empty() ? "" : ", ") + a.get<std::string>();
  std::printf("  attributes    %s\n",
              attrs.empty() ? "none (positions and ids only)" : (attrs + " (separate per-chunk streams)").c_str());
  std::printf("  triangles     %s unique, %s instanced; %s meshes, %s instances\n", group(u64(h["unique_triangles"])).c_str(),
              group(u64(h["instanced_triangles"])).c_str(), group(u64(j["meshes"])).c_str(), group(u64(j["instances"])).c_str());
  const json& b = h["bounds"];
  std::printf("  bounds        min (%s, %s, %s)  max (%s, %s, %s)\n", num(b["min"][0], "%g").c_str(),
              num(b["min"][1], "%g").c_str(), num(b["min"][2], "%g").c_str(), num(b["max"][0], "%g").c_str(),
              num(b["max"][1], "%g").c_str(), num(b["max"][2], "%g").c_str());
  const json& m = j["metadata"];
  if (m.is_object()) {
    auto s = [&m](const char* k) { return m.contains(k) ? (m[k].is_string() ? m[k].get<std::string>() : m[k].dump()) : "-"; };
    std::printf("  source        %s (%s)\n", s("source").c_str(), s("tool_version").c_str());
    std::printf("  build         %s BVH, chunk target %s triangles (counting %s)\n", s("bvh_build").c_str(),
                s("chunk_target").c_str(), s("chunk_by").c_str());
    if (m.contains("options")) std::printf("  options       %s\n", m["options"].dump().c_str());
    std::printf("  cameras       %zu\n", m["cameras"].size());
    for (const auto& c : m["cameras"]) {
      std::string pos = c.contains("position") ? " at (" + num(c["position"][0], "%g") + ", " + num(c["position"][1], "%g") +
                                                     ", " + num(c["position"][2], "%g") + ")"
                                               : "";
      std::string lens =
          c.contains("yfov") ? ", yfov " + num(c["yfov"], "%.4g") : (c.contains("ymag") ? ", ymag " + num(c["ymag"], "%g") : "");
      std::printf("    %-24s %s%s%s\n", c["name"].get<std::string>().c_str(), c["type"].get<std::string>().c_str(), lens.c_str(),
                  pos.c_str());
    }
  }

  std::printf(
      "\nchunk sizes (B/tri: bytes per unique triangle)      chunks          raw       stored   ratio   raw B/tri  stored "
      "B/tri\n");
  auto size_row = [](const std::string& name, const json& r) {
    std::printf("  %-46s %6s %12s %12s %7.2f %11.2f %13.2f\n", name.c_str(), group(u64(r["chunks"])).c_str(),
                human(double(u64(r["raw_bytes"]))).c_str(), human(double(u64(r["stored_bytes"]))).c_str(),
                r["ratio"].get<double>(), r["raw_bytes_per_unique_triangle"].get<double>(),
                r["stored_bytes_per_unique_triangle"].get<double>());
  };
  for (const auto& k : j["sizes"]["by_kind"])
    size_row(k["name"].get<std::string>() + " (" + k["residency"].get<std::string>() + ")", k);
  size_row("all resident", j["sizes"]["resident"]);
  size_row("all on demand", j["sizes"]["on_demand"]);
  const json& z = j["sizes"];
  std::printf("  header block %s, table of contents %s, alignment padding %s\n",
              human(double(u64(z["header_block_bytes"]))).c_str(), human(double(u64(z["toc_bytes"]))).c_str(),
              human(double(u64(z["alignment_padding_bytes"]))).c_str());
  std::printf("  whole file: %.2f bytes per unique triangle\n", j["bytes_per_unique_triangle"].get<double>());

  const json& p = j["batching_points"];
  std::printf("\nbatching points %s (%s pieces, %s instances; %s unique + %s instanced triangles)\n",
              group(u64(p["count"])).c_str(), group(u64(p["pieces"])).c_str(), group(u64(p["instances"])).c_str(),
              group(u64(p["unique_triangles"])).c_str(), group(u64(p["instanced_triangles"])).c_str());
  std::printf("  triangles per point    %s   (min / mean / max)\n", spread(p["triangles"]).c_str());
  std::printf("  stored bytes           %s\n", spread(p["stored_bytes"], true).c_str());
  std::printf("  pieces per point       %s\n", spread(p["pieces_per_point"]).c_str());
  std::printf("  instances per point    %s\n", spread(p["instances_per_point"]).c_str());
  histogram("triangles (unique + instanced) per point", p["triangles_histogram"], false);
  histogram("stored bytes per point", p["stored_bytes_histogram"], true);
  histogram("instances per point", p["instances_histogram"], false);

  const json& s = j["mesh_segments"];
  std::printf("\nmesh segments   %s (%s triangles of instanced meshes)\n", group(u64(s["count"])).c_str(),
              group(u64(s["triangles"])).c_str());
  if (u64(s["count"])) {
    std::printf("  meshes per segment     %s   (min / mean / max)\n", spread(s["meshes_per_segment"]).c_str());
    std::printf("  triangles per segment  %s\n", spread(s["triangles_per_segment"]).c_str());
    std::printf("  stored bytes           %s\n", spread(s["stored_bytes"], true).c_str());
    std::printf("  raw bytes              %s\n", spread(s["raw_bytes"], true).c_str());
  }

  print_dag(j["dag"]);

  std::printf("\nBVH statistics (Benthin 2008 §4 cost model, reader side; min / mean / max over the BVHs)\n");
  for (const auto& [name, g] : j["bvh"].items()) {
    if (u64(g["bvhs"]) == 0) continue;
    std::printf("  %s: %s BVHs (%s leaf-only), %s primitives, %s nodes, %s blocks\n", name.c_str(), group(u64(g["bvhs"])).c_str(),
                group(u64(g["root_leaves"])).c_str(), group(u64(g["primitives"])).c_str(), group(u64(g["nodes"])).c_str(),
                group(u64(g["blocks"])).c_str());
    for (const char* k : {"c_box", "c_tri", "sah", "branching", "leaf_fill", "max_depth"})
      std::printf("    %-12s %10s %10s %10s\n", k, num(g[k]["min"]).c_str(), num(g[k]["mean"]).c_str(), num(g[k]["max"]).c_str());
  }
  std::printf("  top level: %s nodes, %s levels\n", group(u64(j["top_level"]["nodes"])).c_str(),
              group(u64(j["top_level"]["max_depth"])).c_str());

  if (j.contains("chunks")) {
    std::printf(
        "\nchunks (triangles: unique + instanced; BVH columns: mean over the chunk's mesh/piece BVHs, depth: max;\n"
        "        inst cb / inst ct: c_box / c_tri of a batching point's instance BVH)\n");
    std::printf("  %5s %-26s %6s %10s %10s %10s %6s %10s %6s %6s %7s %7s %6s %5s %5s %7s %7s\n", "#", "kind", "id", "offset",
                "stored", "raw", "ratio", "triangles", "BVHs", "inst", "c_box", "c_tri", "branch", "fill", "depth", "inst cb",
                "inst ct");
    for (const auto& c : j["chunks"]) {
      const bool has_bvh = c.contains("bvh");
      const json g = has_bvh ? c["bvh"] : json::object();
      const uint64_t tris = u64(c.value("triangles", json(0))) + u64(c.value("unique_triangles", json(0))) +
                            u64(c.value("instanced_triangles", json(0)));
      auto mean = [&](const char* k) { return has_bvh ? num(g[k]["mean"], "%.2f") : std::string(); };
      auto count = [&](bool has, uint64_t v) { return has ? group(v) : std::string(); };
      const json ib = c.value("instance_bvh", json::object());
      char line[512];
      std::snprintf(line, sizeof line, "  %5s %-26s %6s %10s %10s %10s %6.2f %10s %6s %6s %7s %7s %6s %5s %5s %7s %7s",
                    group(u64(c["index"])).c_str(), c["kind"].get<std::string>().c_str(), group(u64(c["id"])).c_str(),
                    group(u64(c["offset"])).c_str(), human(double(u64(c["stored_bytes"]))).c_str(),
                    human(double(u64(c["raw_bytes"]))).c_str(), c["ratio"].get<double>(), count(has_bvh, tris).c_str(),
                    count(has_bvh, has_bvh ? u64(g["bvhs"]) : 0).c_str(),
                    count(c.contains("instances"), u64(c.value("instances", json(0)))).c_str(), mean("c_box").c_str(),
                    mean("c_tri").c_str(), mean("branching").c_str(), mean("leaf_fill").c_str(),
                    has_bvh ? num(g["max_depth"]["max"], "%.0f").c_str() : "",
                    ib.contains("c_box") ? num(ib["c_box"], "%.2f").c_str() : "",
                    ib.contains("c_tri") ? num(ib["c_tri"], "%.2f").c_str() : "");
      std::string row = line;
      row.erase(row.find_last_not_of(' ') + 1);
      std::printf("%s\n", row.c_str());
    }
  }
}

void print_problems(const json& j, size_t shown) {
  const uint64_t n = u64(j["problems"]["count"]);
  if (n == 0) {
    if (j["verified"].get<bool>()) std::printf("\nverify: OK (checksums, decompression and every invariant)\n");
    return;
  }
  std::printf("\n%s: %s problem%s\n", j["verified"].get<bool>() ? "verify: FAILED" : "problems", group(n).c_str(),
              n == 1 ? "" : "s");
  for (const auto& msg : j["problems"]["listed"]) std::printf("  %s\n", msg.get<std::string>().c_str());
  if (n > shown) std::printf("  ... and %s more\n", group(n - shown).c_str());
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rtpack-inspect: sizes, batching points, BVH statistics and (--verify) invariants of a .rtp package"};
  rtp::tools::add_version_flag(app, "rtpack-inspect");
  std::string input;
  bool chunks = false, json_out = false, verify = false;
  app.add_option("package", input, "the .rtp package")->required();
  app.add_flag("--chunks", chunks, "one row per chunk (sizes and BVH statistics)");
  app.add_flag("--json", json_out, "print the report as one JSON object on stdout");
  app.add_flag("--verify", verify, "check every checksum, frame and invariant; exit 3 if any fails");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return rtp::tools::parse_error_exit(app, e, "rtpack-inspect", argc, argv);
  }
  return rtp::tools::run_reporting_errors("rtpack-inspect", json_out, input, [&]() -> int {
    const rtp::PackageReader reader(input);
    rtp::InspectOptions opt;
    opt.chunks = chunks;
    opt.verify = verify;
    const rtp::InspectResult r = rtp::inspect_package(reader, opt);
    nlohmann::json j = r.report;
    j["file"] = rtp::utf8_display(input);  // any bytes in the name: valid JSON
    j.update(rtp::tools::json_stamp("rtpack-inspect"));
    const std::string failed = std::to_string(r.problems) + (verify ? " failed checks" : " unreadable or malformed chunks");
    // Problems under --json: the report with its `problems` list, and the `error` object every tool's
    // failure carries (docs/json.md), so a caller tests one key whatever the tool.
    if (r.problems && json_out) {
      const std::string first = r.listed.empty() ? std::string() : ": first: " + r.listed.front();
      j["error"] = rtp::tools::error_json("rtpack-inspect", input, rtp::ExitCode::kInputInvalid, failed + first)["error"];
    }
    if (json_out) {
      std::cout << j.dump(2) << "\n";
    } else {
      print_text(input, j);
      print_problems(j, r.listed.size());
    }
    std::fflush(stdout);
    if (r.problems) {
      std::cerr << "error: " << input << ": " << failed << "\n";
      return int(rtp::ExitCode::kInputInvalid);
    }
    return 0;
  });
}
