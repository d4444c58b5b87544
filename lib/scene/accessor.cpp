// glTF accessor reading: byteStride, normalized integers (KHR_mesh_quantization), sparse substitution.
// Every byte read is checked against the real buffer data, whatever the JSON claimed.
#include <cmath>
#include <cstring>

#include "core/error.h"
#include "scene/gltf_internal.h"

namespace rtp::gltf {
namespace {

using std::to_string;

int component_bytes(int ct) {
  switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
  }
}

// glTF 2.0 §3.11 "Animations"/"KHR_mesh_quantization": normalized integer -> float mapping.
double decode_component(const unsigned char* p, int ct, bool normalized) {
  switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
      float f;
      std::memcpy(&f, p, 4);
      return f;
    }
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      int8_t v;
      std::memcpy(&v, p, 1);
      return normalized ? std::max(v / 127.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[0] / 255.0 : p[0];
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? std::max(v / 32767.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? v / 65535.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
      uint32_t v;
      std::memcpy(&v, p, 4);
      return normalized ? v / 4294967295.0 : v;
    }
    default: return 0;
  }
}

uint32_t decode_uint(const unsigned char* p, int ct) {
  switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return p[0];
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t v;
      std::memcpy(&v, p, 2);
      return v;
    }
    default: {
      uint32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
  }
}

// A checked view of `count` elements of `elem` bytes starting at byteOffset within a bufferView.
struct Span {
  const unsigned char* base = nullptr;
  size_t stride = 0;
};

Span span_of(const tinygltf::Model& m, int view, size_t offset, size_t count, size_t elem, bool use_stride,
             const std::string& ptr) {
  if (view < 0 || size_t(view) >= m.bufferViews.size()) fail_invalid(ptr + ": bufferView " + to_string(view) + " out of range");
  const tinygltf::BufferView& bv = m.bufferViews[size_t(view)];
  if (bv.buffer < 0 || size_t(bv.buffer) >= m.buffers.size()) fail_invalid(ptr + ": buffer out of range");
  const auto& data = m.buffers[size_t(bv.buffer)].data;
  const size_t stride = (use_stride && bv.byteStride) ? bv.byteStride : elem;
  const unsigned __int128 end = (unsigned __int128)bv.byteOffset + offset + (unsigned __int128)(count - 1) * stride + elem;
  if (count == 0 || end > (unsigned __int128)bv.byteOffset + bv.byteLength || end > data.size() || stride < elem)
    fail_invalid(ptr + ": data overruns bufferView " + to_string(view) + " (" + to_string(bv.byteLength) + " bytes)");
  return {data.data() + bv.byteOffset + offset, stride};
}

const tinygltf::Accessor& accessor_at(const tinygltf::Model& m, int a, const std::string& ptr) {
  if (a < 0 || size_t(a) >= m.accessors.size()) fail_invalid(ptr + ": accessor " + to_string(a) + " out of range");
  return m.accessors[size_t(a)];
}

}  // namespace

std::vector<double> read_components(const tinygltf::Model& m, int a, int components, const std::string& ptr) {
  const tinygltf::Accessor& acc = accessor_at(m, a, ptr);
  const int ncomp = tinygltf::GetNumComponentsInType(uint32_t(acc.type));
  const int cbytes = component_bytes(acc.componentType);
  if (ncomp != components || cbytes == 0)
    fail_invalid(ptr + ": accessor " + to_string(a) + " has " + to_string(ncomp) + " components, expected " +
                 to_string(components));
  const size_t count = acc.count, elem = size_t(ncomp) * size_t(cbytes);
  // The data is located (and bounds-checked) before the output is allocated from `count`.
  Span s;
  if (acc.bufferView >= 0) s = span_of(m, acc.bufferView, acc.byteOffset, count, elem, true, ptr);
  std::vector<double> out(count * size_t(components), 0.0);
  if (acc.bufferView >= 0) {
    for (size_t i = 0; i < count; ++i)
      for (int c = 0; c < components; ++c)
        out[i * size_t(components) + size_t(c)] =
            decode_component(s.base + i * s.stride + size_t(c) * size_t(cbytes), acc.componentType, acc.normalized);
  }
  if (acc.sparse.isSparse) {
    // glTF 2.0 §3.6.2.3 sparse accessors: substitute values at the listed indices.
    const size_t sc = size_t(acc.sparse.count);
    const int ict = acc.sparse.indices.componentType;
    const int ib = component_bytes(ict);
    if (ib == 0 || ict == TINYGLTF_COMPONENT_TYPE_FLOAT || ict == TINYGLTF_COMPONENT_TYPE_BYTE ||
        ict == TINYGLTF_COMPONENT_TYPE_SHORT)
      fail_invalid(ptr + "/sparse/indices/componentType: invalid");
    const Span si =
        span_of(m, acc.sparse.indices.bufferView, acc.sparse.indices.byteOffset, sc, size_t(ib), false, ptr + "/sparse/indices");
    const Span sv =
        span_of(m, acc.sparse.values.bufferView, acc.sparse.values.byteOffset, sc, elem, false, ptr + "/sparse/values");
    for (size_t k = 0; k < sc; ++k) {
      const uint32_t idx = decode_uint(si.base + k * size_t(ib), ict);
      if (idx >= count)
        fail_invalid(ptr + "/sparse/indices: index " + to_string(idx) + " out of range (" + to_string(count) + " elements)");
      for (int c = 0; c < components; ++c)
        out[size_t(idx) * size_t(components) + size_t(c)] =
            decode_component(sv.base + k * elem + size_t(c) * size_t(cbytes), acc.componentType, acc.normalized);
    }
  }
  return out;
}

std::vector<Vec3f> read_vec3(const tinygltf::Model& m, int a, const std::string& ptr) {
  const tinygltf::Accessor& acc = accessor_at(m, a, ptr);
  if (acc.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT && !acc.sparse.isSparse && acc.bufferView >= 0 &&
      acc.type == TINYGLTF_TYPE_VEC3) {  // fast path: plain float positions
    const Span s = span_of(m, acc.bufferView, acc.byteOffset, acc.count, 12, true, ptr);
    std::vector<Vec3f> out(acc.count);
    for (size_t i = 0; i < acc.count; ++i) std::memcpy(&out[i], s.base + i * s.stride, 12);
    return out;
  }
  const std::vector<double> v = read_components(m, a, 3, ptr);
  std::vector<Vec3f> out(acc.count);
  for (size_t i = 0; i < acc.count; ++i) out[i] = {float(v[3 * i]), float(v[3 * i + 1]), float(v[3 * i + 2])};
  return out;
}

std::vector<uint32_t> read_indices(const tinygltf::Model& m, int a, const std::string& ptr) {
  const tinygltf::Accessor& acc = accessor_at(m, a, ptr);
  const int ct = acc.componentType;
  if (acc.type != TINYGLTF_TYPE_SCALAR ||
      (ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
       ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT))
    fail_invalid(ptr + ": indices must be SCALAR unsigned byte/short/int (accessor " + to_string(a) + ")");
  const size_t cb = size_t(component_bytes(ct));
  Span s;
  if (acc.bufferView >= 0) s = span_of(m, acc.bufferView, acc.byteOffset, acc.count, cb, true, ptr);
  std::vector<uint32_t> out(acc.count, 0);
  if (acc.bufferView >= 0) {
    for (size_t i = 0; i < acc.count; ++i) out[i] = decode_uint(s.base + i * s.stride, ct);
  }
  if (acc.sparse.isSparse) {
    const std::vector<double> v = read_components(m, a, 1, ptr);
    for (size_t i = 0; i < acc.count; ++i) out[i] = uint32_t(v[i]);
  }
  return out;
}

}  // namespace rtp::gltf
