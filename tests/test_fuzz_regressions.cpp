// The inputs scripts/fuzz found crashing (tests/fuzz/regressions/<target>/, docs/fuzzing.md), each run
// through the tool a user would run on it: a clean rejection (exit 3, or 2 for a glTF naming a file that
// is not there) or, for ray files, a clean trace — never a signal, never exit 5.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "tests/fuzz/reseal.h"

namespace { namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

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
  fs::path dir = fs::temp_directory_path() /
                 ("rtp-fuzzreg-" + std::to_string(getpid()) + "-" +
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
  if (files.empty()) GTEST_SKIP() << "no saved inputs in tests/fuzz/regressions/gltf";
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
  if (files.empty()) GTEST_SKIP() << "no saved inputs in tests/fuzz/regressions/package";
  const fs::path rays = dir / "probe.rays";
  write_bytes(rays, std::vector<uint8_t>(32 * 4, 0));
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
  if (files.empty()) GTEST_SKIP() << "no saved inputs in tests/fuzz/regressions/rays";
  const fs::path pkg = dir / "suzanne.rtp";
  ASSERT_EQ(run("rtpack-convert", "-q " + (kSource / "samples/khronos/Suzanne/glTF/Suzanne.gltf").string() +
                                      " --attributes normal,uv -o " + pkg.string(), dir), 0);
  for (const auto& f : files)
    expect(run("rtpack-trace", pkg.string() + " --rays " + f.string() + " --hits " + (dir / "h").string(), dir),
           {0, 3}, f);
}

}}  // namespace
