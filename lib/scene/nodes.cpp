// Node hierarchy -> instances and cameras. Transforms are composed in double and stored as float.
#include <cfloat>
#include <cmath>
#include <cstdio>

#include <tbb/parallel_for.h>

#include <atomic>

#include "core/error.h"
#include "scene/gltf_internal.h"

namespace rtp::gltf {
namespace {

using std::to_string;

Mat4d local_matrix(const tinygltf::Node& n) {
  if (n.matrix.size() == 16) return Mat4d::from_column_major(n.matrix.data());
  double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
  for (size_t i = 0; i < 3 && i < n.translation.size(); ++i) t[i] = n.translation[i];
  for (size_t i = 0; i < 3 && i < n.scale.size(); ++i) s[i] = n.scale[i];
  if (n.rotation.size() == 4) {
    const double len = std::sqrt(n.rotation[0] * n.rotation[0] + n.rotation[1] * n.rotation[1] + n.rotation[2] * n.rotation[2] +
                                 n.rotation[3] * n.rotation[3]);
    if (len > 0)
      for (int i = 0; i < 4; ++i) q[i] = n.rotation[size_t(i)] / len;
  }
  return Mat4d::from_trs(t, q, s);
}

// Camera world transform with scale stripped: Gram-Schmidt on the rotation columns.
Affine3x4 strip_scale(const Mat4d& g, bool& degenerate) {
  Vec3d c[3];
  for (int k = 0; k < 3; ++k) c[k] = {g(0, k), g(1, k), g(2, k)};
  degenerate = false;
  auto norm = [&](Vec3d v) {
    const double l = length(v);
    if (!(l > 1e-300) || !std::isfinite(l)) {
      degenerate = true;
      return v;
    }
    return v * (1.0 / l);
  };
  c[0] = norm(c[0]);
  c[1] = norm(c[1] - c[0] * dot(c[0], c[1]));
  Vec3d z = cross(c[0], c[1]);
  c[2] = dot(z, c[2]) < 0 ? z * -1.0 : z;  // keep the handedness the file gave
  Mat4d r = g;
  for (int k = 0; k < 3; ++k)
    for (int row = 0; row < 3; ++row) r(row, k) = degenerate ? (row == k ? 1.0 : 0.0) : c[k][row];
  return Affine3x4::from(r);
}

void add_camera(const Document& doc, int node, const Mat4d& global, Scene& out) {
  const tinygltf::Node& n = doc.model.nodes[size_t(node)];
  const tinygltf::Camera& gc = doc.model.cameras[size_t(n.camera)];
  Camera cam;
  cam.name = gc.name.empty() ? (n.name.empty() ? "camera" + to_string(n.camera) : n.name) : gc.name;
  cam.node = uint32_t(node);
  cam.gltf_camera = uint32_t(n.camera);
  if (gc.type == "orthographic") {
    cam.type = Camera::Type::kOrthographic;
    cam.xmag = gc.orthographic.xmag;
    cam.ymag = gc.orthographic.ymag;
    cam.znear = gc.orthographic.znear;
    cam.zfar = gc.orthographic.zfar;
  } else {
    cam.yfov = gc.perspective.yfov;
    cam.aspect_ratio = gc.perspective.aspectRatio;
    cam.znear = gc.perspective.znear;
    cam.zfar = gc.perspective.zfar;
  }
  bool degenerate = false;
  cam.world = strip_scale(global, degenerate);
  if (degenerate) out.warnings.push_back("/nodes/" + to_string(node) + ": camera transform is degenerate, rotation reset");
  out.cameras.push_back(cam);
}

// The JSON pointer of the property that defines node `node`'s local transform.
std::string transform_pointer(const Document& doc, int node) {
  std::string np = "/nodes/" + to_string(node);
  const tinygltf::Node& n = doc.model.nodes[size_t(node)];
  if (n.matrix.size() == 16) return np + "/matrix";
  if (!n.scale.empty()) return np + "/scale";
  if (!n.translation.empty()) return np + "/translation";
  return np;
}

// World transforms are stored as float: every entry must be finite there too (a matrix entry of
// 1e39 is a finite double but an infinite float), or the node is rejected by its pointer.
// `gpu_instance`: the index within the node's EXT_mesh_gpu_instancing, or kNoIndex for the node's own
// transform (the message is built only on failure: per instance it was a heap string each).
void check_float_range(const Document& doc, int node, const Mat4d& world, uint64_t gpu_instance = kNoIndex) {
  for (double v : world.m)
    if (!std::isfinite(v) || std::abs(v) > double(FLT_MAX)) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.3g", v);
      const std::string what = gpu_instance == kNoIndex
                                   ? std::string("world transform")
                                   : "world transform of EXT_mesh_gpu_instancing instance " + to_string(gpu_instance);
      fail_invalid(transform_pointer(doc, node) + ": " + what + " is not finite in float (entry " + buf + ")");
    }
}

Instance make_instance(uint32_t gltf_mesh, const Mat4d& world, int node, uint32_t gpu_instance) {
  Instance inst;
  inst.mesh = gltf_mesh;
  inst.transform = Affine3x4::from(world);
  inst.mirrored = world.det3() < 0;
  inst.node = uint32_t(node);
  inst.gpu_instance = gpu_instance;
  return inst;
}

void add_instance(Scene& out, uint32_t gltf_mesh, const Mat4d& world, int node, uint32_t gpu_instance) {
  out.instances.push_back(make_instance(gltf_mesh, world, node, gpu_instance));
}

// The instance count an EXT_mesh_gpu_instancing node declares (its first attribute's accessor count; 0
// when it has none): only a capacity hint, add_gpu_instances checks the attributes.
size_t gpu_instance_count(const Document& doc, int node) {
  const nlohmann::json& attrs = doc.json["nodes"][size_t(node)]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"];
  for (const char* name : {"TRANSLATION", "ROTATION", "SCALE"}) {
    if (!attrs.contains(name) || !attrs[name].is_number_integer()) continue;
    const int64_t a = attrs[name].get<int64_t>();
    if (a >= 0 && size_t(a) < doc.model.accessors.size()) return doc.model.accessors[size_t(a)].count;
  }
  return 0;
}

// EXT_mesh_gpu_instancing: per-instance TRS, applied before the node's global transform. The instances
// are composed in parallel into their final places (one by one with push_back they were 8 % of a
// 10^6-instance convert, mostly the vector's regrowth); a bad instance is reported as the serial loop
// would: the lowest-numbered one, recomputed alone so that its own message is thrown.
void add_gpu_instances(const Document& doc, int node, const Mat4d& global, Scene& out) {
  const nlohmann::json& attrs = doc.json["nodes"][size_t(node)]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"];
  const std::string ep = "/nodes/" + to_string(node) + "/extensions/EXT_mesh_gpu_instancing/attributes";
  std::vector<double> t, r, s;
  size_t count = 0;
  bool have_count = false;
  auto read = [&](const char* name, int comps, std::vector<double>& dst) {
    if (!attrs.contains(name)) return;
    dst = read_components(doc.model, attrs[name].get<int>(), comps, ep + "/" + name);
    const size_t c = dst.size() / size_t(comps);
    if (have_count && c != count)
      fail_invalid(ep + "/" + name + ": count " + to_string(c) + " differs from the other attributes (" + to_string(count) + ")");
    count = c;
    have_count = true;
  };
  read("TRANSLATION", 3, t);
  read("ROTATION", 4, r);
  read("SCALE", 3, s);
  const uint32_t mesh = uint32_t(doc.model.nodes[size_t(node)].mesh);
  auto instance = [&](size_t i) {
    double ti[3] = {0, 0, 0}, qi[4] = {0, 0, 0, 1}, si[3] = {1, 1, 1};
    if (!t.empty())
      for (int k = 0; k < 3; ++k) ti[k] = t[3 * i + size_t(k)];
    if (!s.empty())
      for (int k = 0; k < 3; ++k) si[k] = s[3 * i + size_t(k)];
    if (!r.empty()) {
      double len = 0;
      for (int k = 0; k < 4; ++k) len += r[4 * i + size_t(k)] * r[4 * i + size_t(k)];
      len = std::sqrt(len);
      if (len > 0)
        for (int k = 0; k < 4; ++k) qi[k] = r[4 * i + size_t(k)] / len;
    }
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(ti[k]) || !std::isfinite(si[k]))
        fail_invalid(ep + ": instance " + to_string(i) + " has a non-finite TRANSLATION/SCALE");
    const Mat4d world = global * Mat4d::from_trs(ti, qi, si);
    check_float_range(doc, node, world, i);
    return make_instance(mesh, world, node, uint32_t(i));
  };
  const size_t base = out.instances.size();
  out.instances.resize(base + count);
  std::atomic<size_t> first_bad{count};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 4096), [&](const tbb::blocked_range<size_t>& range) {
    for (size_t i = range.begin(); i < range.end(); ++i) {
      try {
        out.instances[base + i] = instance(i);
      } catch (const Error&) {
        size_t seen = first_bad.load();
        while (i < seen && !first_bad.compare_exchange_weak(seen, i)) {}
        return;
      }
    }
  });
  if (first_bad.load() < count) {
    out.instances.resize(base);
    instance(first_bad.load());                                                       // throws its message
    fail_invalid(ep + ": instance " + to_string(first_bad.load()) + " was refused");  // not reached
  }
}

}  // namespace

void walk_nodes(const Document& doc, int scene, Scene& out) {
  const tinygltf::Model& m = doc.model;
  std::vector<int> roots;
  if (scene >= 0) {
    roots = m.scenes[size_t(scene)].nodes;
  } else {
    std::vector<bool> is_child(m.nodes.size(), false);
    for (const auto& n : m.nodes)
      for (int c : n.children) is_child[size_t(c)] = true;
    for (size_t i = 0; i < m.nodes.size(); ++i)
      if (!is_child[i]) roots.push_back(int(i));
  }
  // Iterative pre-order walk (validate_json guarantees a forest, so this terminates): the visited nodes
  // with their world transforms first, so that the instances can be counted and allocated once (grown
  // node by node, a 10^6-instance forest reallocated and re-faulted its 120 MB six times).
  struct Item {
    int node;
    Mat4d parent;
  };
  struct Visit {
    int node;
    Mat4d global;
    bool gpu;
  };
  std::vector<Item> stack;
  std::vector<Visit> visits;
  size_t instance_count = 0;
  for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.push_back({*it, Mat4d::identity()});
  while (!stack.empty()) {
    const Item item = stack.back();
    stack.pop_back();
    const tinygltf::Node& n = m.nodes[size_t(item.node)];
    const Mat4d global = item.parent * local_matrix(n);
    for (double v : global.m)
      if (!std::isfinite(v)) fail_invalid("/nodes/" + to_string(item.node) + ": transform is not finite");
    check_float_range(doc, item.node, global);
    const nlohmann::json& jn = doc.json["nodes"][size_t(item.node)];
    const bool gpu = jn.contains("extensions") && jn["extensions"].contains("EXT_mesh_gpu_instancing");
    if (n.mesh >= 0 || n.camera >= 0) visits.push_back({item.node, global, gpu});
    if (n.mesh >= 0) instance_count += gpu ? gpu_instance_count(doc, item.node) : 1;
    for (auto it = n.children.rbegin(); it != n.children.rend(); ++it) stack.push_back({*it, global});
  }
  out.instances.reserve(out.instances.size() + instance_count);
  for (const Visit& v : visits) {
    const tinygltf::Node& n = m.nodes[size_t(v.node)];
    if (n.mesh >= 0) {
      if (v.gpu)
        add_gpu_instances(doc, v.node, v.global, out);
      else
        add_instance(out, uint32_t(n.mesh), v.global, v.node, kNoIndex);
    }
    if (n.camera >= 0) add_camera(doc, v.node, v.global, out);
  }
}

}  // namespace rtp::gltf
