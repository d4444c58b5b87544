// glTF mesh -> rtp::Mesh: all triangle primitives merged, strips and fans expanded, indices checked,
// triangles with non-finite positions dropped, and a source map kept for every triangle.
#include <cmath>

#include "core/error.h"
#include "scene/gltf_internal.h"

namespace rtp::gltf {

namespace {

// glTF 2.0 §3.7.2.1: NORMAL is a unit VEC3 (float, or normalized byte/short with
// KHR_mesh_quantization). Dequantized normals are renormalized; a zero or non-finite one becomes
// (0,0,0) ("none given") and is counted.
std::vector<Vec3f> read_normals(const tinygltf::Model& model, int accessor, size_t count, const std::string& ptr, uint64_t& bad) {
  const std::vector<Vec3f> raw = read_vec3(model, accessor, ptr);
  if (raw.size() != count)
    fail_invalid(ptr + ": " + std::to_string(raw.size()) + " normals for " + std::to_string(count) + " positions");
  std::vector<Vec3f> out(raw.size());
  for (size_t i = 0; i < raw.size(); ++i) {
    const Vec3f n = raw[i];
    const double len2 = double(n.x) * n.x + double(n.y) * n.y + double(n.z) * n.z;
    if (!std::isfinite(len2) || len2 == 0) {
      ++bad;
      continue;
    }
    if (std::abs(len2 - 1) <= 1e-6) {
      out[i] = n;  // already unit length: stored exactly as given
    } else {
      const double inv = 1 / std::sqrt(len2);
      out[i] = {float(n.x * inv), float(n.y * inv), float(n.z * inv)};
    }
  }
  return out;
}

// TEXCOORD_0: VEC2 float or normalized unsigned byte/short. Non-finite values become (0,0), counted.
std::vector<Vec2f> read_uvs(const tinygltf::Model& model, int accessor, size_t count, const std::string& ptr, uint64_t& bad) {
  const std::vector<double> raw = read_components(model, accessor, 2, ptr);
  if (raw.size() != 2 * count)
    fail_invalid(ptr + ": " + std::to_string(raw.size() / 2) + " texture coordinates for " + std::to_string(count) +
                 " positions");
  std::vector<Vec2f> out(count);
  for (size_t i = 0; i < count; ++i) {
    const Vec2f t{float(raw[2 * i]), float(raw[2 * i + 1])};
    if (std::isfinite(t.x) && std::isfinite(t.y))
      out[i] = t;
    else
      ++bad;
  }
  return out;
}

// KHR_texture_transform of one texture reference: uv' = T(offset)·R(rotation)·S(scale)·uv.
struct UvTransform {
  double offset[2] = {0, 0}, rotation = 0, scale[2] = {1, 1};
  bool operator==(const UvTransform&) const = default;
  Vec2f apply(Vec2f t) const {
    const double a = scale[0] * t.x, b = scale[1] * t.y, c = std::cos(rotation), s = std::sin(rotation);
    return {float(c * a + s * b + offset[0]), float(-s * a + c * b + offset[1])};
  }
};

UvTransform read_transform(const tinygltf::ExtensionMap& ext) {
  UvTransform t;
  auto it = ext.find("KHR_texture_transform");
  if (it == ext.end() || !it->second.IsObject()) return t;
  const tinygltf::Value& v = it->second;
  auto num = [](const tinygltf::Value& x, double d) { return x.IsNumber() ? x.GetNumberAsDouble() : d; };
  if (v.Has("offset") && v.Get("offset").IsArray() && v.Get("offset").ArrayLen() == 2)
    for (int k = 0; k < 2; ++k) t.offset[k] = num(v.Get("offset").Get(k), 0);
  if (v.Has("scale") && v.Get("scale").IsArray() && v.Get("scale").ArrayLen() == 2)
    for (int k = 0; k < 2; ++k) t.scale[k] = num(v.Get("scale").Get(k), 1);
  if (v.Has("rotation")) t.rotation = num(v.Get("rotation"), 0);
  return t;
}

// The transform every texture of the primitive's material applies to TEXCOORD_0, when they all agree
// (KHR_mesh_quantization writers such as gltfpack store integer uvs and put their dequantization
// there). Returns false when textures on set 0 disagree: the uvs then stay as stored.
bool material_uv_transform(const tinygltf::Model& model, int material, UvTransform& out) {
  out = {};
  if (material < 0 || size_t(material) >= model.materials.size()) return true;
  const tinygltf::Material& m = model.materials[size_t(material)];
  std::vector<UvTransform> seen;
  auto add = [&](int index, int tex_coord, const tinygltf::ExtensionMap& ext) {
    if (index < 0 || tex_coord != 0) return;
    seen.push_back(read_transform(ext));
  };
  const auto& pbr = m.pbrMetallicRoughness;
  add(pbr.baseColorTexture.index, pbr.baseColorTexture.texCoord, pbr.baseColorTexture.extensions);
  add(pbr.metallicRoughnessTexture.index, pbr.metallicRoughnessTexture.texCoord, pbr.metallicRoughnessTexture.extensions);
  add(m.normalTexture.index, m.normalTexture.texCoord, m.normalTexture.extensions);
  add(m.occlusionTexture.index, m.occlusionTexture.texCoord, m.occlusionTexture.extensions);
  add(m.emissiveTexture.index, m.emissiveTexture.texCoord, m.emissiveTexture.extensions);
  for (const UvTransform& t : seen)
    if (!(t == seen.front())) return false;
  if (!seen.empty()) out = seen.front();
  return true;
}

}  // namespace

Mesh build_mesh(const tinygltf::Model& model, int gltf_mesh, std::vector<std::string>& warnings, bool want_normals,
                bool want_uvs) {
  using std::to_string;
  uint64_t bad_normals = 0, bad_uvs = 0;
  bool any_normals = false, any_uvs = false;
  std::vector<Vec3f> normals;
  std::vector<Vec2f> uvs;
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
    if (want_normals) {
      auto it = prim.attributes.find("NORMAL");
      if (it != prim.attributes.end()) {
        const auto n = read_normals(model, it->second, pos.size(), pp + "/attributes/NORMAL", bad_normals);
        normals.insert(normals.end(), n.begin(), n.end());
        any_normals = true;
      } else {
        normals.resize(mesh.positions.size());
      }
    }
    if (want_uvs) {
      auto it = prim.attributes.find("TEXCOORD_0");
      if (it != prim.attributes.end()) {
        auto t = read_uvs(model, it->second, pos.size(), pp + "/attributes/TEXCOORD_0", bad_uvs);
        UvTransform xf;
        if (!material_uv_transform(model, prim.material, xf))
          warnings.push_back(pp +
                             ": its material's textures use different KHR_texture_transform; TEXCOORD_0 stored untransformed");
        else if (!(xf == UvTransform{}))
          for (Vec2f& uv : t) uv = xf.apply(uv);
        uvs.insert(uvs.end(), t.begin(), t.end());
        any_uvs = true;
      } else {
        uvs.resize(mesh.positions.size());
      }
    }
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
  // A mesh where no primitive has the attribute stores none of it (store no more than the scene has).
  if (any_normals) mesh.normals = std::move(normals);
  if (any_uvs) mesh.uvs = std::move(uvs);
  if (bad_normals) warnings.push_back(mp + ": " + to_string(bad_normals) + " zero or non-finite normals stored as (0,0,0)");
  if (bad_uvs) warnings.push_back(mp + ": " + to_string(bad_uvs) + " non-finite texture coordinates stored as (0,0)");
  if (skipped_nontriangle) warnings.push_back(mp + ": " + to_string(skipped_nontriangle) + " point/line primitives skipped");
  return mesh;
}

}  // namespace rtp::gltf
