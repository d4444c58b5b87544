// KHR_draco_mesh_compression, decoded here rather than by tinygltf: tinygltf trusts the payload
// (an attribute id the payload lacks is a null dereference, a failed decode is silently ignored).
// Every attribute id, component count and decode failure is reported with the primitive's pointer.
#include <draco/compression/decode.h>
#include <draco/core/decoder_buffer.h>

#include <climits>
#include <cstring>
#include <map>
#include <memory>

#include "core/error.h"
#include "core/json_checked.h"
#include "scene/gltf_internal.h"

namespace rtp::gltf {
namespace {

using nlohmann::json;
using std::to_string;

constexpr const char* kExt = "KHR_draco_mesh_compression";

// The Draco extension object of a primitive, or nullptr.
const json* draco_of(const json& primitive) {
  const json* ext = jsonc::find(primitive, "extensions");
  return ext ? jsonc::find(*ext, kExt) : nullptr;
}

// Appends `bytes` as a new buffer + bufferView and points accessor `a` at it.
void attach(tinygltf::Model& m, int a, std::vector<unsigned char>&& bytes, size_t count) {
  tinygltf::Buffer buf;
  buf.data = std::move(bytes);
  tinygltf::BufferView view;
  view.buffer = int(m.buffers.size());
  view.byteOffset = 0;
  view.byteLength = buf.data.size();
  view.byteStride = 0;
  m.buffers.push_back(std::move(buf));
  m.bufferViews.push_back(view);
  tinygltf::Accessor& acc = m.accessors[size_t(a)];
  acc.bufferView = int(m.bufferViews.size() - 1);
  acc.byteOffset = 0;
  acc.count = count;
  acc.sparse = {};  // the payload is the whole data
}

template <class T>
bool convert_all(const draco::Mesh& mesh, const draco::PointAttribute& att, int components, std::vector<unsigned char>& out) {
  T values[16];
  out.resize(size_t(mesh.num_points()) * size_t(components) * sizeof(T));
  unsigned char* dst = out.data();
  for (draco::PointIndex i(0); i < mesh.num_points(); ++i) {
    if (!att.ConvertValue<T>(att.mapped_index(i), int8_t(components), values)) return false;
    std::memcpy(dst, values, sizeof(T) * size_t(components));
    dst += sizeof(T) * size_t(components);
  }
  return true;
}

// The attribute's values for every point, converted to the accessor's component type.
bool convert(const draco::Mesh& mesh, const draco::PointAttribute& att, int component_type, int components,
             std::vector<unsigned char>& out) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: return convert_all<int8_t>(mesh, att, components, out);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return convert_all<uint8_t>(mesh, att, components, out);
    case TINYGLTF_COMPONENT_TYPE_SHORT: return convert_all<int16_t>(mesh, att, components, out);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return convert_all<uint16_t>(mesh, att, components, out);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return convert_all<uint32_t>(mesh, att, components, out);
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return convert_all<float>(mesh, att, components, out);
    default: return false;
  }
}

}  // namespace

void strip_draco(json& patched) {
  if (!patched.contains("meshes") || !patched["meshes"].is_array()) return;
  for (json& m : patched["meshes"]) {
    if (!m.is_object() || !m.contains("primitives") || !m["primitives"].is_array()) continue;
    for (json& p : m["primitives"])
      if (draco_of(p)) {
        p["extensions"].erase(kExt);
        p.erase("indices");  // tinygltf requires an indices accessor to have a bufferView: decode_draco sets it
      }
  }
}

void decode_draco(Document& doc) {
  const json* meshes = jsonc::find(doc.json, "meshes");
  if (!meshes) return;
  tinygltf::Model& model = doc.model;
  std::map<int, std::shared_ptr<draco::Mesh>> decoded;  // by bufferView: primitives may share a payload
  for (size_t mi = 0; mi < meshes->size(); ++mi) {
    const json& prims = (*meshes)[mi]["primitives"];
    for (size_t pi = 0; pi < prims.size(); ++pi) {
      const json& pr = prims[pi];
      const json* d = draco_of(pr);
      if (!d) continue;
      const std::string dp = "/meshes/" + to_string(mi) + "/primitives/" + to_string(pi) + "/extensions/" + kExt;
      const int view = int(jsonc::get_int(*d, "bufferView", dp));
      if (view < 0 || size_t(view) >= model.bufferViews.size()) fail_invalid(dp + "/bufferView: out of range");
      std::shared_ptr<draco::Mesh>& mesh = decoded[view];
      if (!mesh) {
        const tinygltf::BufferView& bv = model.bufferViews[size_t(view)];
        if (bv.buffer < 0 || size_t(bv.buffer) >= model.buffers.size()) fail_invalid(dp + "/bufferView: buffer out of range");
        const auto& data = model.buffers[size_t(bv.buffer)].data;
        if (bv.byteOffset > data.size() || bv.byteLength > data.size() - bv.byteOffset)
          fail_invalid(dp + ": bufferView " + to_string(view) + " overruns its buffer");
        draco::DecoderBuffer buffer;
        buffer.Init(reinterpret_cast<const char*>(data.data() + bv.byteOffset), bv.byteLength);
        draco::Decoder decoder;
        auto result = decoder.DecodeMeshFromBuffer(&buffer);
        if (!result.ok())
          fail_invalid(dp + ": Draco decode failed (bufferView " + to_string(view) + ", " + to_string(bv.byteLength) +
                       " bytes): " + result.status().error_msg_string());
        mesh = std::shared_ptr<draco::Mesh>(std::move(result).value());
      }
      if (mi >= model.meshes.size() || pi >= model.meshes[mi].primitives.size()) fail_invalid(dp + ": primitive not loaded");
      const std::map<std::string, int>& attributes = model.meshes[mi].primitives[pi].attributes;
      const draco::Mesh& dm = *mesh;
      if (dm.num_points() == 0 || dm.num_faces() == 0)
        fail_invalid(dp + ": Draco payload has " + to_string(dm.num_points()) + " points and " + to_string(dm.num_faces()) +
                     " faces");
      if (const json* ind = jsonc::find(pr, "indices")) {
        // Always stored as uint32: a uint16 accessor cannot hold indices of a payload with more points.
        std::vector<unsigned char> bytes(size_t(dm.num_faces()) * 3 * 4);
        unsigned char* dst = bytes.data();
        for (draco::FaceIndex f(0); f < dm.num_faces(); ++f)
          for (int k = 0; k < 3; ++k, dst += 4) {
            const uint32_t v = dm.face(f)[k].value();
            std::memcpy(dst, &v, 4);
          }
        const int a = int(ind->get<int64_t>());
        attach(model, a, std::move(bytes), size_t(dm.num_faces()) * 3);
        model.meshes[mi].primitives[pi].indices = a;
        model.accessors[size_t(a)].componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
      }
      for (auto it = (*d)["attributes"].begin(); it != (*d)["attributes"].end(); ++it) {
        const std::string ap = jsonc::child(dp + "/attributes", it.key());
        const int64_t id = jsonc::as_int(it.value(), ap);
        const auto found = attributes.find(it.key());
        if (found == attributes.end()) fail_invalid(ap + ": Draco attribute has no accessor in the primitive");
        const draco::PointAttribute* att = id < 0 || id > INT32_MAX ? nullptr : dm.GetAttributeByUniqueId(uint32_t(id));
        if (!att)
          fail_invalid(ap + ": Draco attribute id " + to_string(id) + " is not in the payload (" +
                       to_string(dm.num_attributes()) + " attributes)");
        const int a = found->second;
        const tinygltf::Accessor& acc = model.accessors[size_t(a)];
        const int components = tinygltf::GetNumComponentsInType(uint32_t(acc.type));
        if (components != att->num_components())
          fail_invalid(ap + ": Draco attribute " + to_string(id) + " has " + to_string(int(att->num_components())) +
                       " components but accessor " + to_string(a) + " has " + to_string(components));
        std::vector<unsigned char> bytes;
        if (!convert(dm, *att, acc.componentType, components, bytes))
          fail_invalid(ap + ": Draco attribute " + to_string(id) + " cannot be converted to accessor " + to_string(a) +
                       "'s component type");
        attach(model, a, std::move(bytes), size_t(dm.num_points()));
      }
    }
  }
}

}  // namespace rtp::gltf
