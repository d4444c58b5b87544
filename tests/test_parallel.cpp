// parallel_for_lowest_error: every index runs, and the lowest failing index's exception is the one
// rethrown, for any thread count.
#include <gtest/gtest.h>

#include <tbb/task_arena.h>

#include <atomic>
#include <stdexcept>
#include <string>

#include "core/parallel.h"

namespace rtp {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

TEST(ParallelForLowestError, TheLowestFailingIndexIsReportedAndEveryIndexRuns) {
  for (int threads : {1, 2}) {
    for (int trial = 0; trial < 50; ++trial) {
      std::atomic<int> ran{0};
      std::string what;
      tbb::task_arena(threads).execute([&] {
        try {
          // 37 and every index from 600 up fail; 600 and later ones usually fail first in time.
          parallel_for_lowest_error(1000, [&](size_t i) {
            ++ran;
            if (i == 37 + size_t(trial) || i >= 600) throw std::runtime_error("index " + std::to_string(i));
          });
        } catch (const std::runtime_error& e) {
          what = e.what();
        }
      });
      EXPECT_EQ(ran.load(), 1000) << threads << " threads";
      EXPECT_EQ(what, "index " + std::to_string(37 + trial)) << threads << " threads";
    }
  }
  int calls = 0;
  EXPECT_NO_THROW(parallel_for_lowest_error(0, [&](size_t) { ++calls; }));
  EXPECT_EQ(calls, 0);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp
