// rtpack-convert: glTF scene -> rtpack package. This build: import + mesh preparation and the
// scene summary (--dry-run); package writing lands with the package format.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <sys/resource.h>
#include <unistd.h>

#include "core/error.h"
#include "mesh/prepare.h"
#include "scene/import.h"
#include "scene/summary.h"

namespace {

double peak_rss_mib() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return double(ru.ru_maxrss) / 1024.0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rtpack-convert: prepare a glTF scene for out-of-core ray tracing"};
  std::string input, output;
  bool dry_run = false, json = false, quiet = false, verbose = false;
  int scene_index = -1, subdivide = 0;
  double weld = -1, subdivide_to = 0;
  app.add_option("input", input, "input .gltf or .glb")->required();
  app.add_option("-o,--output", output, "output package (.rtp)");
  app.add_flag("--dry-run", dry_run, "import and prepare only; print the scene summary");
  app.add_flag("--json", json, "print the summary as JSON on stdout");
  app.add_option("--scene", scene_index, "glTF scene index (default: the file's default scene)")->check(CLI::NonNegativeNumber);
  app.add_option("--weld", weld, "weld vertices closer than EPS (L-inf, local units)")->check(CLI::NonNegativeNumber);
  auto* sub = app.add_option("--subdivide", subdivide, "uniform Loop subdivision levels")->check(CLI::Range(0, 8));
  app.add_option("--subdivide-to", subdivide_to, "refine each mesh until its longest world-space edge is below LENGTH")
      ->check(CLI::PositiveNumber)->excludes(sub);
  app.add_flag("-q,--quiet", quiet, "no warnings on stderr");
  app.add_flag("-v,--verbose", verbose, "stage times and peak memory on stderr");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : int(rtp::ExitCode::kUsage);
  }
  if (!dry_run) {
    std::cerr << "rtpack-convert: this build only prepares and summarizes scenes; run with --dry-run "
                 "(package output comes with the package format)\n";
    return int(rtp::ExitCode::kUsage);
  }
  using clock = std::chrono::steady_clock;
  try {
    const auto t0 = clock::now();
    rtp::ImportOptions opt;
    opt.scene = scene_index;
    rtp::Scene scene = rtp::import_gltf(input, opt);
    const auto t1 = clock::now();
    rtp::PrepareOptions prep;
    prep.clean.weld_eps = weld;
    prep.subdivide_levels = subdivide;
    prep.subdivide_to = subdivide_to;
    const rtp::PrepareReport report = rtp::prepare_scene(scene, prep);
    const auto t2 = clock::now();
    if (!quiet)
      for (const auto& w : scene.warnings) std::cerr << "warning: " << input << ": " << w << "\n";
    if (json) {
      nlohmann::json j = rtp::scene_summary_json(scene);
      j["preparation"] = rtp::prepare_report_json(report);
      std::cout << j.dump(2) << "\n";
    } else {
      std::cout << rtp::scene_summary_text(scene) << "\n" << rtp::prepare_report_text(report);
    }
    if (verbose)
      std::fprintf(stderr, "import %.3f s, preparation %.3f s, peak RSS %.1f MiB\n",
                   std::chrono::duration<double>(t1 - t0).count(), std::chrono::duration<double>(t2 - t1).count(),
                   peak_rss_mib());
  } catch (const rtp::Error& e) {
    std::cerr << "error: " << input << ": " << e.what() << "\n";
    return int(e.code());
  } catch (const std::bad_alloc&) {
    std::cerr << "error: " << input << ": out of memory\n";
    return int(rtp::ExitCode::kInternal);
  } catch (const std::exception& e) {
    std::cerr << "error: " << input << ": internal error: " << e.what() << "\n";
    return int(rtp::ExitCode::kInternal);
  }
  return 0;
}
