// Primary rays through an image from a package's camera (glTF 2.0 §3.10: cameras look down -z of their
// node, +y up; perspective yfov is vertical, orthographic xmag/ymag are half-extents).
#include "reader/camera.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/json_checked.h"
#include "layout/chunk_io.h"
#include "reader/metadata.h"

namespace rtp {

namespace {

struct Metadata {
  nlohmann::json cameras = nlohmann::json::array();
  std::string label;  // the metadata chunk, for messages
};

Metadata read_cameras(const PackageReader& r) {
  Metadata md;
  const nlohmann::json meta = read_metadata(r, &md.label);
  if (const nlohmann::json* cams = jsonc::find(meta, "cameras")) {
    if (!cams->is_array()) fail_invalid(md.label + ": /cameras: not an array");
    md.cameras = *cams;
  }
  return md;
}

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

}  // namespace

size_t camera_count(const PackageReader& reader) { return read_cameras(reader).cameras.size(); }

void check_camera_world(const double m[12], const std::string& pointer) {
  char v[32];
  for (int i = 0; i < 12; ++i)
    if (!(std::fabs(m[i]) <= 1e30)) {  // also NaN
      std::snprintf(v, sizeof v, "%g", m[i]);
      fail_invalid(pointer + "/" + std::to_string(i) + ": " + v + " is not a finite coordinate of float range");
    }
  const double det =
      m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) + m[2] * (m[4] * m[9] - m[5] * m[8]);
  if (!(std::fabs(std::fabs(det) - 1) <= 1e-3)) {
    std::snprintf(v, sizeof v, "%g", det);
    fail_invalid(pointer + ": the 3x3 part has determinant " + v + ", not a rotation (+-1)");
  }
}

CameraRays camera_rays(const PackageReader& reader, int w, int h, int camera) {
  const Metadata md = read_cameras(reader);
  const size_t n = md.cameras.size();
  if (camera >= 0 && size_t(camera) >= n)
    throw Error(ExitCode::kUsage, "camera " + std::to_string(camera) + ": the package has " + std::to_string(n) +
                                      (n == 1   ? " camera (0)"
                                       : n == 0 ? " cameras (leave out --camera for an automatic one)"
                                                : " cameras (0 to " + std::to_string(n - 1) + ")"));
  CameraRays out;
  double m[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};  // camera -> world, row-major 3x4
  double yfov = 0.785398, ymag = 0;
  bool ortho = false;
  const double aspect = double(w) / h;
  if (n > 0) {
    const size_t ci = camera < 0 ? 0 : size_t(camera);
    const nlohmann::json& cam = md.cameras[ci];
    const std::string cp = md.label + ": /cameras/" + std::to_string(ci);
    if (!cam.is_object()) fail_invalid(cp + ": not an object");
    const std::string type = jsonc::get_string(cam, "type", cp);
    if (type != "perspective" && type != "orthographic")
      fail_invalid(cp + "/type: '" + type + "' is neither perspective nor orthographic");
    const nlohmann::json& world = jsonc::member(cam, "world", cp);
    if (!world.is_array() || world.size() != 12) fail_invalid(cp + "/world: needs 12 numbers");
    for (size_t i = 0; i < 12; ++i) m[i] = jsonc::as_number(world[i], cp + "/world/" + std::to_string(i));
    check_camera_world(m, cp + "/world");
    ortho = type == "orthographic";
    std::string name = cam.contains("name") && cam["name"].is_string() ? cam["name"].get<std::string>() : "";
    out.description = "camera " + std::to_string(ci) + (name.empty() ? "" : " '" + name + "'") + " (" + type;
    if (ortho) {
      // glTF 2.0 §5.13: ymag MUST NOT be zero and SHOULD NOT be negative; a negative one is taken by its size.
      ymag = std::fabs(jsonc::get_number(cam, "ymag", cp));
      if (!(ymag > 0) || !std::isfinite(ymag)) fail_invalid(cp + "/ymag: " + std::to_string(ymag) + " is zero or not finite");
      out.description += ", ymag " + fixed(ymag, 3) + ")";
    } else {
      yfov = jsonc::get_number(cam, "yfov", cp);
      if (!(yfov > 0) || !(yfov < 3.141592653589793)) fail_invalid(cp + "/yfov: " + std::to_string(yfov) + " is not in (0, pi)");
      out.description += ", yfov " + fixed(yfov * 180 / 3.141592653589793, 1) + " deg)";
    }
  } else {
    const auto& hd = reader.header();
    double c[3], ext = 0;
    for (int k = 0; k < 3; ++k) {
      c[k] = 0.5 * (double(hd.bounds_lo[k]) + hd.bounds_hi[k]);
      ext = std::max(ext, double(hd.bounds_hi[k]) - hd.bounds_lo[k]);
    }
    m[3] = c[0];
    m[7] = c[1];
    m[11] = c[2] + 1.5 * ext + 1e-3;
    out.description = "automatic camera (from +z, yfov 45.0 deg, framing the package bounds)";
  }
  out.rays.reserve(size_t(w) * size_t(h));
  const double t = std::tan(yfov / 2);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      // Pixel centre in [-1, 1]^2, +y up.
      const double sx = 2 * (x + 0.5) / w - 1, sy = 1 - 2 * (y + 0.5) / h;
      const double d[3] = {ortho ? 0 : sx * t * aspect, ortho ? 0 : sy * t, -1};  // camera looks down -z
      const double o[3] = {ortho ? sx * ymag * aspect : 0, ortho ? sy * ymag : 0, 0};
      fmt::Ray ray{};
      for (int k = 0; k < 3; ++k) {
        ray.org[k] = float(m[4 * k] * o[0] + m[4 * k + 1] * o[1] + m[4 * k + 2] * o[2] + m[4 * k + 3]);
        ray.dir[k] = float(m[4 * k] * d[0] + m[4 * k + 1] * d[1] + m[4 * k + 2] * d[2]);
      }
      ray.tnear = 0;
      ray.tfar = std::numeric_limits<float>::infinity();
      out.rays.push_back(ray);
    }
  return out;
}

}  // namespace rtp
