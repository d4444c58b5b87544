#pragma once
// The random source of the lib/voxel unit tests (test_voxel.cpp, test_voxel_dag.cpp, test_voxel_spans.cpp).
#include "test_rng.h"

namespace rtp::test {

using Rng = SplitMix64<12345, double>;

}  // namespace rtp::test
