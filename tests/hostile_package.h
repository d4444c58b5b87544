#pragma once
// Shared by the hostile-package tests: real samples converted once per run, tools run as subprocesses,
// and a fixture whose checks say where a patched package must be rejected (exit 3, chunk and field).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <filesystem>
#include <string>
#include <vector>

#include "cluster/cluster.h"
#include "core/error.h"
#include "gltf_builder.h"
#include "mesh/prepare.h"
#include "package/inspect.h"
#include "package/package.h"
#include "package/package_tracer.h"
#include "package/write_package.h"
#include "package_patch.h"
#include "scene/import.h"

namespace rtp::test {

namespace fs = std::filesystem;

constexpr int kW = 8, kB = 8;

// Packages written once per run: the forest sample (mesh segments, pieces, several batching points)
// uncompressed and compressed, and Lantern with attribute chunks, uncompressed.
struct Bases {
  fs::path dir = temp_dir("hostile_bases");
  std::string forest, forest_zstd, lantern;
  Bases() {
    const Scene forest_scene = import_gltf((source_dir() / "samples/generated/forest-small.glb").string());
    forest = write(forest_scene, "forest.rtp", 60000, 0);
    forest_zstd = write(forest_scene, "forest-zstd.rtp", 60000, 9);
    ImportOptions io;
    io.normals = io.uvs = true;
    Scene lantern_scene = import_gltf((source_dir() / "samples/khronos/Lantern/glTF/Lantern.gltf").string(), io);
    prepare_scene(lantern_scene, {});
    lantern = write(lantern_scene, "lantern.rtp", 1000, 0);
  }
  ~Bases() { fs::remove_all(dir); }
  std::string write(const Scene& s, const char* name, uint64_t target, int zstd) {
    ClusterOptions co;
    co.chunk_target = target;
    ConvertOptions cv;
    cv.width = kW;
    cv.leaf_width = kB;
    cv.zstd_level = zstd;
    const std::string p = (dir / name).string();
    write_package(s, plan_batching_points(s, co), p, cv);
    return p;
  }
};
inline const Bases& bases() {
  static Bases b;
  return b;
}

struct ToolRun {
  int code;
  std::string out, err;
};
inline ToolRun run(const std::string& cmdline, const fs::path& dir) {
  const std::string cmd = cmdline + " > " + (dir / "out").string() + " 2> " + (dir / "err").string();
  const int status = std::system(cmd.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(dir / "out"), slurp(dir / "err")};
}
inline std::string tool(const char* name) { return std::string(RTP_BINARY_DIR) + "/" + name; }

// The TOC index and label of chunk (kind, id).
inline std::pair<size_t, std::string> chunk_of(const std::string& path, fmt::ChunkKind kind, uint64_t id) {
  PackageReader r(path);
  const int64_t i = r.find(kind, id);
  if (i < 0) throw std::runtime_error("no such chunk");
  return {size_t(i), chunk_label(r.toc()[size_t(i)], size_t(i))};
}

inline bool contains_all(const std::string& s, const std::vector<std::string>& needles) {
  for (const std::string& n : needles)
    if (s.find(n) == std::string::npos) return false;
  return true;
}

class Hostile : public ::testing::Test {
 protected:
  fs::path dir = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  void TearDown() override { fs::remove_all(dir); }
  std::string copy(const std::string& base) {
    const fs::path p = dir / fs::path(base).filename();
    fs::copy_file(base, p, fs::copy_options::overwrite_existing);
    return p.string();
  }
  // The in-core tracer (what rtpack-trace loads) refuses the package: exit 3, every needle in the message.
  static void expect_tracer_rejects(const std::string& path, const std::vector<std::string>& needles) {
    try {
      const PackageReader r(path);
      const auto tracer = load_package_in_core(r);
      ADD_FAILURE() << "the tracer loaded the package";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ExitCode::kInputInvalid) << e.what();
      EXPECT_TRUE(contains_all(e.what(), needles)) << e.what();
    }
  }
  // rtpack-inspect (in process, without --verify) lists it as a problem.
  static void expect_inspect_problem(const std::string& path, const std::vector<std::string>& needles, bool verify = false) {
    const PackageReader r(path);
    InspectOptions o;
    o.verify = verify;
    const InspectResult res = inspect_package(r, o);
    bool found = false;
    for (const std::string& m : res.listed) found |= contains_all(m, needles);
    EXPECT_TRUE(found) << res.report["problems"].dump(2);
  }
  static void expect_everywhere(const std::string& path, const std::vector<std::string>& needles) {
    expect_tracer_rejects(path, needles);
    expect_inspect_problem(path, needles);
    expect_inspect_problem(path, needles, true);
  }
};

}  // namespace rtp::test
