// Validation of the glTF JSON before tinygltf sees it: every reference in range, every accessor and
// bufferView inside its data, no node cycles. Messages name the JSON pointer (as gltf-validator does).
#include <algorithm>
#include <climits>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/json_checked.h"
#include "scene/gltf_internal.h"

namespace rtp::gltf {
namespace {

using nlohmann::json;
using std::to_string;

const json kEmptyArray = json::array();

// meshoptimizer's codecs cannot expand data more than this: the vertex codec spends at least 2 header
// bits per 16-byte group of one byte lane (64x), the index codec a code byte per triangle (12x), the
// index sequence codec a byte per index (4x). A larger claim is rejected before anything is allocated.
constexpr uint64_t kMeshoptMaxExpansion = 64;

// Floor of the byte budget of accessors without a bufferView (docs/exit-codes.md).
constexpr uint64_t kMaxUnbackedBytes = uint64_t(1) << 24;

const json& array_of(const json& root, const char* name) {
  if (!root.contains(name)) return kEmptyArray;
  const json& a = root[name];
  if (!a.is_array()) fail_invalid(std::string("/") + name + ": not an array");
  for (size_t i = 0; i < a.size(); ++i)
    if (!a[i].is_object()) fail_invalid(std::string("/") + name + "/" + to_string(i) + ": not an object");
  return a;
}

// An optional (or required) integer reference `obj[key]` into an array of `n` elements.
bool check_ref(const json& obj, const char* key, size_t n, const std::string& ptr, const char* target, bool required) {
  if (!obj.contains(key)) {
    if (required) fail_invalid(ptr + ": missing required '" + key + "'");
    return false;
  }
  const json& v = obj[key];
  if (!v.is_number_integer()) fail_invalid(ptr + "/" + key + ": not an integer");
  const int64_t i = v.get<int64_t>();
  if (i < 0 || uint64_t(i) >= n)
    fail_invalid(ptr + "/" + key + ": " + target + " " + to_string(i) + " out of range (" + to_string(n) + " " + target +
                 (std::string(target) == "mesh" ? "es)" : "s)"));
  return true;
}

uint64_t get_u64(const json& obj, const char* key, uint64_t def, const std::string& ptr) {
  if (!obj.contains(key)) return def;
  if (!obj[key].is_number_unsigned()) fail_invalid(ptr + "/" + key + ": not a non-negative integer");
  return obj[key].get<uint64_t>();
}

int components_of(const std::string& type) {
  if (type == "SCALAR") return 1;
  if (type == "VEC2") return 2;
  if (type == "VEC3") return 3;
  if (type == "VEC4") return 4;
  if (type == "MAT2") return 4;
  if (type == "MAT3") return 9;
  if (type == "MAT4") return 16;
  return 0;
}

int component_size(int64_t ct) {
  switch (ct) {
    case 5120:
    case 5121: return 1;
    case 5122:
    case 5123: return 2;
    case 5125:
    case 5126: return 4;
    default: return 0;
  }
}

// Bytes [offset, offset + (count-1)*stride + elem) must lie inside the bufferView.
void check_span(const json& views, int64_t view, uint64_t offset, uint64_t count, uint64_t elem, bool use_view_stride,
                const std::string& ptr) {
  const json& bv = views[size_t(view)];
  const uint64_t len = bv["byteLength"].get<uint64_t>();
  const uint64_t stride = (use_view_stride && bv.contains("byteStride")) ? bv["byteStride"].get<uint64_t>() : elem;
  if (use_view_stride && bv.contains("byteStride") && stride < elem)
    fail_invalid(ptr + ": element of " + to_string(elem) + " bytes is larger than bufferView " + to_string(view) +
                 " byteStride " + to_string(stride));
  const unsigned __int128 end = (unsigned __int128)offset + (unsigned __int128)(count - 1) * stride + elem;
  if (end > len)
    fail_invalid(ptr + ": needs " + to_string(uint64_t(end > ~uint64_t(0) ? ~uint64_t(0) : uint64_t(end))) +
                 " bytes but bufferView " + to_string(view) + " has " + to_string(len) + " (accessor overruns its bufferView)");
}

// Accessors without a bufferView are zero-filled (plus sparse values): they may not describe more bytes
// than the file's buffers hold, or kMaxUnbackedBytes, whichever is larger (a 1 KB file must not ask
// for gigabytes). Accessors a Draco primitive decodes into are sized by the payload, not by `count`.
void validate_accessors(const json& accessors, const json& views, uint64_t backed_bytes, const std::vector<bool>& draco_decoded) {
  for (size_t i = 0; i < accessors.size(); ++i) {
    const json& a = accessors[i];
    const std::string ptr = "/accessors/" + to_string(i);
    if (!a.contains("componentType") || !a["componentType"].is_number_integer() ||
        component_size(a["componentType"].get<int64_t>()) == 0)
      fail_invalid(ptr + "/componentType: missing or invalid");
    if (!a.contains("type") || !a["type"].is_string() || components_of(a["type"].get<std::string>()) == 0)
      fail_invalid(ptr + "/type: missing or invalid");
    const uint64_t count = get_u64(a, "count", 0, ptr);
    if (count == 0) fail_invalid(ptr + "/count: missing or zero");
    const uint64_t elem =
        uint64_t(component_size(a["componentType"].get<int64_t>())) * uint64_t(components_of(a["type"].get<std::string>()));
    if (check_ref(a, "bufferView", views.size(), ptr, "bufferView", false)) {
      check_span(views, a["bufferView"].get<int64_t>(), get_u64(a, "byteOffset", 0, ptr), count, elem, true, ptr);
    } else if (!draco_decoded[i]) {
      const uint64_t limit = std::max(kMaxUnbackedBytes, backed_bytes);
      if (count > limit / elem)
        fail_invalid(ptr + "/count: " + to_string(count) + " elements without a bufferView would take " +
                     (count > ~uint64_t(0) / elem ? std::string("more than 2^64") : to_string(count * elem)) +
                     " bytes; the file's buffers hold " + to_string(backed_bytes) + " (limit: that or " +
                     to_string(kMaxUnbackedBytes) + " bytes, whichever is larger)");
    }
    if (a.contains("sparse")) {
      const json& s = a["sparse"];
      const std::string sp = ptr + "/sparse";
      if (!s.is_object() || !s.contains("indices") || !s.contains("values") || !s["indices"].is_object() ||
          !s["values"].is_object())
        fail_invalid(sp + ": needs objects 'indices' and 'values'");
      const uint64_t sc = get_u64(s, "count", 0, sp);
      if (sc == 0 || sc > count) fail_invalid(sp + "/count: " + to_string(sc) + " not in 1.." + to_string(count));
      const json& si = s["indices"];
      check_ref(si, "bufferView", views.size(), sp + "/indices", "bufferView", true);
      const int64_t ict = jsonc::get_int(si, "componentType", sp + "/indices");
      if (ict != 5121 && ict != 5123 && ict != 5125) fail_invalid(sp + "/indices/componentType: invalid");
      check_span(views, si["bufferView"].get<int64_t>(), get_u64(si, "byteOffset", 0, sp + "/indices"), sc,
                 uint64_t(component_size(ict)), false, sp + "/indices");
      const json& sv = s["values"];
      check_ref(sv, "bufferView", views.size(), sp + "/values", "bufferView", true);
      check_span(views, sv["bufferView"].get<int64_t>(), get_u64(sv, "byteOffset", 0, sp + "/values"), sc, elem, false,
                 sp + "/values");
    }
  }
}

void validate_meshes(const json& meshes, const json& accessors, size_t n_views) {
  const size_t n_accessors = accessors.size();
  for (size_t m = 0; m < meshes.size(); ++m) {
    const std::string mp = "/meshes/" + to_string(m);
    if (!meshes[m].contains("primitives") || !meshes[m]["primitives"].is_array())
      fail_invalid(mp + "/primitives: missing or not an array");
    const json& prims = meshes[m]["primitives"];
    for (size_t p = 0; p < prims.size(); ++p) {
      const std::string pp = mp + "/primitives/" + to_string(p);
      const json& pr = prims[p];
      if (!pr.is_object() || !pr.contains("attributes") || !pr["attributes"].is_object())
        fail_invalid(pp + "/attributes: missing or not an object");
      for (auto it = pr["attributes"].begin(); it != pr["attributes"].end(); ++it)
        check_ref(pr["attributes"], it.key().c_str(), n_accessors, pp + "/attributes", "accessor", true);
      const bool draco =
          pr.contains("extensions") && pr["extensions"].is_object() && pr["extensions"].contains("KHR_draco_mesh_compression");
      // glTF 2.0 §3.6.2.1 lets an accessor without a bufferView be zeros; as indices that is no triangle
      // at all (tinygltf refuses it with "invalid bufferView", naming neither primitive nor pointer).
      if (check_ref(pr, "indices", n_accessors, pp, "accessor", false) && !draco) {
        const int64_t ia = pr["indices"].get<int64_t>();
        if (!accessors[size_t(ia)].is_object() || !accessors[size_t(ia)].contains("bufferView"))
          fail_invalid(pp + "/indices: accessor " + to_string(ia) +
                       " has no bufferView (indices must be stored in a buffer; all-zero indices make no triangle)");
      }
      const int64_t mode = jsonc::get_int(pr, "mode", 4, pp);
      if (mode < 0 || mode > 6) fail_invalid(pp + "/mode: " + to_string(mode) + " is not a glTF primitive mode");
      if (draco) {
        const json& d = pr["extensions"]["KHR_draco_mesh_compression"];
        const std::string dp = pp + "/extensions/KHR_draco_mesh_compression";
        if (!d.is_object() || !d.contains("attributes") || !d["attributes"].is_object())
          fail_invalid(dp + "/attributes: missing");
        check_ref(d, "bufferView", n_views, dp, "bufferView", true);
        if (!pr["attributes"].contains("POSITION")) fail_invalid(dp + ": compressed primitive has no POSITION accessor");
        for (auto it = d["attributes"].begin(); it != d["attributes"].end(); ++it) {
          const std::string ap = jsonc::child(dp + "/attributes", it.key());
          if (jsonc::as_int(it.value(), ap) < 0 || it.value().get<int64_t>() > INT32_MAX)
            fail_invalid(ap + ": Draco attribute id " + it.value().dump() + " out of range");
          if (!pr["attributes"].contains(it.key()))
            fail_invalid(ap + ": Draco attribute has no accessor in " + pp + "/attributes");
        }
      }
    }
  }
}

// Which accessors a KHR_draco_mesh_compression primitive decodes into (its indices and the attributes
// its Draco extension lists). Runs after validate_meshes (references are in range).
std::vector<bool> draco_accessors(const json& meshes, size_t n_accessors) {
  std::vector<bool> out(n_accessors, false);
  for (const json& m : meshes)
    for (const json& pr : m["primitives"]) {
      const json* ext = jsonc::find(pr, "extensions");
      const json* d = ext ? jsonc::find(*ext, "KHR_draco_mesh_compression") : nullptr;
      if (!d) continue;
      if (const json* i = jsonc::find(pr, "indices")) out[i->get<size_t>()] = true;
      for (auto it = (*d)["attributes"].begin(); it != (*d)["attributes"].end(); ++it)
        out[pr["attributes"][it.key()].get<size_t>()] = true;
    }
  return out;
}

void validate_views(const json& views, const std::vector<int64_t>& buffer_sizes, const std::vector<bool>& fallback) {
  for (size_t v = 0; v < views.size(); ++v) {
    const json& bv = views[v];
    const std::string ptr = "/bufferViews/" + to_string(v);
    check_ref(bv, "buffer", buffer_sizes.size(), ptr, "buffer", true);
    const uint64_t off = get_u64(bv, "byteOffset", 0, ptr), len = get_u64(bv, "byteLength", 0, ptr);
    if (!bv.contains("byteLength")) fail_invalid(ptr + ": missing required 'byteLength'");
    const int64_t b = bv["buffer"].get<int64_t>();
    if (off + len < off || off + len > uint64_t(buffer_sizes[size_t(b)]))
      fail_invalid(ptr + ": bytes " + to_string(off) + ".." + to_string(off + len) + " overrun buffer " + to_string(b) + " (" +
                   to_string(buffer_sizes[size_t(b)]) + " bytes)");
    if (bv.contains("byteStride")) {
      const uint64_t s = get_u64(bv, "byteStride", 0, ptr);
      if (s < 4 || s > 252 || s % 4) fail_invalid(ptr + "/byteStride: " + to_string(s) + " not a multiple of 4 in 4..252");
    }
    if (bv.contains("extensions") && bv["extensions"].is_object() && bv["extensions"].contains("EXT_meshopt_compression")) {
      const json& e = bv["extensions"]["EXT_meshopt_compression"];
      const std::string ep = ptr + "/extensions/EXT_meshopt_compression";
      if (!e.is_object()) fail_invalid(ep + ": not an object");
      check_ref(e, "buffer", buffer_sizes.size(), ep, "buffer", true);
      const uint64_t eo = jsonc::get_uint(e, "byteOffset", 0, ep), el = jsonc::get_uint(e, "byteLength", ep);
      const uint64_t stride = jsonc::get_uint(e, "byteStride", ep), count = jsonc::get_uint(e, "count", ep);
      const std::string mode = jsonc::get_string(e, "mode", ep);
      if (mode != "ATTRIBUTES" && mode != "TRIANGLES" && mode != "INDICES")
        fail_invalid(ep + "/mode: unknown meshopt mode '" + mode + "'");
      jsonc::get_string(e, "filter", "NONE", ep);
      const int64_t eb = e["buffer"].get<int64_t>();
      if (eo + el < eo || eo + el > uint64_t(buffer_sizes[size_t(eb)]))
        fail_invalid(ep + ": compressed bytes overrun buffer " + to_string(eb));
      if (stride == 0 || stride > 256 || count == 0 || count > (uint64_t(1) << 32) || stride * count != len)
        fail_invalid(ep + ": count " + to_string(count) + " × byteStride " + to_string(stride) + " != byteLength " +
                     to_string(len));
      if (len > kMeshoptMaxExpansion * el)
        fail_invalid(ep + ": meshopt cannot decode " + to_string(len) + " bytes from " + to_string(el) +
                     " compressed bytes (at most " + to_string(kMeshoptMaxExpansion) + "x expansion)");
    } else if (fallback[size_t(bv["buffer"].get<int64_t>())]) {
      fail_invalid(ptr + ": refers to meshopt fallback buffer " + to_string(bv["buffer"].get<int64_t>()) +
                   " but is not EXT_meshopt_compression-compressed (the fallback buffer has no data)");
    }
  }
}

// Node graph: references in range, no cycles, no node with two parents. Iterative (deep chains are fine).
void validate_nodes(const json& root, const json& nodes, size_t n_meshes, size_t n_cameras, size_t n_accessors) {
  std::vector<int64_t> parent(nodes.size(), -1);
  for (size_t i = 0; i < nodes.size(); ++i) {
    const json& n = nodes[i];
    const std::string ptr = "/nodes/" + to_string(i);
    check_ref(n, "mesh", n_meshes, ptr, "mesh", false);
    check_ref(n, "camera", n_cameras, ptr, "camera", false);
    auto check_nums = [&](const char* key, size_t want) {
      if (!n.contains(key)) return;
      if (!n[key].is_array() || n[key].size() != want) fail_invalid(ptr + "/" + key + ": needs " + to_string(want) + " numbers");
      for (const auto& x : n[key])
        if (!x.is_number()) fail_invalid(ptr + "/" + key + ": needs " + to_string(want) + " numbers");
    };
    check_nums("matrix", 16);
    check_nums("translation", 3);
    check_nums("rotation", 4);
    check_nums("scale", 3);
    if (n.contains("children")) {
      if (!n["children"].is_array()) fail_invalid(ptr + "/children: not an array");
      for (size_t k = 0; k < n["children"].size(); ++k) {
        const json& c = n["children"][k];
        const std::string cp = ptr + "/children/" + to_string(k);
        if (!c.is_number_integer() || c.get<int64_t>() < 0 || uint64_t(c.get<int64_t>()) >= nodes.size())
          fail_invalid(cp + ": node " + c.dump() + " out of range (" + to_string(nodes.size()) + " nodes)");
        const int64_t ci = c.get<int64_t>();
        if (ci == int64_t(i)) fail_invalid(cp + ": node cycle: node " + to_string(i) + " is its own child");
        if (parent[size_t(ci)] >= 0)
          fail_invalid(cp + ": node " + to_string(ci) + " already has parent " + to_string(parent[size_t(ci)]) +
                       " (the node hierarchy must be a forest)");
        parent[size_t(ci)] = int64_t(i);
      }
    }
    if (n.contains("extensions") && n["extensions"].is_object() && n["extensions"].contains("EXT_mesh_gpu_instancing")) {
      const json& e = n["extensions"]["EXT_mesh_gpu_instancing"];
      const std::string ep = ptr + "/extensions/EXT_mesh_gpu_instancing";
      if (!e.is_object() || !e.contains("attributes") || !e["attributes"].is_object()) fail_invalid(ep + "/attributes: missing");
      for (auto it = e["attributes"].begin(); it != e["attributes"].end(); ++it)
        check_ref(e["attributes"], it.key().c_str(), n_accessors, ep + "/attributes", "accessor", true);
    }
  }
  // With at most one parent each, a cycle is a loop of parent links with no root: walk up from each node.
  std::vector<uint8_t> state(nodes.size(), 0);  // 0 unknown, 1 on current path, 2 reaches a root
  for (size_t i = 0; i < nodes.size(); ++i) {
    std::vector<size_t> path;
    int64_t cur = int64_t(i);
    while (cur >= 0 && state[size_t(cur)] == 0) {
      state[size_t(cur)] = 1;
      path.push_back(size_t(cur));
      cur = parent[size_t(cur)];
    }
    if (cur >= 0 && state[size_t(cur)] == 1)
      fail_invalid("/nodes/" + to_string(cur) + ": node cycle (node " + to_string(cur) + " is its own ancestor)");
    for (size_t p : path) state[p] = 2;
  }
  for (size_t s = 0; s < array_of(root, "scenes").size(); ++s) {
    const json& sc = root["scenes"][s];
    if (!sc.contains("nodes")) continue;
    if (!sc["nodes"].is_array()) fail_invalid("/scenes/" + to_string(s) + "/nodes: not an array");
    for (size_t k = 0; k < sc["nodes"].size(); ++k) {
      const json& c = sc["nodes"][k];
      if (!c.is_number_integer() || c.get<int64_t>() < 0 || uint64_t(c.get<int64_t>()) >= nodes.size())
        fail_invalid("/scenes/" + to_string(s) + "/nodes/" + to_string(k) + ": node " + c.dump() + " out of range (" +
                     to_string(nodes.size()) + " nodes)");
      if (parent[size_t(c.get<int64_t>())] >= 0)
        fail_invalid("/scenes/" + to_string(s) + "/nodes/" + to_string(k) + ": node " + c.dump() + " is not a root node");
    }
  }
}

void validate_cameras(const json& cameras) {
  for (size_t i = 0; i < cameras.size(); ++i) {
    const json& c = cameras[i];
    const std::string ptr = "/cameras/" + to_string(i);
    const std::string type = jsonc::get_string(c, "type", ptr);
    if (type != "perspective" && type != "orthographic") fail_invalid(ptr + "/type: must be perspective or orthographic");
    if (!c.contains(type) || !c[type].is_object()) fail_invalid(ptr + "/" + type + ": missing");
    // glTF 2.0 §5.12/5.13: the required lens parameters, as numbers.
    const json& lens = c[type];
    const std::string lp = ptr + "/" + type;
    if (type == "perspective") {
      if (!(jsonc::get_number(lens, "yfov", lp) > 0)) fail_invalid(lp + "/yfov: must be > 0");
      jsonc::get_number(lens, "znear", lp);
      jsonc::get_number(lens, "aspectRatio", 0, lp);
      jsonc::get_number(lens, "zfar", 0, lp);
    } else {
      for (const char* k : {"xmag", "ymag", "znear", "zfar"}) jsonc::get_number(lens, k, lp);
    }
  }
}

}  // namespace

void validate_json(const json& root, const std::vector<int64_t>& buffer_sizes) {
  const json& views = array_of(root, "bufferViews");
  const json& accessors = array_of(root, "accessors");
  const json& meshes = array_of(root, "meshes");
  const json& nodes = array_of(root, "nodes");
  const json& cameras = array_of(root, "cameras");
  const json& scenes = array_of(root, "scenes");
  const json& buffers = array_of(root, "buffers");
  // EXT_meshopt_compression fallback buffers hold no data of their own.
  std::vector<bool> fallback(buffer_sizes.size(), false);
  uint64_t backed_bytes = 0;
  for (size_t b = 0; b < buffer_sizes.size() && b < buffers.size(); ++b) {
    const std::string bp = "/buffers/" + to_string(b);
    if (const json* ext = jsonc::find(buffers[b], "extensions"))
      if (const json* e = jsonc::find(jsonc::object(*ext, bp + "/extensions"), "EXT_meshopt_compression"))
        fallback[b] = jsonc::get_bool(*e, "fallback", false, bp + "/extensions/EXT_meshopt_compression");
    if (!fallback[b]) backed_bytes += uint64_t(buffer_sizes[b]);
  }
  validate_views(views, buffer_sizes, fallback);
  validate_meshes(meshes, accessors, views.size());
  validate_accessors(accessors, views, backed_bytes, draco_accessors(meshes, accessors.size()));
  validate_cameras(cameras);
  validate_nodes(root, nodes, meshes.size(), cameras.size(), accessors.size());
  if (root.contains("scene")) check_ref(root, "scene", scenes.size(), "", "scene", false);
}

}  // namespace rtp::gltf
