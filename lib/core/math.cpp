#include "core/math.h"

namespace rtp {

Mat4d Mat4d::from_trs(const double t[3], const double q[4], const double s[3]) {
  const double x = q[0], y = q[1], z = q[2], w = q[3];
  Mat4d m;
  m(0, 0) = (1 - 2 * (y * y + z * z)) * s[0];
  m(0, 1) = (2 * (x * y - z * w)) * s[1];
  m(0, 2) = (2 * (x * z + y * w)) * s[2];
  m(1, 0) = (2 * (x * y + z * w)) * s[0];
  m(1, 1) = (1 - 2 * (x * x + z * z)) * s[1];
  m(1, 2) = (2 * (y * z - x * w)) * s[2];
  m(2, 0) = (2 * (x * z - y * w)) * s[0];
  m(2, 1) = (2 * (y * z + x * w)) * s[1];
  m(2, 2) = (1 - 2 * (x * x + y * y)) * s[2];
  m(0, 3) = t[0];
  m(1, 3) = t[1];
  m(2, 3) = t[2];
  return m;
}

Mat4d operator*(const Mat4d& a, const Mat4d& b) {
  Mat4d o;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) {
      double s = 0;
      for (int k = 0; k < 4; ++k) s += a(r, k) * b(k, c);
      o(r, c) = s;
    }
  return o;
}

double Affine3x4::max_scale() const {
  // Spectral norm of the 3x3 part = sqrt(largest eigenvalue of A^T A), by power iteration in double.
  double ata[3][3];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double s = 0;
      for (int k = 0; k < 3; ++k) s += double((*this)(k, i)) * double((*this)(k, j));
      ata[i][j] = s;
    }
  double v[3] = {1, 0.7548776662, 0.5698402910};  // generic start vector
  double lambda = 0;
  for (int it = 0; it < 64; ++it) {
    double w[3];
    for (int i = 0; i < 3; ++i) w[i] = ata[i][0] * v[0] + ata[i][1] * v[1] + ata[i][2] * v[2];
    double n = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    if (n == 0) return 0;
    for (int i = 0; i < 3; ++i) v[i] = w[i] / n;
    if (std::abs(n - lambda) <= 1e-15 * n) {
      lambda = n;
      break;
    }
    lambda = n;
  }
  return std::sqrt(lambda);
}

}  // namespace rtp
