// glTF mesh -> rtp::Mesh: all triangle primitives merged, strips and fans expanded, indices checked,
// triangles with non-finite positions dropped, and a source map kept for every triangle.
#include "core/error.h"
#include "scene/gltf_internal.h"

namespace rtp::gltf {

Mesh build_mesh(const tinygltf::Model& model, int gltf_mesh, std::vector<std::string>& warnings) {
  using std::to_string;
  const tinygltf::Mesh& gm = model.meshes[size_t(gltf_mesh)];
  const std::string mp = "/meshes/" + to_string(gltf_mesh);
  Mesh mesh;
  mesh.name = gm.name.empty() ? "mesh" + to_string(gltf_mesh) : gm.name;
  int skipped_nontriangle = 0;
  for (size_t p = 0; p < gm.primitives.size(); ++p) {
    const tinygltf::Primitive& prim = gm.primitives[p];
    const std::string pp = mp + "/primitives/" + to_string(p);
    const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN) {
      ++skipped_nontriangle;
      continue;
    }
    auto pos_it = prim.attributes.find("POSITION");
    if (pos_it == prim.attributes.end()) {
      warnings.push_back(pp + ": no POSITION attribute, primitive skipped");
      continue;
    }
    const std::vector<Vec3f> pos = read_vec3(model, pos_it->second, pp + "/attributes/POSITION");
    std::vector<uint32_t> idx;
    if (prim.indices >= 0) {
      idx = read_indices(model, prim.indices, pp + "/indices");
      for (uint32_t i : idx)
        if (i >= pos.size())
          fail_invalid(pp + "/indices: index " + to_string(i) + " out of range (" + to_string(pos.size()) + " vertices)");
    } else {
      idx.resize(pos.size());
      for (size_t i = 0; i < idx.size(); ++i) idx[i] = uint32_t(i);
    }
    // glTF 2.0 §3.7.2.1: triangle i of a strip is {i, i+(1+i%2), i+(2-i%2)}; of a fan {i+1, i+2, 0}.
    std::vector<uint32_t> tri;
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      if (idx.size() % 3)
        warnings.push_back(pp + ": " + to_string(idx.size() % 3) + " trailing indices ignored (count not a multiple of 3)");
      tri.assign(idx.begin(), idx.begin() + (idx.size() / 3) * 3);
    } else if (idx.size() >= 3) {
      tri.reserve((idx.size() - 2) * 3);
      for (size_t i = 0; i + 2 < idx.size(); ++i) {
        if (mode == TINYGLTF_MODE_TRIANGLE_STRIP)
          tri.insert(tri.end(), {idx[i], idx[i + 1 + i % 2], idx[i + 2 - i % 2]});
        else
          tri.insert(tri.end(), {idx[i + 1], idx[i + 2], idx[0]});
      }
    }
    const uint32_t slot = uint32_t(mesh.primitives.size());
    mesh.primitives.push_back({uint32_t(gltf_mesh), uint32_t(p)});
    const size_t base = mesh.positions.size();
    if (base + pos.size() > 0xffffffffu) fail_invalid(mp + ": more than 2^32 vertices in one mesh");
    mesh.positions.insert(mesh.positions.end(), pos.begin(), pos.end());
    uint64_t dropped = 0;
    for (size_t t = 0; t * 3 < tri.size(); ++t) {
      const uint32_t a = tri[3 * t], b = tri[3 * t + 1], c = tri[3 * t + 2];
      if (!is_finite(pos[a]) || !is_finite(pos[b]) || !is_finite(pos[c])) {
        ++dropped;
        continue;
      }
      mesh.indices.insert(mesh.indices.end(), {uint32_t(base + a), uint32_t(base + b), uint32_t(base + c)});
      mesh.source.push_back({slot, uint32_t(t)});
    }
    if (dropped) warnings.push_back(pp + ": dropped " + to_string(dropped) + " triangles with NaN/Inf positions");
  }
  if (skipped_nontriangle)
    warnings.push_back(mp + ": " + to_string(skipped_nontriangle) + " point/line primitives skipped");
  return mesh;
}

}  // namespace rtp::gltf
