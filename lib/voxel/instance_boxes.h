#pragma once
// The instance-box culling proxy of an instance-heavy batching point (formats/dag.h kDagBoxes, SPEC
// §4.5, version 7.0): its instance BVH node for node, every box rounded outward to 8 bits per plane.
#include <vector>

#include "formats/bvh_layout.h"
#include "formats/dag.h"

namespace rtp::voxel {

// Appends one CullNode per WideNode (same order, same child references) whose decoded boxes contain
// the nodes' boxes. False, and nothing appended, when a filled lane's box is not finite.
template <int W>
bool quantize_instance_bvh(const std::vector<fmt::WideNode<W>>& nodes, std::vector<fmt::CullNode<W>>& out);

}  // namespace rtp::voxel
