// The inputs scripts/fuzz found crashing (tests/fuzz/regressions/<target>/, docs/fuzzing.md), each run
// through the tool a user would run on it: a clean rejection (exit 3, or 2 for a glTF naming a file that
// is not there) or, for ray files, a clean trace — never a signal, never exit 5. No crash has been saved
// yet, so each test also runs inputs of its own that it can check every time: the committed glTF seeds
// (converted, exit 0), packages converted from them, truncated and bit-flipped and re-sealed as the
// harness does (exit 0 or 3), and hostile ray files (exit 0, or 3 for a partial record).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "tests/fuzz/reseal.h"

namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

const fs::path kSource = RTP_SOURCE_DIR;
const fs::path kBin = RTP_BINARY_DIR;

std::vector<uint8_t> read_bytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::vector<uint8_t>((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

void write_bytes(const fs::path& p, const std::vector<uint8_t>& b) {
  std::ofstream(p, std::ios::binary | std::ios::trunc).write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

// The saved inputs of one target, sorted (none: the test is skipped).
std::vector<fs::path> regressions(const std::string& target) {
  std::vector<fs::path> files;
  const fs::path dir = kSource / "tests/fuzz/regressions" / target;
  if (fs::is_directory(dir))
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_regular_file() && e.path().filename().string()[0] != '.') files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

// Exit code of a tool run, -1 when it died of a signal. Output is kept in dir/out and dir/err.
int run(const std::string& tool, const std::string& args, const fs::path& dir) {
  const std::string cmd = (kBin / tool).string() + " " + args + " > " + (dir / "out").string() + " 2> " + (dir / "err").string();
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

class FuzzRegressions : public ::testing::Test {
 protected:
  fs::path dir = fs::temp_directory_path() / ("rtp-fuzzreg-" + std::to_string(getpid()) + "-" +
                                              ::testing::UnitTest::GetInstance()->current_test_info()->name());
  void SetUp() override { fs::create_directories(dir); }
  void TearDown() override { fs::remove_all(dir); }
  void expect(int code, const std::set<int>& allowed, const fs::path& input) {
    EXPECT_TRUE(allowed.count(code)) << input.filename() << ": exit " << code << "\n" << slurp(dir / "err");
  }
};

// fuzz_gltf inputs, with the external buffers the fuzzer had next to them (scripts/fuzz), converted.
TEST_F(FuzzRegressions, GltfInputsAreRejectedCleanly) {
  const auto files = regressions("gltf");
  size_t seeds = 0;
  for (const auto& e : fs::directory_iterator(kSource / "tests/fuzz/seeds/gltf")) {
    const fs::path out = dir / "seed.rtp";
    expect(run("rtpack-convert", "-q " + e.path().string() + " -o " + out.string(), dir), {0}, e.path());
    EXPECT_TRUE(fs::exists(out)) << e.path().filename();
    fs::remove(out);
    ++seeds;
  }
  EXPECT_GE(seeds, 2u) << "tests/fuzz/seeds/gltf";
  for (const char* bin : {"BoomBox/glTF/BoomBox.bin", "Suzanne/glTF/Suzanne.bin", "Lantern/glTF-Draco/Lantern.bin"})
    fs::copy_file(kSource / "samples/khronos" / bin, dir / fs::path(bin).filename());
  for (const auto& f : files) {
    const auto bytes = read_bytes(f);
    const bool glb = bytes.size() >= 4 && std::equal(bytes.begin(), bytes.begin() + 4, "glTF");
    const fs::path in = dir / (glb ? "input.glb" : "input.gltf");
    write_bytes(in, bytes);
    expect(run("rtpack-convert", "-q " + in.string() + " -o " + (dir / "out.rtp").string(), dir), {2, 3}, f);
    EXPECT_FALSE(fs::exists(dir / "out.rtp")) << f.filename();
  }
}

// fuzz_package inputs, re-sealed as the harness does, through rtpack-inspect --verify and rtpack-trace.
TEST_F(FuzzRegressions, PackageInputsAreRejectedCleanly) {
  const auto files = regressions("package");
  const fs::path rays = dir / "probe.rays";
  write_bytes(rays, std::vector<uint8_t>(32 * 4, 0));
  // Packages of the seed glTF (stored and zstd chunks), cut at 8 places and with 16 bytes flipped one at a
  // time, re-sealed: read to the end or refused, never a crash.
  size_t mutants = 0, rejected = 0;
  for (const char* level : {"0", "1"}) {
    const fs::path pkg = dir / (std::string("seed-") + level + ".rtp");
    ASSERT_EQ(
        run("rtpack-convert",
            "-q " + (kSource / "tests/fuzz/seeds/gltf/tiny.gltf").string() + " --zstd-level " + level + " -o " + pkg.string(),
            dir),
        0);
    const auto good = read_bytes(pkg);
    for (int k = 0; k < 24; ++k) {
      auto bytes = good;
      if (k < 8)
        bytes.resize(good.size() * size_t(k + 1) / 9);
      else
        bytes[(good.size() * size_t(k - 8)) / 16 + size_t(k) * 37 % 4096 % good.size()] ^= uint8_t(1u << (k % 8));
      rtp::fuzz::reseal_package(bytes);
      const fs::path in = dir / "mutant.rtp";
      write_bytes(in, bytes);
      const fs::path label = pkg.filename().string() + " mutant " + std::to_string(k);
      const int verify = run("rtpack-inspect", "--verify " + in.string(), dir);
      expect(verify, {0, 3}, label);
      rejected += verify == 3;
      expect(run("rtpack-trace", in.string() + " --rays " + rays.string() + " --hits " + (dir / "h").string(), dir), {0, 3},
             label);
      ++mutants;
    }
  }
  EXPECT_EQ(mutants, 48u);
  EXPECT_GE(rejected, 16u) << "every cut package at least is refused";
  for (const auto& f : files) {
    auto bytes = read_bytes(f);
    rtp::fuzz::reseal_package(bytes);
    const fs::path in = dir / "input.rtp";
    write_bytes(in, bytes);
    expect(run("rtpack-inspect", "--verify " + in.string(), dir), {3}, f);
    expect(run("rtpack-trace", in.string() + " --rays " + rays.string() + " --hits " + (dir / "h").string(), dir), {3}, f);
  }
}

// fuzz_rays inputs traced through the package the fuzzer used (Suzanne with attributes): any ray
// file of whole records traces (exit 0), others are rejected (exit 3).
TEST_F(FuzzRegressions, RayInputsTraceCleanly) {
  const auto files = regressions("rays");
  const fs::path pkg = dir / "suzanne.rtp";
  ASSERT_EQ(
      run("rtpack-convert",
          "-q " + (kSource / "samples/khronos/Suzanne/glTF/Suzanne.gltf").string() + " --attributes normal,uv -o " + pkg.string(),
          dir),
      0);
  // Hostile rays of the fuzzer's seeds (docs/fuzzing.md): NaN, ±inf, zero and denormal directions, tnear >
  // tfar, tnear = inf, huge origins; whole records trace (exit 0), a partial record is refused (exit 3).
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  const float den = std::numeric_limits<float>::denorm_min();
  const std::vector<std::array<float, 8>> hostile = {{0, 0, 5, 0, 0, 0, -1, inf},       {0, 0, 5, 0, nan, 0, -1, inf},
                                                     {0, 0, 5, 0, inf, 0, -1, inf},     {0, 0, 5, 0, 0, 0, 0, inf},
                                                     {0, 0, 5, 0, den, den, -den, inf}, {0, 0, 5, 2, 0, 0, -1, 1},
                                                     {0, 0, 5, inf, 0, 0, -1, inf},     {3e38f, -3e38f, 3e38f, 0, -1, 1, -1, inf},
                                                     {nan, 0, 5, 0, 0, 0, -1, nan}};
  std::vector<uint8_t> all(hostile.size() * 32);
  std::memcpy(all.data(), hostile.data(), all.size());
  write_bytes(dir / "hostile.rays", all);
  expect(run("rtpack-trace",
             pkg.string() + " --rays " + (dir / "hostile.rays").string() + " --shading " + (dir / "s").string() + " --hits " +
                 (dir / "h").string(),
             dir),
         {0}, "hostile.rays");
  all.pop_back();
  write_bytes(dir / "partial.rays", all);
  expect(
      run("rtpack-trace", pkg.string() + " --rays " + (dir / "partial.rays").string() + " --hits " + (dir / "h").string(), dir),
      {3}, "partial.rays");
  for (const auto& f : files)
    expect(run("rtpack-trace", pkg.string() + " --rays " + f.string() + " --hits " + (dir / "h").string(), dir), {0, 3}, f);
}

}  // namespace RTP_UNITY_ID
}  // namespace
