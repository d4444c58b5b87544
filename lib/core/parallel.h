#pragma once
// tbb::parallel_for over indices whose failures are reported as a serial loop would report them.
#include <tbb/parallel_for.h>

#include <cstddef>
#include <exception>
#include <vector>

namespace rtp {

// Runs f(i) for every i in [0, n) as TBB tasks. When some throw, the exception of the lowest i is
// rethrown once all have run, whatever the thread timing: the same message for any thread count.
template <class F>
void parallel_for_lowest_error(size_t n, F&& f) {
  std::vector<std::exception_ptr> errors(n);
  tbb::parallel_for(size_t(0), n, [&](size_t i) {
    try {
      f(i);
    } catch (...) {
      errors[i] = std::current_exception();
    }
  });
  for (auto& e : errors)
    if (e) std::rethrow_exception(e);
}

}  // namespace rtp
