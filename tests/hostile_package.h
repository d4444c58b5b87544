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
#include "inspect/inspect.h"
#include "package/writer.h"
#include "reader/reader.h"
#include "trace/package_tracer.h"
#include "package/write_package.h"
#include "package_patch.h"
#include "scene/import.h"
#include "tool_run.h"

namespace rtp::test {

namespace fs = std::filesystem;

constexpr int kW = 8, kB = 8;

// Packages written once per run: the forest sample (mesh segments, pieces, several batching points)
// uncompressed and compressed, in large points that cull by instance boxes, and Lantern with attribute
// chunks, uncompressed.
struct Bases {
  fs::path dir = temp_dir("hostile_bases");
  std::string forest, forest_zstd, forest_boxes, lantern;
  Bases() {
    const Scene forest_scene = import_gltf((source_dir() / "samples/generated/forest-small.glb").string());
    forest = write(forest_scene, "forest.rtp", 60000, 0);
    forest_zstd = write(forest_scene, "forest-zstd.rtp", 60000, 9);
    forest_boxes = write(forest_scene, "forest-boxes.rtp", 1000000, 0);
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

// A batching point with at least two instances.
inline size_t point_with_instances(const std::string& path, uint64_t& id) {
  PackageReader r(path);
  for (size_t i = 0; i < r.toc().size(); ++i) {
    if (r.toc()[i].kind != uint32_t(fmt::ChunkKind::kBatchingPoint)) continue;
    AlignedBytes b = r.read(i);
    uint64_t n = 0;
    section<uint32_t>(b.data(), fmt::SectionType::kInstanceIds, &n);
    if (n >= 2) {
      id = r.toc()[i].id;
      return i;
    }
  }
  throw std::runtime_error("no batching point with two instances");
}

inline bool contains_all(const std::string& s, const std::vector<std::string>& needles) {
  for (const std::string& n : needles)
    if (s.find(n) == std::string::npos) return false;
  return true;
}

class Hostile : public ::testing::Test {
 protected:
  fs::path dir = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  // RTP_KEEP_HOSTILE=DIR keeps every package a test fabricated (TEST-NAME.FILE.rtp), so
  // scripts/hostile-report can time the tools on them (timings never go into the tests).
  void TearDown() override {
    if (const char* keep = std::getenv("RTP_KEEP_HOSTILE"); keep && *keep) {
      fs::create_directories(keep);
      const std::string name = ::testing::UnitTest::GetInstance()->current_test_info()->name();
      for (const auto& f : fs::directory_iterator(dir))
        if (f.is_regular_file() && f.path().extension() == ".rtp")
          fs::copy_file(f.path(), fs::path(keep) / (name + "." + f.path().filename().string()),
                        fs::copy_options::overwrite_existing);
    }
    fs::remove_all(dir);
  }
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
  // The tools themselves, as subprocesses: plain rtpack-trace, rtpack-inspect and rtpack-inspect --verify
  // exit 3 with every needle in the message, write no hit file, never hang (20 s is a hang, not a
  // timing) and stay under 100 MB of resident memory (not under ASan, whose shadow memory dominates).
  void expect_tools_reject(const std::string& path, const std::vector<std::string>& needles) {
    const fs::path rays = dir / "tools.rays", hits = dir / "tools.hits";
    if (!fs::exists(rays)) {
      std::vector<fmt::Ray> r(64);
      for (size_t i = 0; i < r.size(); ++i)
        r[i] = {{float(i) * 0.5f - 16.f, 50.f, float(i % 8) - 4.f}, 0.f, {0.01f, -1.f, 0.02f}, 1e30f};
      std::ofstream(rays, std::ios::binary)
          .write(reinterpret_cast<const char*>(r.data()), std::streamsize(r.size() * sizeof(fmt::Ray)));
    }
    const std::vector<std::pair<std::string, std::vector<std::string>>> runs = {
        {"rtpack-trace", {path, "--rays", rays.string(), "--hits", hits.string()}},
        {"rtpack-inspect", {path}},
        {"rtpack-inspect", {"--verify", path}}};
    for (const auto& [t, args] : runs) {
      const ToolResult r = run_tool(t, args, dir, {}, 20);
      const std::string what = t + (args[0] == "--verify" ? " --verify" : "");
      EXPECT_EQ(r.code, 3) << what << (r.timed_out ? " hung" : "") << " signal " << r.signal << ": " << r.err;
      EXPECT_TRUE(contains_all(r.out + r.err, needles)) << what << ": " << r.out << r.err;  // --verify lists on stdout
      if (!std::getenv("RTP_SANITIZED")) {
        EXPECT_GT(r.max_rss_kib, 0) << what;
        EXPECT_LT(r.max_rss_kib, 100 * 1000) << what << " peak RSS (KiB)";
      }
    }
    EXPECT_FALSE(fs::exists(hits)) << "rtpack-trace wrote a hit file for a package it refused";
  }
  void expect_everywhere(const std::string& path, const std::vector<std::string>& needles) {
    expect_tracer_rejects(path, needles);
    expect_inspect_problem(path, needles);
    expect_inspect_problem(path, needles, true);
    expect_tools_reject(path, needles);
  }
};

}  // namespace rtp::test
