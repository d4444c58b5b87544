#pragma once
// Number checks for the tools' options, stricter and clearer than CLI11's: NaN and ±inf are refused
// (CLI::Range only compares, and NaN passes every comparison: `--subdivide-to nan` was silently ignored,
// `rtpack-make-scene --spacing nan` wrote null translations), and the message says what was expected
// (CLI::PositiveNumber's lower bound is DBL_MIN: "Value 0 not in range 0.000000 to 1797693134862315...").
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace rtp::tools {

// A finite number v with lo < v (lo_open) or lo <= v, and v <= hi; `expected` names the set.
inline CLI::Validator number_check(const std::string& expected, double lo, bool lo_open, double hi) {
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (text.empty() || end != text.c_str() + text.size()) return "expected " + expected + ", got '" + text + "'";
        if (!std::isfinite(v) || (lo_open ? !(v > lo) : !(v >= lo)) || !(v <= hi))
          return "expected " + expected + ", got " + text;
        return {};
      },
      expected);
}

inline CLI::Validator positive() { return number_check("a positive number", 0, true, DBL_MAX); }
inline CLI::Validator non_negative() { return number_check("a number >= 0", 0, false, DBL_MAX); }
inline CLI::Validator finite_range(double lo, double hi) {
  char text[64];
  std::snprintf(text, sizeof text, "a number from %g to %g", lo, hi);
  return number_check(text, lo, false, hi);
}
// A decimal integer from 0 to 2^64 - 1 (--seed): CLI11 reads "-1" into a uint64_t as 2^64 - 1, silently.
inline CLI::Validator unsigned_integer() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        std::string expected = "expected an integer from 0 to 18446744073709551615, got '" + text + "'";
        if (text.empty() || text.size() > 20 || text.find_first_not_of("0123456789") != std::string::npos) return expected;
        if (text.size() == 20 && text > "18446744073709551615") return expected;
        return {};
      },
      "an integer >= 0");
}
// --chunk-target (rtpack-convert, rtpack-bench --convert): 1 to 2^53 triangles; beyond that the uint64
// conversion saturated silently.
inline CLI::Validator chunk_target_range() { return finite_range(1, 9007199254740992.0); }

// The items of a comma-separated list option ("100,50,25"), empty items kept so the caller names them.
inline std::vector<std::string> split_list(const std::string& text) {
  std::vector<std::string> items;
  for (size_t a = 0; a <= text.size();) {
    const size_t b = std::min(text.find(',', a), text.size());
    items.push_back(text.substr(a, b - a));
    a = b + 1;
  }
  return items;
}

}  // namespace rtp::tools
