#pragma once
// Small math types: float storage, double composition.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

namespace rtp {

inline constexpr float kInf = std::numeric_limits<float>::infinity();

struct Vec3f {
  float x = 0, y = 0, z = 0;
  float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  float& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
  bool operator==(const Vec3f&) const = default;
};

struct Vec2f {
  float x = 0, y = 0;
  bool operator==(const Vec2f&) const = default;
};

struct Vec3d {
  double x = 0, y = 0, z = 0;
  double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  double& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
};

// std::nextafter(v, -inf) and std::nextafter(v, +inf) for floats, by their bits (no libm call: one per
// box plane of 10^6 instances was 1 % of a forest's convert). NaN stays NaN, an infinity towards
// itself stays, zero steps to the smallest denormal.
inline float float_down(float v) {
  if (!(v == v) || v == -std::numeric_limits<float>::infinity()) return v;
  if (v == 0) return -std::numeric_limits<float>::denorm_min();
  const uint32_t u = std::bit_cast<uint32_t>(v);
  return std::bit_cast<float>(v > 0 ? u - 1 : u + 1);
}
inline float float_up(float v) { return -float_down(-v); }

inline Vec3d to_d(const Vec3f& v) { return {v.x, v.y, v.z}; }
inline Vec3d operator-(const Vec3d& a, const Vec3d& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3d operator+(const Vec3d& a, const Vec3d& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3d operator*(const Vec3d& a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline double dot(const Vec3d& a, const Vec3d& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3d cross(const Vec3d& a, const Vec3d& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(const Vec3d& a) { return std::sqrt(dot(a, a)); }

inline bool is_finite(const Vec3f& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Axis-aligned box in double (bounds are accumulated in double, stored as float outward-rounded).
struct Aabb {
  Vec3d lo{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
           std::numeric_limits<double>::infinity()};
  Vec3d hi{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
           -std::numeric_limits<double>::infinity()};
  bool empty() const { return !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z); }
  void grow(const Vec3d& p) {
    for (int i = 0; i < 3; ++i) {
      lo[i] = std::min(lo[i], p[i]);
      hi[i] = std::max(hi[i], p[i]);
    }
  }
  void grow(const Aabb& b) {
    if (b.empty()) return;
    grow(b.lo);
    grow(b.hi);
  }
  Vec3d center() const { return (lo + hi) * 0.5; }
  Vec3d extent() const { return hi - lo; }
  double surface_area() const {
    if (empty()) return 0;
    Vec3d e = extent();
    return 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
  }
};

// Row-major 4x4 in double, used to compose node hierarchies exactly before storing.
struct Mat4d {
  std::array<double, 16> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  double& operator()(int r, int c) { return m[r * 4 + c]; }
  double operator()(int r, int c) const { return m[r * 4 + c]; }
  static Mat4d identity() { return {}; }
  // From a glTF column-major 16-element matrix.
  static Mat4d from_column_major(const double* v) {
    Mat4d out;
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) out(r, c) = v[c * 4 + r];
    return out;
  }
  // T * R * S as glTF defines it; q = (x, y, z, w).
  static Mat4d from_trs(const double t[3], const double q[4], const double s[3]);
  double det3() const {
    const Mat4d& a = *this;
    return a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) - a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0)) +
           a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0));
  }
};

Mat4d operator*(const Mat4d& a, const Mat4d& b);

// The determinant of a row-major float 3x3 (an instance record's L^-1), in double.
inline double det3_of(const float m[9]) {
  const double a = m[0], b = m[1], c = m[2], d = m[3], e = m[4], f = m[5], g = m[6], h = m[7], i = m[8];
  return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
}

// The inverse of a row-major float 3x3 (an instance record's L^-1: L, the local->world linear part) as
// adj / det in double; false when the matrix is singular or not finite.
inline bool inverse3_of(const float li[9], double out[9]) {
  const double det = det3_of(li);
  if (!(det != 0) || !std::isfinite(det)) return false;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      const int r1 = (c + 1) % 3, r2 = (c + 2) % 3, c1 = (r + 1) % 3, c2 = (r + 2) % 3;
      out[3 * r + c] = (double(li[3 * r1 + c1]) * li[3 * r2 + c2] - double(li[3 * r1 + c2]) * li[3 * r2 + c1]) / det;
    }
  return true;
}

// Affine 3x4 (row-major, last column = translation), double storage: the instance transform as the
// glTF node hierarchy composes it (a translation of 3000000.3 stays 3000000.3; SPEC §2.4 keeps it so).
struct Affine3x4 {
  std::array<double, 12> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
  double operator()(int r, int c) const { return m[r * 4 + c]; }
  double& operator()(int r, int c) { return m[r * 4 + c]; }
  static Affine3x4 from(const Mat4d& a) {
    Affine3x4 out;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) out(r, c) = a(r, c);
    return out;
  }
  // The transform rounded to float, row-major 3x4 (what Embree is given).
  std::array<float, 12> to_float() const {
    std::array<float, 12> f;
    for (size_t i = 0; i < 12; ++i) f[i] = static_cast<float>(m[i]);
    return f;
  }
  // Applies the transform in double.
  Vec3d apply(const Vec3d& p) const {
    Vec3d o;
    for (int r = 0; r < 3; ++r)
      o[r] = double((*this)(r, 0)) * p.x + double((*this)(r, 1)) * p.y + double((*this)(r, 2)) * p.z + double((*this)(r, 3));
    return o;
  }
  double det3() const {
    const Affine3x4& a = *this;
    return double(a(0, 0)) * (double(a(1, 1)) * a(2, 2) - double(a(1, 2)) * a(2, 1)) -
           double(a(0, 1)) * (double(a(1, 0)) * a(2, 2) - double(a(1, 2)) * a(2, 0)) +
           double(a(0, 2)) * (double(a(1, 0)) * a(2, 1) - double(a(1, 1)) * a(2, 0));
  }
  // Largest factor by which this transform stretches any length (spectral norm bound: max column norm
  // is a lower bound, Frobenius an upper bound; we use the exact 3x3 spectral norm via power iteration).
  double max_scale() const;
};

}  // namespace rtp
