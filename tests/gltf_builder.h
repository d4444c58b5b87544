#pragma once
// Test helper: fabricates small glTF files (.gltf with data-URI or external buffers, .glb) so every
// import path and every rejection can be exercised on exact bytes.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <unistd.h>
#include <string>
#include <vector>

namespace rtp::test {

inline std::string base64(const std::vector<uint8_t>& d) {
  static const char* t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string o;
  for (size_t i = 0; i < d.size(); i += 3) {
    uint32_t v = uint32_t(d[i]) << 16 | (i + 1 < d.size() ? uint32_t(d[i + 1]) << 8 : 0) | (i + 2 < d.size() ? d[i + 2] : 0);
    o += t[v >> 18 & 63];
    o += t[v >> 12 & 63];
    o += i + 1 < d.size() ? t[v >> 6 & 63] : '=';
    o += i + 2 < d.size() ? t[v & 63] : '=';
  }
  return o;
}

// A glTF document under construction: one binary buffer, views and accessors appended as data is added.
struct GltfBuilder {
  nlohmann::json j = {{"asset", {{"version", "2.0"}}}};
  std::vector<uint8_t> bin;

  template <class T>
  int add_view(const std::vector<T>& data, int stride = 0) {
    while (bin.size() % 4) bin.push_back(0);
    const size_t off = bin.size();
    bin.resize(off + data.size() * sizeof(T));
    std::memcpy(bin.data() + off, data.data(), data.size() * sizeof(T));
    nlohmann::json v = {{"buffer", 0}, {"byteOffset", off}, {"byteLength", data.size() * sizeof(T)}};
    if (stride) v["byteStride"] = stride;
    j["bufferViews"].push_back(v);
    return int(j["bufferViews"].size() - 1);
  }
  int add_accessor(int view, int component_type, const char* type, size_t count, bool normalized = false,
                   size_t byte_offset = 0) {
    nlohmann::json a = {{"componentType", component_type}, {"type", type}, {"count", count}};
    if (view >= 0) a["bufferView"] = view;
    if (byte_offset) a["byteOffset"] = byte_offset;
    if (normalized) a["normalized"] = true;
    j["accessors"].push_back(a);
    return int(j["accessors"].size() - 1);
  }
  int add_positions(const std::vector<float>& xyz) { return add_accessor(add_view(xyz), 5126, "VEC3", xyz.size() / 3); }
  template <class T>
  int add_indices(const std::vector<T>& idx) {
    const int ct = sizeof(T) == 1 ? 5121 : (sizeof(T) == 2 ? 5123 : 5125);
    return add_accessor(add_view(idx), ct, "SCALAR", idx.size());
  }
  // A mesh with one primitive; returns the mesh index.
  int add_mesh(int positions, int indices = -1, int mode = -1) {
    nlohmann::json p = {{"attributes", {{"POSITION", positions}}}};
    if (indices >= 0) p["indices"] = indices;
    if (mode >= 0) p["mode"] = mode;
    j["meshes"].push_back({{"primitives", {p}}});
    return int(j["meshes"].size() - 1);
  }
  int add_node(nlohmann::json node) {
    j["nodes"].push_back(node);
    return int(j["nodes"].size() - 1);
  }
  // Makes scene 0 with the given roots (the default scene).
  void set_scene(const std::vector<int>& roots) {
    j["scenes"] = nlohmann::json::array({{{"nodes", roots}}});
    j["scene"] = 0;
  }
  // Writes a .gltf with the buffer as a data URI.
  std::string write_gltf(const std::filesystem::path& p) {
    nlohmann::json d = j;
    d["buffers"] = {{{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin)}}};
    std::ofstream(p, std::ios::binary) << d.dump();
    return p.string();
  }
  // Writes a .gltf plus an external .bin next to it.
  std::string write_gltf_external(const std::filesystem::path& p, const std::string& bin_name) {
    nlohmann::json d = j;
    d["buffers"] = {{{"byteLength", bin.size()}, {"uri", bin_name}}};
    std::ofstream(p, std::ios::binary) << d.dump();
    std::ofstream(p.parent_path() / bin_name, std::ios::binary)
        .write(reinterpret_cast<const char*>(bin.data()), std::streamsize(bin.size()));
    return p.string();
  }
  std::string glb_bytes() const {
    nlohmann::json d = j;
    d["buffers"] = {{{"byteLength", bin.size()}}};
    std::string js = d.dump();
    while (js.size() % 4) js.push_back(' ');
    std::vector<uint8_t> b = bin;
    while (b.size() % 4) b.push_back(0);
    std::string out;
    auto put = [&](uint32_t v) { out.append(reinterpret_cast<const char*>(&v), 4); };
    put(0x46546C67);
    put(2);
    put(uint32_t(12 + 8 + js.size() + 8 + b.size()));
    put(uint32_t(js.size()));
    put(0x4E4F534A);
    out += js;
    put(uint32_t(b.size()));
    put(0x004E4942);
    out.append(reinterpret_cast<const char*>(b.data()), b.size());
    return out;
  }
  std::string write_glb(const std::filesystem::path& p) {
    std::ofstream(p, std::ios::binary) << glb_bytes();
    return p.string();
  }
};

// One triangle (0,0,0) (1,0,0) (0,1,0) with uint16 indices, one node, scene 0.
inline GltfBuilder one_triangle() {
  GltfBuilder b;
  const int pos = b.add_positions({0, 0, 0, 1, 0, 0, 0, 1, 0});
  const int idx = b.add_indices(std::vector<uint16_t>{0, 1, 2});
  b.add_mesh(pos, idx);
  b.set_scene({b.add_node({{"mesh", 0}})});
  return b;
}

// A fresh temporary directory per test.
inline std::filesystem::path temp_dir(const std::string& name) {
  auto d = std::filesystem::temp_directory_path() / ("rtp_test_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

inline std::filesystem::path source_dir() { return RTP_SOURCE_DIR; }
inline std::filesystem::path shared_assets() { return std::filesystem::path(RTP_SOURCE_DIR) / ".." / "shared" / "assets"; }

// TESTING.md: ../shared/assets may be missing on a developer's machine (the tests that need it skip), never
// in CI: scripts/test sets RTP_REQUIRE_SHARED=1 when the assets are there, and a missing asset then fails
// the test instead of letting it pass unseen (a renamed file or a wrong path skipped silently).
inline bool shared_assets_required() {
  const char* v = std::getenv("RTP_REQUIRE_SHARED");
  return v != nullptr && *v != 0 && std::string(v) != "0";
}

}  // namespace rtp::test

// Skips the test when `where` (a ../shared/assets file or directory) is absent, or fails it under
// RTP_REQUIRE_SHARED. Returns from the test body either way.
#define RTP_NEED_SHARED(where)                                                                                            \
  do {                                                                                                                    \
    const std::filesystem::path& rtp_need_shared_path_ = (where);                                                         \
    if (!std::filesystem::exists(rtp_need_shared_path_)) {                                                                \
      if (::rtp::test::shared_assets_required())                                                                          \
        FAIL() << rtp_need_shared_path_ << " is absent, and RTP_REQUIRE_SHARED is set (../shared/assets)";                \
      GTEST_SKIP() << rtp_need_shared_path_ << " is absent (../shared/assets is not checked out next to the repository)"; \
    }                                                                                                                     \
  } while (0)

namespace rtp::test {}  // namespace rtp::test
