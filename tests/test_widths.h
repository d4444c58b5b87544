#pragma once
// The (W, B) pairs every BVH and trace test runs: node width W and leaf block width B as the converter
// builds them (4/4, 8/8, 16/16, 8/4, 16/8; rtp::supported_widths), for typed tests and for loops.
#include <gtest/gtest.h>

namespace rtp::test {

template <int W_, int B_>
struct WB {
  static constexpr int W = W_, B = B_;
};
using AllWidths = ::testing::Types<WB<4, 4>, WB<8, 8>, WB<16, 16>, WB<8, 4>, WB<16, 8>>;

// Calls f.template operator()<W, B>() for every pair.
template <class F>
void for_each_config(F&& f) {
  f.template operator()<4, 4>();
  f.template operator()<8, 8>();
  f.template operator()<16, 16>();
  f.template operator()<8, 4>();
  f.template operator()<16, 8>();
}

}  // namespace rtp::test
