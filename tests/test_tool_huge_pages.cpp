// rtpack-convert's malloc heaps on transparent huge pages (tools/malloc_policy.h): where the kernel's THP
// mode is "madvise" the tool re-executes itself with glibc.malloc.hugetlb=1 and its heaps hold 2 MiB
// pages; a GLIBC_TUNABLES that names the tunable is obeyed; the package is the same bytes either way.
#include <gtest/gtest.h>

#include <fstream>
#include <regex>

#include "gltf_builder.h"
#include "tool_run.h"
#include "tools/malloc_policy.h"  // thp_mode(): the kernel's mode, read as the tool reads it

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

// The -v line "memory: malloc huge pages STATE; X MiB of anonymous huge pages resident at the end".
struct MemoryLine {
  std::string state;
  double huge_mib = -2;
};

MemoryLine memory_line(const std::string& err) {
  static const std::regex re(R"(memory: malloc huge pages (.*); (-?[0-9.]+) MiB of anonymous huge pages resident at the end)");
  std::smatch m;
  if (!std::regex_search(err, m, re)) return {};
  return {m[1].str(), std::stod(m[2].str())};
}

class HugePages : public ::testing::Test {
 protected:
  fs::path dir = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::path scene = source_dir() / "samples/khronos/FlightHelmet/glTF/FlightHelmet.gltf";
  void TearDown() override { fs::remove_all(dir); }
  ToolResult convert(const fs::path& out, const std::vector<std::string>& env) {
    return run_tool("rtpack-convert", {scene.string(), "-o", out.string(), "-v", "--threads", "1"}, dir, env);
  }
};

TEST_F(HugePages, ConvertHeapsUseThemAndTheTunableTurnsThemOff) {
  const ToolResult off = convert(dir / "off.rtp", {"GLIBC_TUNABLES=glibc.malloc.hugetlb=0"});
  ASSERT_EQ(off.code, 0) << off.err;
  const MemoryLine o = memory_line(off.err);
  EXPECT_EQ(o.state, "off (GLIBC_TUNABLES sets glibc.malloc.hugetlb=0)") << off.err;

  // Another tunable the user set is kept beside ours (the tool still turns huge pages on).
  const ToolResult on = convert(dir / "on.rtp", {"GLIBC_TUNABLES=glibc.malloc.arena_max=4"});
  ASSERT_EQ(on.code, 0) << on.err;
  EXPECT_EQ(slurp_file(dir / "on.rtp"), slurp_file(dir / "off.rtp")) << "huge pages changed the package bytes";
  const MemoryLine m = memory_line(on.err);
#ifdef RTP_SANITIZED_BUILD
  EXPECT_EQ(m.state, "off (sanitizer build: its own allocator)") << on.err;
#else
  const std::string mode = rtp::tools::thp_mode();
  if (mode != "madvise") {
    EXPECT_EQ(m.state, "off (kernel THP mode '" + (mode.empty() ? std::string("unknown") : mode) + "')") << on.err;
    GTEST_SKIP() << "kernel THP mode is '" << mode << "', not madvise: the tool leaves malloc as it is";
  }
  EXPECT_EQ(m.state, "on (glibc.malloc.hugetlb=1)") << on.err;
  // The re-executed process really holds huge pages: FlightHelmet's heaps peak near 40 MiB.
  EXPECT_GE(m.huge_mib, 2.0) << on.err;
  EXPECT_EQ(o.huge_mib, 0.0) << "without the tunable no heap is madvised and no buffer of FlightHelmet is 4 MiB: " << off.err;
#endif
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
