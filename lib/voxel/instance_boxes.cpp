// Instance boxes as a culling proxy (SPEC §4.5, 7.0): a point's instance BVH with its boxes rounded
// outward to 8 bits per plane relative to each node (after the quantized child boxes of Ylitie et al.
// 2017 §3, "Efficient incoherent ray traversal on GPUs through compressed wide BVHs").
#include "voxel/instance_boxes.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/math.h"

namespace rtp::voxel {
namespace {

float scale_up(double v) {  // the float nearest above v
  float f = float(v);
  if (double(f) < v) f = float_up(f);
  return f;
}

}  // namespace

template <int W>
bool quantize_instance_bvh(const std::vector<fmt::WideNode<W>>& nodes, std::vector<fmt::CullNode<W>>& out) {
  const size_t first = out.size();
  for (const fmt::WideNode<W>& n : nodes) {
    fmt::CullNode<W> c{};
    for (int l = 0; l < W; ++l) c.child[l] = n.child[l];
    for (int k = 0; k < 3; ++k) {
      float lo = std::numeric_limits<float>::infinity(), hi = -lo;
      for (int l = 0; l < W; ++l) {
        if (fmt::ChildRef::is_empty(n.child[l])) continue;
        if (!std::isfinite(n.lo[k][l]) || !std::isfinite(n.hi[k][l])) {
          out.resize(first);
          return false;
        }
        lo = std::min(lo, n.lo[k][l]), hi = std::max(hi, n.hi[k][l]);
      }
      if (!(lo <= hi)) lo = hi = 0;  // no filled lane
      // The smallest float scale whose 255 steps from lo reach hi, as cull_plane decodes them.
      float scale = scale_up((double(hi) - double(lo)) / 255.0);
      while (fmt::cull_plane(lo, scale, 255) < double(hi)) scale = float_up(scale);
      if (!std::isfinite(scale)) {
        out.resize(first);
        return false;
      }
      c.origin[k] = lo, c.scale[k] = scale;
      for (int l = 0; l < W; ++l) {
        if (fmt::ChildRef::is_empty(n.child[l])) continue;
        const double a = double(n.lo[k][l]), b = double(n.hi[k][l]);
        int qa = 0, qb = 255;
        if (scale > 0) {
          qa = int(std::clamp(std::floor((a - double(lo)) / double(scale)), 0.0, 255.0));
          qb = int(std::clamp(std::ceil((b - double(lo)) / double(scale)), 0.0, 255.0));
        }
        while (qa > 0 && fmt::cull_plane(lo, scale, uint8_t(qa)) > a) --qa;    // division rounding: the decoded
        while (qb < 255 && fmt::cull_plane(lo, scale, uint8_t(qb)) < b) ++qb;  // planes must contain the box
        c.lo[k][l] = uint8_t(qa), c.hi[k][l] = uint8_t(qb);
      }
    }
    out.push_back(c);
  }
  return true;
}

template bool quantize_instance_bvh<4>(const std::vector<fmt::WideNode<4>>&, std::vector<fmt::CullNode<4>>&);
template bool quantize_instance_bvh<8>(const std::vector<fmt::WideNode<8>>&, std::vector<fmt::CullNode<8>>&);
template bool quantize_instance_bvh<16>(const std::vector<fmt::WideNode<16>>&, std::vector<fmt::CullNode<16>>&);

}  // namespace rtp::voxel
