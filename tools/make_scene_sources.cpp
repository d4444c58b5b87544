// rtpack-make-scene's source meshes (make_scene_sources.h): found, imported, refined, measured.
#include "make_scene_sources.h"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <unordered_map>

#include "core/error.h"
#include "core/input_file.h"
#include "scene/import.h"

namespace rtp::tools {

namespace fs = std::filesystem;

// Default sample paths are relative to a data root holding samples/. Looked for, in order: $RTP_DATA_DIR,
// the installed data directory beside the executable (PREFIX/bin -> PREFIX/share/rtpack, `cmake --install
// --component tools`), the working directory, and every directory above the executable (a build directory
// inside the repository). Not found: exit 2 naming every place looked in and --mesh.
std::string resolve_default(const std::string& rel) {
  std::vector<fs::path> roots;
  if (const char* env = std::getenv("RTP_DATA_DIR"); env && *env) roots.push_back(env);
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) roots.push_back(exe.parent_path().parent_path() / "share" / "rtpack");
  roots.push_back(fs::current_path(ec));
  if (!exe.empty())
    for (fs::path dir = exe.parent_path(); !dir.empty(); dir = dir.parent_path()) {
      roots.push_back(dir);
      if (dir == dir.root_path()) break;
    }
  std::string looked;
  for (const fs::path& root : roots) {
    if (root.empty()) continue;
    if (fs::is_regular_file(root / rel, ec)) return (root / rel).string();
    looked += (looked.empty() ? "" : ", ") + root.string();
  }
  throw Error(ExitCode::kInputIo,
              "cannot find the default mesh '" + rel + "' (looked under: " + looked +
                  "); pass your own with --mesh FILE.gltf, or set RTP_DATA_DIR to a directory holding samples/");
}

std::vector<SourceMesh> load_sources(const std::vector<std::string>& files, const std::vector<std::string>& allow_paths,
                                     const std::string& output) {
  std::vector<SourceMesh> out;
  for (const std::string& file : files) {
    rtp::Scene scene;
    try {
      rtp::ImportOptions opt;
      opt.allowed_dirs = allow_paths;
      scene = rtp::import_gltf(file, opt);
    } catch (const Error& e) {
      throw Error(e.code(), "mesh source '" + file + "': " + e.what());
    } catch (const std::exception& e) {
      throw Error(ExitCode::kInputIo, "cannot read mesh source '" + file + "': " + e.what());
    }
    for (const std::string& b : scene.input.buffer_paths) rtp::check_not_same_file(b, output);  // nor its buffers
    const size_t before = out.size();
    for (size_t i = 0; i < scene.meshes.size(); ++i) {
      rtp::Mesh& m = scene.meshes[i];
      if (m.triangle_count() == 0) continue;
      SourceMesh s;
      s.name = m.name.empty() ? fs::path(file).stem().string() + "_" + std::to_string(i) : m.name;
      s.positions = std::move(m.positions);
      s.indices = std::move(m.indices);
      for (const rtp::Vec3f& p : s.positions)
        if (!rtp::is_finite(p)) throw Error(ExitCode::kInputInvalid, file + ": mesh '" + s.name + "' has a non-finite position");
      for (uint32_t v : s.indices)
        if (v >= s.positions.size())
          throw Error(ExitCode::kInputInvalid, file + ": mesh '" + s.name + "' has an index out of range");
      out.push_back(std::move(s));
    }
    if (out.size() == before) throw Error(ExitCode::kInputInvalid, file + ": no mesh with triangles");
  }
  return out;
}

// One 1-to-4 midpoint split: (a,b,c) -> (a,ab,ca) (ab,b,bc) (ca,bc,c) (ab,bc,ca), winding kept.
void refine_once(SourceMesh& m) {
  std::unordered_map<uint64_t, uint32_t> midpoints;
  midpoints.reserve(m.indices.size());
  std::vector<uint32_t> out;
  out.reserve(m.indices.size() * 4);
  auto mid = [&](uint32_t a, uint32_t b) {
    const uint64_t key = (uint64_t(std::min(a, b)) << 32) | std::max(a, b);
    auto [it, inserted] = midpoints.try_emplace(key, uint32_t(m.positions.size()));
    if (inserted) {
      const rtp::Vec3f pa = m.positions[a], pb = m.positions[b];
      m.positions.push_back({(pa.x + pb.x) * 0.5f, (pa.y + pb.y) * 0.5f, (pa.z + pb.z) * 0.5f});
    }
    return it->second;
  };
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    const uint32_t a = m.indices[t], b = m.indices[t + 1], c = m.indices[t + 2];
    const uint32_t ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
    out.insert(out.end(), {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca});
  }
  m.indices = std::move(out);
}

void compute_bounds(SourceMesh& m) {
  // min/max of the POSITION accessor cover every vertex, referenced or not.
  m.lo = m.hi = m.positions.at(0);
  for (const rtp::Vec3f& p : m.positions)
    for (int k = 0; k < 3; ++k) {
      m.lo[k] = std::min(m.lo[k], p[k]);
      m.hi[k] = std::max(m.hi[k], p[k]);
    }
  double extent = 0;
  for (int k = 0; k < 3; ++k) extent = std::max(extent, double(m.hi[k]) - double(m.lo[k]));
  m.norm = extent > 0 ? 1.0 / extent : 1.0;
}

}  // namespace rtp::tools
