// Scene summaries: what a user needs to know before converting (counts, bounds with instancing,
// cameras, warnings).
#include "scene/summary.h"

#include <cstdio>

#include "core/utf8.h"

namespace rtp {
namespace {

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

std::string group(uint64_t v) {  // 12345678 -> 12,345,678
  std::string s = std::to_string(v), out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (i && (s.size() - i) % 3 == 0) out.push_back(',');
    out.push_back(s[i]);
  }
  return out;
}

}  // namespace

nlohmann::json scene_summary_json(const Scene& s) {
  using nlohmann::json;
  std::vector<uint64_t> per_mesh(s.meshes.size(), 0);
  uint64_t mirrored = 0;
  for (const Instance& i : s.instances) {
    ++per_mesh[i.mesh];
    mirrored += i.mirrored;
  }
  json meshes = json::array();
  for (size_t m = 0; m < s.meshes.size(); ++m) {
    const Mesh& mesh = s.meshes[m];
    meshes.push_back({{"name", mesh.name},
                      {"gltf_mesh", mesh.primitives.empty() ? -1 : int64_t(mesh.primitives[0].gltf_mesh)},
                      {"triangles", mesh.triangle_count()},
                      {"vertices", mesh.positions.size()},
                      {"primitives", mesh.primitives.size()},
                      {"instances", per_mesh[m]}});
  }
  json cams = json::array();
  for (const Camera& c : s.cameras) {
    json j = {{"name", c.name},
              {"node", c.node},
              {"type", c.type == Camera::Type::kPerspective ? "perspective" : "orthographic"},
              {"position", {c.world(0, 3), c.world(1, 3), c.world(2, 3)}},
              {"forward", {-c.world(0, 2), -c.world(1, 2), -c.world(2, 2)}},
              {"znear", c.znear},
              {"zfar", c.zfar}};
    if (c.type == Camera::Type::kPerspective) {
      j["yfov"] = c.yfov;
      j["aspect_ratio"] = c.aspect_ratio;
    } else {
      j["xmag"] = c.xmag;
      j["ymag"] = c.ymag;
    }
    cams.push_back(j);
  }
  json bounds = nullptr;
  if (!s.bounds.empty())
    bounds = {{"min", {s.bounds.lo.x, s.bounds.lo.y, s.bounds.lo.z}}, {"max", {s.bounds.hi.x, s.bounds.hi.y, s.bounds.hi.z}}};
  return {{"source", utf8_display(s.source_path)},
          {"scene", s.gltf_scene},
          {"meshes", s.meshes.size()},
          {"instances", s.instances.size()},
          {"mirrored_instances", mirrored},
          {"unique_triangles", s.unique_triangles()},
          {"instanced_triangles", s.instanced_triangles()},
          {"bounds", bounds},
          {"cameras", cams},
          {"mesh_table", meshes},
          {"warnings", s.warnings}};
}

std::string scene_summary_text(const Scene& s) {
  const nlohmann::json j = scene_summary_json(s);
  std::string o;
  o +=
      "source               " + s.source_path + (s.gltf_scene >= 0 ? " (scene " + std::to_string(s.gltf_scene) + ")" : "") + "\n";
  o += "meshes               " + group(s.meshes.size()) + "\n";
  o += "instances            " + group(s.instances.size()) + " (" + group(j["mirrored_instances"].get<uint64_t>()) +
       " mirrored)\n";
  o += "unique triangles     " + group(s.unique_triangles()) + "\n";
  o += "instanced triangles  " + group(s.instanced_triangles()) + "\n";
  if (s.bounds.empty()) {
    o += "bounds               (empty scene)\n";
  } else {
    o += "bounds min           " + fmt("%.7g", s.bounds.lo.x) + " " + fmt("%.7g", s.bounds.lo.y) + " " +
         fmt("%.7g", s.bounds.lo.z) + "\n";
    o += "bounds max           " + fmt("%.7g", s.bounds.hi.x) + " " + fmt("%.7g", s.bounds.hi.y) + " " +
         fmt("%.7g", s.bounds.hi.z) + "\n";
  }
  o += "cameras              " + std::to_string(s.cameras.size()) + "\n";
  for (const auto& c : j["cameras"])
    o += "  " + c["name"].get<std::string>() + " (" + c["type"].get<std::string>() + ") at " +
         fmt("%.6g", c["position"][0].get<double>()) + " " + fmt("%.6g", c["position"][1].get<double>()) + " " +
         fmt("%.6g", c["position"][2].get<double>()) + "\n";
  const size_t show = std::min<size_t>(s.meshes.size(), 20);
  o += "\n  mesh                             triangles     vertices    instances\n";
  for (size_t m = 0; m < show; ++m) {
    const auto& row = j["mesh_table"][m];
    char line[160];
    std::snprintf(line, sizeof line, "  %-30.30s %11s  %11s  %11s\n", row["name"].get<std::string>().c_str(),
                  group(row["triangles"].get<uint64_t>()).c_str(), group(row["vertices"].get<uint64_t>()).c_str(),
                  group(row["instances"].get<uint64_t>()).c_str());
    o += line;
  }
  if (show < s.meshes.size()) o += "  ... " + std::to_string(s.meshes.size() - show) + " more meshes (--json lists all)\n";
  o += "\nwarnings             " + std::to_string(s.warnings.size()) + "\n";
  for (const auto& w : s.warnings) o += "  " + w + "\n";
  return o;
}

}  // namespace rtp
