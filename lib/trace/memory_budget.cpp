// --memory-budget text -> bytes: a byte count with an optional binary (KiB, MiB, GiB, TiB) or decimal
// (KB, MB, GB, TB) unit, or a percentage of the package's on-demand bytes.
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <string>

#include "core/error.h"
#include "trace/out_of_core.h"

namespace rtp {

uint64_t parse_memory_budget(const std::string& text, uint64_t on_demand) {
  auto bad = [&](const std::string& why) -> uint64_t {
    throw Error(ExitCode::kUsage, "--memory-budget " + text + ": " + why +
                                      " (expected bytes with an optional unit, e.g. 256MiB or 2GB, or a percentage, e.g. 10%)");
  };
  size_t end = 0;
  while (end < text.size() && (std::isdigit(static_cast<unsigned char>(text[end])) || text[end] == '.')) ++end;
  const std::string number = text.substr(0, end), unit = text.substr(end);
  if (number.empty() || number.front() == '.' || number.back() == '.' || number.find('.') != number.rfind('.'))
    return bad("not a number");
  const double v = std::strtod(number.c_str(), nullptr);
  double bytes = 0;
  if (unit == "%") {
    if (v <= 0 || v > 100) return bad("a percentage in (0, 100]");
    bytes = std::ceil(double(on_demand) * v / 100.0);
  } else {
    static const struct {
      const char* name;
      double scale;
    } kUnits[] = {{"", 1},     {"B", 1},    {"KiB", 1024.0}, {"MiB", 1048576.0}, {"GiB", 1073741824.0}, {"TiB", 1099511627776.0},
                  {"KB", 1e3}, {"MB", 1e6}, {"GB", 1e9},     {"TB", 1e12}};
    bool known = false;
    for (const auto& u : kUnits)
      if (unit == u.name) bytes = std::floor(v * u.scale), known = true;
    if (!known) return bad("unknown unit '" + unit + "'");
  }
  if (!(bytes >= 1) || bytes > 9.0e18) return bad("out of range");
  return uint64_t(bytes);
}

}  // namespace rtp
