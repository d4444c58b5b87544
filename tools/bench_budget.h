#pragma once
// rtpack-bench SCENE --out-of-core PKG: the batched out-of-core tracer against the in-core tracer on the
// same rays, same run: time, bytes read and chunks loaded per memory budget, with and without DAG
// culling (Molenaar 2019 §5.3: time and I/O against the cache size). Every out-of-core answer is
// checked byte for byte against the in-core one.
#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "bench_mode.h"

namespace rtp::bench {

struct BudgetBenchConfig : ModeConfig {
  BudgetBenchConfig() {
    kinds = {RayKind::kBounce};
    rays = size_t(1) << 18;
  }
  std::string package;
  std::vector<double> budgets = {100, 50, 25, 10, 5};  // percent of the package's on-demand bytes
  std::string budgets_text;                            // --budgets as given (parsed by run_budget_bench)
  bool direct_io = false;
  bool prefetch = false;         // --prefetch: read ahead on an I/O thread while a round traces
  std::string culling = "both";  // --culling on|off|both
  std::string save_rays;         // --save-rays PREFIX: PREFIX-KIND.rays (formats/ray_file.h) for rtpack-trace
  // reps: each out-of-core run and the in-core reference, best of this many (interleaved)
};

// Registers --out-of-core PKG (returned, for the caller's excludes), --budgets, --direct-io, --prefetch,
// --culling and --save-rays.
CLI::Option* add_budget_options(CLI::App& app, BudgetBenchConfig& cfg);

// Prints the table (stdout, or stderr with --json, the records then on stdout). Returns the exit code:
// kInternal when some out-of-core answer differs from the in-core one. Throws Error(kUsage) for a bad
// --budgets list.
int run_budget_bench(BudgetBenchConfig cfg);

// Parses --budgets (cfg.budgets_text) into cfg.budgets; throws a usage Error naming a bad item.
void parse_budgets(BudgetBenchConfig& cfg);

}  // namespace rtp::bench
