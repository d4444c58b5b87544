// Shading primary-ray hits into an image (rtpack-trace --image): normal, depth or instance colours.
#include <algorithm>
#include <cmath>
#include <limits>

#include "image/image.h"

namespace rtp::image {

namespace {

struct V3 {
  double x = 0, y = 0, z = 0;
};
V3 sub(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
V3 cross(V3 a, V3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
double dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
double len(V3 a) { return std::sqrt(dot(a, a)); }

bool is_hit(const fmt::Hit& h) { return h.instance != fmt::Hit::kNone && std::isfinite(h.t); }

V3 position(const fmt::Ray& r, const fmt::Hit& h) {
  return {double(r.org[0]) + double(h.t) * r.dir[0], double(r.org[1]) + double(h.t) * r.dir[1],
          double(r.org[2]) + double(h.t) * r.dir[2]};
}

uint8_t to_byte(double v) { return uint8_t(std::lround(std::clamp(v, 0.0, 1.0) * 255.0)); }

// The surface normal at pixel (x, y) from the hit positions of its neighbours on the same instance
// (screen-space differences: forward or backward along each axis, whichever neighbour is nearer in
// depth), facing the ray; -dir when no neighbour qualifies (isolated pixels, silhouettes).
V3 estimated_normal(const fmt::Ray* rays, const fmt::Hit* hits, int w, int h, int x, int y) {
  const size_t i = size_t(y) * w + x;
  const V3 p = position(rays[i], hits[i]);
  const V3 d = {rays[i].dir[0], rays[i].dir[1], rays[i].dir[2]};
  auto tangent = [&](int dx, int dy, V3* out) {
    double best = std::numeric_limits<double>::infinity();
    bool found = false;
    for (int s : {1, -1}) {
      const int nx = x + s * dx, ny = y + s * dy;
      if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
      const size_t j = size_t(ny) * w + nx;
      if (!is_hit(hits[j]) || hits[j].instance != hits[i].instance) continue;
      const double dt = std::abs(double(hits[j].t) - hits[i].t);
      if (dt < best) {
        best = dt;
        const V3 q = position(rays[j], hits[j]);
        *out = s > 0 ? sub(q, p) : sub(p, q);
        found = true;
      }
    }
    return found;
  };
  V3 tx, ty;
  if (tangent(1, 0, &tx) && tangent(0, 1, &ty)) {
    V3 n = cross(ty, tx);
    const double l = len(n);
    if (l > 0 && std::isfinite(l)) {
      n = {n.x / l, n.y / l, n.z / l};
      return dot(n, d) > 0 ? V3{-n.x, -n.y, -n.z} : n;
    }
  }
  const double l = len(d);
  return l > 0 ? V3{-d.x / l, -d.y / l, -d.z / l} : V3{0, 0, 1};
}

}  // namespace

bool parse_shade(const std::string& name, Shade* out) {
  if (name == "normal")
    *out = Shade::kNormal;
  else if (name == "depth")
    *out = Shade::kDepth;
  else if (name == "instance")
    *out = Shade::kInstance;
  else
    return false;
  return true;
}

std::array<uint8_t, 3> instance_color(uint32_t instance) {
  // A hash spread over hue, at full saturation and value 0.95 (never near the dark background).
  uint32_t x = instance * 0x9E3779B1u;
  x ^= x >> 15;
  x *= 0x85EBCA77u;
  x ^= x >> 13;
  const double hue = double(x % 3600) / 600.0;  // [0, 6)
  const int sector = int(hue);
  const double f = hue - sector, v = 0.95, lo = 0.25 * v, rise = lo + (v - lo) * f, fall = v - (v - lo) * f;
  double r = v, g = v, b = v;
  switch (sector) {
    case 0: r = v, g = rise, b = lo; break;
    case 1: r = fall, g = v, b = lo; break;
    case 2: r = lo, g = v, b = rise; break;
    case 3: r = lo, g = fall, b = v; break;
    case 4: r = rise, g = lo, b = v; break;
    default: r = v, g = lo, b = fall; break;
  }
  return {to_byte(r), to_byte(g), to_byte(b)};
}

Rgb8 shade(const fmt::Ray* rays, const fmt::Hit* hits, int w, int h, Shade mode, const fmt::Shading* shading) {
  Rgb8 img;
  img.width = w;
  img.height = h;
  const size_t n = size_t(w) * size_t(h);
  img.rgb.resize(n * 3);
  double tmin = std::numeric_limits<double>::infinity(), tmax = -tmin;
  for (size_t i = 0; i < n; ++i)
    if (is_hit(hits[i])) {
      tmin = std::min(tmin, double(hits[i].t));
      tmax = std::max(tmax, double(hits[i].t));
    }
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t i = size_t(y) * w + x;
      uint8_t* px = &img.rgb[i * 3];
      if (!is_hit(hits[i])) {
        std::copy(kBackground.begin(), kBackground.end(), px);
        continue;
      }
      if (mode == Shade::kDepth) {
        // Near bright (1.0), far dim (0.2); one hit distance alone is bright.
        const double s = tmax > tmin ? (double(hits[i].t) - tmin) / (tmax - tmin) : 0.0;
        px[0] = px[1] = px[2] = to_byte(1.0 - 0.8 * s);
        continue;
      }
      V3 nrm;
      const V3 d = {rays[i].dir[0], rays[i].dir[1], rays[i].dir[2]};
      if (shading && len({shading[i].normal[0], shading[i].normal[1], shading[i].normal[2]}) > 0) {
        nrm = {shading[i].normal[0], shading[i].normal[1], shading[i].normal[2]};
        const double l = len(nrm);
        nrm = {nrm.x / l, nrm.y / l, nrm.z / l};
      } else {
        nrm = estimated_normal(rays, hits, w, h, x, y);
      }
      if (mode == Shade::kNormal) {
        px[0] = to_byte(0.5 * (nrm.x + 1));
        px[1] = to_byte(0.5 * (nrm.y + 1));
        px[2] = to_byte(0.5 * (nrm.z + 1));
      } else {
        // Instance colour times a headlight term |cos| between the normal and the ray, in [0.3, 1].
        const double dl = len(d), c = dl > 0 ? std::abs(dot(nrm, d)) / dl : 1.0;
        const double k = 0.3 + 0.7 * std::clamp(c, 0.0, 1.0);
        const auto col = instance_color(hits[i].instance);
        for (int c3 = 0; c3 < 3; ++c3) px[c3] = uint8_t(std::lround(col[size_t(c3)] * k));
      }
    }
  return img;
}

}  // namespace rtp::image
