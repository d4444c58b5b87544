// Files as an attacker or an unlucky user meets them (issue 10, "files"): outputs appear whole or not
// at all and leave no temporary name behind any signal; devices are written in place; no output may
// be an input; inputs must be regular files and never block; external buffers stay inside the glTF's
// directory (or --allow-path); sizes are checked before reading; any bytes in file names.
// Every case runs the real tools as subprocesses (tests/tool_run.h).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>

#include <set>

#include <cstring>
#include <fstream>
#include <limits>

#include "formats/chunk.h"
#include "formats/ray_file.h"
#include "gltf_builder.h"
#include "reader/reader.h"
#include "tool_run.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

std::set<std::string> listing(const fs::path& d) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(d)) names.insert(e.path().filename().string());
  return names;
}

void write_bytes(const fs::path& p, const std::string& bytes) { std::ofstream(p, std::ios::binary | std::ios::trunc) << bytes; }

bool is_char_device(const fs::path& p) {
  struct stat st {};
  return ::lstat(p.c_str(), &st) == 0 && S_ISCHR(st.st_mode);
}

// Four rays straight down onto the unit triangle of one_triangle().
std::string four_rays() {
  std::string r;
  for (int i = 0; i < 4; ++i) {
    const float ray[8] = {0.1f + 0.05f * float(i), 0.2f, 1, 0, 0, 0, -1, 1e30f};
    r.append(reinterpret_cast<const char*>(ray), sizeof ray);
  }
  return r;
}

// The test's name, usable as one path component (parameterized names hold '/').
std::string test_name() {
  std::string n = ::testing::UnitTest::GetInstance()->current_test_info()->name();
  for (char& c : n)
    if (c == '/') c = '_';
  return n;
}

class HardeningFiles : public ::testing::Test {
 protected:
  fs::path dir = temp_dir(test_name());
  fs::path in = dir / "in", out = dir / "o";
  void SetUp() override {
    fs::create_directories(in);
    fs::create_directories(out);
  }
  void TearDown() override { fs::remove_all(dir); }

  std::string glb() { return one_triangle().write_glb(in / "s.glb"); }
  ToolResult tool(const std::string& name, const std::vector<std::string>& args, const std::vector<std::string>& env = {},
                  double timeout_s = 60) {
    return run_tool(name, args, dir, env, timeout_s);
  }
  // A package of the triangle, and a ray file, in `in`.
  std::string package() {
    std::string p = (in / "p.rtp").string();
    const ToolResult r = tool("rtpack-convert", {"-q", glb(), "-o", p});
    EXPECT_EQ(r.code, 0) << r.err;
    write_bytes(in / "rays.bin", four_rays());
    return p;
  }
  // A character device node owned by the test (mknod as root); a real /dev node only when the
  // process cannot replace it anyway (not root). Empty: skip.
  std::string char_device(const char* name, unsigned minor) {
    const fs::path p = dir / name;
    if (::mknod(p.c_str(), S_IFCHR | 0666, makedev(1, minor)) == 0) return p.string();
    return ::geteuid() == 0 ? std::string() : std::string("/dev/") + name;
  }
};

// ------------------------------------------------------------------------------------------------
// Writes

struct SignalCase {
  int sig;
  bool named_fallback;  // RTP_TEST_NO_O_TMPFILE: the filesystem-without-O_TMPFILE path
  const char* tool;
};
void PrintTo(const SignalCase& c, std::ostream* os) {
  *os << c.tool << " signal " << c.sig << (c.named_fallback ? " (named temporary)" : " (O_TMPFILE)");
}

class InterruptedWrite : public HardeningFiles, public ::testing::WithParamInterface<SignalCase> {};

// The tool is held (RTP_TEST_HOLD_OUTPUT) with its output fully written but not yet in place, then
// signalled: the output directory holds exactly the previous output, unchanged.
TEST_P(InterruptedWrite, LeavesOnlyThePreviousOutput) {
  const SignalCase c = GetParam();
  const fs::path target = out / (std::string(c.tool) == "rtpack-convert" ? "p.rtp" : "hits.bin");
  write_bytes(target, "previous output");
  std::vector<std::string> args;
  if (std::string(c.tool) == "rtpack-convert") {
    args = {"-q", glb(), "-o", target.string()};
  } else {
    const std::string p = package();
    args = {p, "--rays", (in / "rays.bin").string(), "--hits", target.string()};
  }
  const fs::path held = dir / "held";
  std::vector<std::string> env{"RTP_TEST_HOLD_OUTPUT=" + held.string()};
  if (c.named_fallback) env.push_back("RTP_TEST_NO_O_TMPFILE=1");
  const pid_t pid = spawn_tool(c.tool, args, dir, env);
  bool exited = false;
  for (int i = 0; i < 3000 && !fs::exists(held) && !exited; ++i) {
    int st;
    exited = ::waitpid(pid, &st, WNOHANG) == pid;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_FALSE(exited) << "the tool finished without holding its output (no RTP_TEST_HOLD_OUTPUT hook)";
  ASSERT_TRUE(fs::exists(held));
  // While held: with O_TMPFILE no name exists at all; the fallback shows its hidden temporary.
  EXPECT_EQ(listing(out).size(), c.named_fallback ? 2u : 1u);
  ::kill(pid, c.sig);
  const ToolResult r = wait_tool(pid, dir, 30);
  EXPECT_EQ(r.signal, c.sig) << r.err;
  EXPECT_EQ(listing(out), std::set<std::string>{target.filename().string()});
  EXPECT_EQ(slurp_file(target), "previous output");
  // The same run, not interrupted, replaces the previous output and leaves nothing else.
  env.erase(env.begin());
  const ToolResult done = wait_tool(spawn_tool(c.tool, args, dir, env), dir);
  ASSERT_EQ(done.code, 0) << done.err;
  EXPECT_EQ(listing(out), std::set<std::string>{target.filename().string()});
  EXPECT_NE(slurp_file(target), "previous output");
}

INSTANTIATE_TEST_SUITE_P(Signals, InterruptedWrite,
                         ::testing::Values(SignalCase{SIGKILL, false, "rtpack-convert"},
                                           SignalCase{SIGTERM, false, "rtpack-convert"},
                                           SignalCase{SIGINT, false, "rtpack-convert"},
                                           SignalCase{SIGTERM, true, "rtpack-convert"},
                                           SignalCase{SIGINT, true, "rtpack-convert"}, SignalCase{SIGHUP, true, "rtpack-convert"},
                                           SignalCase{SIGKILL, false, "rtpack-trace"}, SignalCase{SIGTERM, true, "rtpack-trace"}),
                         [](const auto& info) {
                           return std::string(info.param.tool[7] == 'c' ? "Convert" : "Trace") +
                                  (info.param.sig == SIGKILL   ? "Kill"
                                   : info.param.sig == SIGTERM ? "Term"
                                   : info.param.sig == SIGINT  ? "Int"
                                                               : "Hup") +
                                  (info.param.named_fallback ? "NamedTemporary" : "Tmpfile");
                         });

TEST_F(HardeningFiles, NullDeviceOutputIsWrittenInPlace) {
  const std::string null = char_device("null", 3);
  if (null.empty()) GTEST_SKIP() << "cannot create a private device node";
  const ToolResult c = tool("rtpack-convert", {"-q", glb(), "-o", null});
  EXPECT_EQ(c.code, 0) << c.err;
  EXPECT_TRUE(is_char_device(null)) << "the device node was replaced";
  const std::string p = package();
  const ToolResult t = tool("rtpack-trace", {p, "--rays", (in / "rays.bin").string(), "--hits", null});
  EXPECT_EQ(t.code, 0) << t.err;
  EXPECT_TRUE(is_char_device(null)) << "the device node was replaced";
}

TEST_F(HardeningFiles, FullDeviceOutputFailsWithExit4) {
  const std::string full = char_device("full", 7);
  if (full.empty()) GTEST_SKIP() << "cannot create a private device node";
  const ToolResult c = tool("rtpack-convert", {"-q", glb(), "-o", full});
  EXPECT_EQ(c.code, 4) << c.err;
  EXPECT_NE(c.err.find("No space left on device"), std::string::npos) << c.err;
  EXPECT_TRUE(is_char_device(full));
  const std::string p = package();
  const ToolResult t = tool("rtpack-trace", {p, "--rays", (in / "rays.bin").string(), "--hits", full});
  EXPECT_EQ(t.code, 4) << t.err;
  EXPECT_NE(t.err.find("No space left on device"), std::string::npos) << t.err;
  EXPECT_TRUE(is_char_device(full));
}

TEST_F(HardeningFiles, FifoAtTheOutputPathIsRefusedNotReplaced) {
  const fs::path fifo = out / "p.rtp";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
  const ToolResult r = tool("rtpack-convert", {"-q", glb(), "-o", fifo.string()}, {}, 20);
  EXPECT_FALSE(r.timed_out);
  EXPECT_EQ(r.code, 4) << r.err;
  EXPECT_NE(r.err.find("FIFO"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::is_fifo(fifo));
}

// ------------------------------------------------------------------------------------------------
// Input and output never the same file

TEST_F(HardeningFiles, ConvertRefusesToOverwriteItsInput) {
  const std::string src = glb();
  const std::string before = slurp_file(src);
  ASSERT_EQ(::link(src.c_str(), (in / "hard.glb").c_str()), 0);
  fs::create_symlink(src, in / "sym.glb");
  for (const fs::path& o : {fs::path(src), in / "." / ".." / "in" / "s.glb", in / "hard.glb", in / "sym.glb"}) {
    const ToolResult r = tool("rtpack-convert", {"-q", src, "-o", o.string()});
    EXPECT_EQ(r.code, 1) << o << ": " << r.err;
    EXPECT_NE(r.err.find("same device and inode"), std::string::npos) << r.err;
    EXPECT_TRUE(slurp_file(src) == before) << o << ": the input changed";
  }
  EXPECT_TRUE(fs::is_symlink(in / "sym.glb"));
}

TEST_F(HardeningFiles, MakeSceneRefusesToOverwriteItsMeshSource) {
  const std::string src = glb();
  const std::string before = slurp_file(src);
  const ToolResult r = tool("rtpack-make-scene", {"gallery", "--count", "1", "--mesh", src, "-o", (in / "." / "s.glb").string()});
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("same device and inode"), std::string::npos) << r.err;
  EXPECT_TRUE(slurp_file(src) == before) << "the mesh source changed";
  const ToolResult ok = tool("rtpack-make-scene", {"gallery", "--count", "1", "--mesh", src, "-o", (out / "g.glb").string()});
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_EQ(listing(out), std::set<std::string>{"g.glb"});
}

// A .gltf's external buffer is an input too: neither tool may replace it with its output (a user who
// typed the .bin for the .rtp lost the model's geometry).
TEST_F(HardeningFiles, ConvertAndMakeSceneRefuseToOverwriteABufferTheyRead) {
  for (const char* f : {"Suzanne.gltf", "Suzanne.bin"})
    fs::copy_file(fs::path(RTP_SOURCE_DIR) / "samples/khronos/Suzanne/glTF" / f, in / f);
  const std::string gltf = (in / "Suzanne.gltf").string(), bin = (in / "Suzanne.bin").string();
  const std::string before = slurp_file(bin);
  for (const std::vector<std::string>& args : {std::vector<std::string>{"rtpack-convert", "-q", gltf, "-o", bin},
                                               std::vector<std::string>{"rtpack-make-scene", "gallery", "--count", "2", "--mesh",
                                                                        gltf, "-o", (in / "." / "Suzanne.bin").string()}}) {
    const ToolResult r = tool(args[0], std::vector<std::string>(args.begin() + 1, args.end()));
    EXPECT_EQ(r.code, 1) << args[0] << ": " << r.err;
    EXPECT_NE(r.err.find("Suzanne.bin' (same device and inode)"), std::string::npos) << args[0] << ": " << r.err;
    EXPECT_TRUE(slurp_file(bin) == before) << args[0] << ": the buffer changed";
  }
  EXPECT_EQ(tool("rtpack-convert", {"-q", gltf, "-o", (out / "s.rtp").string()}).code, 0);
}

TEST_F(HardeningFiles, TraceRefusesToOverwriteItsInputs) {
  const std::string p = package();
  const std::string pkg = slurp_file(p), rays = slurp_file(in / "rays.bin");
  ASSERT_EQ(::link(p.c_str(), (in / "hard.rtp").c_str()), 0);
  const std::string r_path = (in / "rays.bin").string();
  const std::vector<std::vector<std::string>> cases = {
      {p, "--rays", r_path, "--hits", p},
      {p, "--rays", r_path, "--hits", (in / "hard.rtp").string()},
      {p, "--rays", r_path, "--hits", r_path},
      {p, "--rays", r_path, "--hits", (out / "h.bin").string(), "--shading", p},
      {p, "--rays", p, "--make-camera-rays", "4x4", "--hits", (out / "h.bin").string()},
  };
  for (const auto& args : cases) {
    const ToolResult r = tool("rtpack-trace", args);
    EXPECT_EQ(r.code, 1) << args.back() << ": " << r.err;
    EXPECT_NE(r.err.find("same device and inode"), std::string::npos) << r.err;
    EXPECT_TRUE(slurp_file(p) == pkg) << "the package changed";
    EXPECT_TRUE(slurp_file(r_path) == rays) << "the ray file changed";
  }
  EXPECT_TRUE(listing(out).empty());
}

// --make-camera-rays writes its ray file with the hit file, when the trace succeeded: a batching point whose
// checksum fails while it is traced out of core leaves neither (a complete ray file of the failed run was
// left behind).
TEST_F(HardeningFiles, MadeCameraRaysAppearOnlyWhenTheTraceSucceeds) {
  const std::string p = package();
  uint64_t at = 0;
  {
    const PackageReader r(p);
    for (const fmt::TocEntry& e : r.toc())
      if (e.kind == uint32_t(fmt::ChunkKind::kBatchingPoint) && at == 0) at = e.offset + e.stored_size / 2;
  }
  ASSERT_GT(at, 0u);
  {
    std::fstream f(p, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(std::streamoff(at));
    const char c = char(f.get());
    f.seekp(std::streamoff(at));
    f.put(char(c ^ 0x10));
  }
  const std::vector<std::string> args = {p,
                                         "--make-camera-rays",
                                         "8x8",
                                         "--rays",
                                         (out / "cam.rays").string(),
                                         "--hits",
                                         (out / "h.bin").string(),
                                         "--memory-budget",
                                         "1MiB"};
  const ToolResult bad = tool("rtpack-trace", args);
  EXPECT_EQ(bad.code, 3) << bad.err;
  EXPECT_NE(bad.err.find("checksum mismatch"), std::string::npos) << bad.err;
  EXPECT_TRUE(listing(out).empty());
  package();  // intact again: both files appear
  const ToolResult ok = tool("rtpack-trace", args);
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_EQ(listing(out), (std::set<std::string>{"cam.rays", "h.bin"}));
  EXPECT_EQ(fs::file_size(out / "cam.rays"), 64 * sizeof(fmt::Ray));
}

// Invalid rays (formats/ray_file.h) come back as misses and are counted; rtpack-trace also names the first,
// on stderr and in --json, so that one bad ray among millions can be found.
TEST_F(HardeningFiles, TraceNamesTheFirstInvalidRay) {
  const std::string p = package();
  std::string rays = four_rays();
  float r1[8], r3[8];
  std::memcpy(r1, rays.data() + 32, 32);
  std::memcpy(r3, rays.data() + 96, 32);
  r1[4] = std::numeric_limits<float>::quiet_NaN();  // ray 1: a NaN direction
  r3[3] = 2, r3[7] = 1;                             // ray 3: tnear > tfar
  rays.replace(32, 32, reinterpret_cast<const char*>(r1), 32);
  rays.replace(96, 32, reinterpret_cast<const char*>(r3), 32);
  write_bytes(in / "bad.rays", rays);
  const std::vector<std::string> args = {p, "--rays", (in / "bad.rays").string(), "--hits", (out / "h.bin").string()};
  const ToolResult r = tool("rtpack-trace", args);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("4 rays: 2 hits, 2 invalid"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("warning: 2 invalid rays"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("the first ray 1: org (0.15, 0.2, 1) dir (nan, 0, -1)"), std::string::npos) << r.err;
  std::vector<std::string> json_args = args;
  json_args.push_back("--json");
  const ToolResult j = tool("rtpack-trace", json_args);
  ASSERT_EQ(j.code, 0) << j.err;
  const auto doc = nlohmann::json::parse(j.out);
  EXPECT_EQ(doc["invalid_rays"], 2);
  EXPECT_EQ(doc["first_invalid_ray"], 1);
}

// ------------------------------------------------------------------------------------------------
// Inputs must be regular files (and never block)

TEST_F(HardeningFiles, GltfInputMustBeARegularFile) {
  ASSERT_EQ(::mkfifo((in / "fifo.glb").c_str(), 0644), 0);
  fs::create_directories(in / "dir.glb");
  const std::vector<std::pair<std::string, std::string>> cases = {{(in / "dir.glb").string(), "is a directory"},
                                                                  {(in / "fifo.glb").string(), "is not a regular file (a FIFO)"},
                                                                  {"/dev/zero", "is not a regular file (a character device)"}};
  for (const auto& [path, msg] : cases) {
    const ToolResult r = tool("rtpack-convert", {"--dry-run", path}, {}, 20);
    EXPECT_FALSE(r.timed_out) << path << " blocked";
    EXPECT_EQ(r.code, 2) << path << ": " << r.err;
    EXPECT_NE(r.err.find(msg), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("no such file"), std::string::npos) << r.err;
  }
}

TEST_F(HardeningFiles, PackageAndRayFileMustBeRegularFiles) {
  const std::string p = package();
  ASSERT_EQ(::mkfifo((in / "fifo").c_str(), 0644), 0);
  fs::create_directories(in / "dir.rtp");
  const std::string r_path = (in / "rays.bin").string(), hits = (out / "h.bin").string();
  struct Case {
    std::string tool;
    std::vector<std::string> args;
    std::string msg;
  };
  const std::vector<Case> cases = {
      {"rtpack-inspect", {(in / "dir.rtp").string()}, "is a directory"},
      {"rtpack-inspect", {(in / "fifo").string()}, "(a FIFO)"},
      {"rtpack-inspect", {"/dev/zero"}, "(a character device)"},
      {"rtpack-trace", {(in / "dir.rtp").string(), "--rays", r_path, "--hits", hits}, "is a directory"},
      {"rtpack-trace", {(in / "fifo").string(), "--rays", r_path, "--hits", hits}, "(a FIFO)"},
      {"rtpack-trace", {p, "--rays", (in / "fifo").string(), "--hits", hits}, "(a FIFO)"},
      {"rtpack-trace", {p, "--rays", (in / "dir.rtp").string(), "--hits", hits}, "is a directory"},
  };
  for (const Case& c : cases) {
    const ToolResult r = tool(c.tool, c.args, {}, 20);
    EXPECT_FALSE(r.timed_out) << c.tool << " " << c.args[0] << " blocked";
    EXPECT_EQ(r.code, 2) << c.tool << " " << c.args[0] << ": " << r.err;
    EXPECT_NE(r.err.find(c.msg), std::string::npos) << r.err;
  }
  EXPECT_TRUE(listing(out).empty());
}

// ------------------------------------------------------------------------------------------------
// External buffer URIs stay inside the glTF's directory unless --allow-path widens it

class BufferPaths : public HardeningFiles {
 protected:
  fs::path scene_dir = dir / "scene", data_dir = dir / "data";
  GltfBuilder b = one_triangle();
  void SetUp() override {
    HardeningFiles::SetUp();
    fs::create_directories(scene_dir);
    fs::create_directories(data_dir);
    std::ofstream(data_dir / "outside.bin", std::ios::binary)
        .write(reinterpret_cast<const char*>(b.bin.data()), std::streamsize(b.bin.size()));
  }
  std::string gltf_with_uri(const std::string& uri, size_t byte_length) {
    nlohmann::json d = b.j;
    d["buffers"] = {{{"byteLength", byte_length}, {"uri", uri}}};
    const fs::path p = scene_dir / "s.gltf";
    std::ofstream(p, std::ios::binary) << d.dump();
    return p.string();
  }
  ToolResult dry_run(const std::string& gltf, const std::vector<std::string>& extra = {}) {
    std::vector<std::string> args{"--dry-run", "--json", gltf};
    args.insert(args.end(), extra.begin(), extra.end());
    return tool("rtpack-convert", args);
  }
};

TEST_F(BufferPaths, DotDotEscapeIsRefusedUnlessAllowed) {
  for (const std::string& uri : std::vector<std::string>{"../data/outside.bin", "%2E%2E/data/outside.bin",
                                                         "..%2Fdata%2Foutside.bin", (data_dir / "outside.bin").string()}) {
    const std::string g = gltf_with_uri(uri, b.bin.size());
    const ToolResult r = dry_run(g);
    EXPECT_EQ(r.code, 3) << uri << ": " << r.err;
    EXPECT_NE(r.err.find("/buffers/0/uri"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("outside the glTF's directory"), std::string::npos) << r.err;
    const ToolResult ok = dry_run(g, {"--allow-path", data_dir.string()});
    EXPECT_EQ(ok.code, 0) << uri << ": " << ok.err;
  }
}

TEST_F(BufferPaths, EtcPasswdIsNeverRead) {
  const uint64_t size = fs::file_size("/etc/passwd");
  nlohmann::json d = b.j;
  d["buffers"] = {{{"byteLength", b.bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(b.bin)}},
                  {{"byteLength", size}, {"uri", "../../../../../../../../../../etc/passwd"}}};
  d["bufferViews"].push_back({{"buffer", 1}, {"byteLength", 24}});
  d["accessors"].push_back(
      {{"bufferView", int(d["bufferViews"].size() - 1)}, {"componentType", 5126}, {"type", "VEC2"}, {"count", 3}});
  d["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = int(d["accessors"].size() - 1);
  std::ofstream(scene_dir / "s.gltf", std::ios::binary) << d.dump();
  const ToolResult r =
      tool("rtpack-convert", {"-q", (scene_dir / "s.gltf").string(), "-o", (out / "p.rtp").string(), "--attributes", "uv"});
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_NE(r.err.find("/buffers/1/uri"), std::string::npos) << r.err;
  EXPECT_TRUE(listing(out).empty());
}

TEST_F(BufferPaths, SymlinkEscapeIsRefusedUnlessAllowed) {
  fs::create_symlink(data_dir / "outside.bin", scene_dir / "link.bin");
  fs::create_directory_symlink(data_dir, scene_dir / "linkdir");
  for (const std::string uri : {"link.bin", "linkdir/outside.bin"}) {
    const std::string g = gltf_with_uri(uri, b.bin.size());
    const ToolResult r = dry_run(g);
    EXPECT_EQ(r.code, 3) << uri << ": " << r.err;
    EXPECT_NE(r.err.find("/buffers/0/uri"), std::string::npos) << r.err;
    EXPECT_EQ(dry_run(g, {"--allow-path", data_dir.string()}).code, 0) << uri;
  }
  // A symbolic link that stays inside is fine.
  fs::copy_file(data_dir / "outside.bin", scene_dir / "real.bin");
  fs::create_symlink("real.bin", scene_dir / "inside.bin");
  const ToolResult r = dry_run(gltf_with_uri("inside.bin", b.bin.size()));
  EXPECT_EQ(r.code, 0) << r.err;
}

// ------------------------------------------------------------------------------------------------
// Sizes checked before reading (sparse files: no disk cost)

TEST_F(BufferPaths, OversizedExternalBufferIsRejectedBeforeReading) {
  const std::string g = gltf_with_uri("big.bin", b.bin.size());
  std::ofstream(scene_dir / "big.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(b.bin.data()), std::streamsize(b.bin.size()));
  fs::resize_file(scene_dir / "big.bin", uint64_t(384) << 20);
  const ToolResult r = dry_run(g);
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_NE(r.err.find("/buffers/0: byteLength is " + std::to_string(b.bin.size())), std::string::npos) << r.err;
  EXPECT_LT(r.max_rss_kib, 100 * 1024) << "the 384 MiB file was read";
}

TEST_F(HardeningFiles, GlbHeaderIsCheckedBeforeItsBody) {
  const uint64_t size = uint64_t(384) << 20;
  auto sparse_glb = [&](uint32_t version, uint32_t length, uint32_t json_length) {
    const fs::path p = in / "big.glb";
    const uint32_t h[5] = {0x46546C67, version, length, json_length, 0x4E4F534A};
    write_bytes(p, std::string(reinterpret_cast<const char*>(h), sizeof h));
    fs::resize_file(p, size);
    return p.string();
  };
  const char* msgs[3] = {"extends past the end", "version 1", "header declares"};
  for (int i = 0; i < 3; ++i) {
    const std::string p = i == 0   ? sparse_glb(2, uint32_t(size), 0xFFFFFF00u)
                          : i == 1 ? sparse_glb(1, uint32_t(size), 100)
                                   : sparse_glb(2, 0xFFFFFFF0u, 100);
    const ToolResult r = tool("rtpack-convert", {"--dry-run", p});
    EXPECT_EQ(r.code, 3) << r.err;
    EXPECT_NE(r.err.find(msgs[i]), std::string::npos) << r.err;
    EXPECT_LT(r.max_rss_kib, 100 * 1024) << "the 384 MiB body was read before the header was checked";
  }
}

// ------------------------------------------------------------------------------------------------
// File names that are not UTF-8

TEST_F(HardeningFiles, NonUtf8FileNamesWork) {
  const std::string src = one_triangle().write_glb(in / "s\xFF\xFE.glb");
  const std::string pkg = (out / "p\xFF.rtp").string();
  const ToolResult c = tool("rtpack-convert", {"--json", src, "-o", pkg});
  ASSERT_EQ(c.code, 0) << c.err;
  EXPECT_TRUE(nlohmann::json::accept(c.out)) << c.out;
  const ToolResult d = tool("rtpack-convert", {"--dry-run", "--json", src});
  EXPECT_EQ(d.code, 0) << d.err;
  const ToolResult i = tool("rtpack-inspect", {pkg, "--verify"});
  EXPECT_EQ(i.code, 0) << i.err;
  const ToolResult j = tool("rtpack-inspect", {pkg, "--json"});
  EXPECT_EQ(j.code, 0) << j.err;
  write_bytes(in / "r\xFF.bin", four_rays());
  const ToolResult t =
      tool("rtpack-trace", {pkg, "--rays", (in / "r\xFF.bin").string(), "--hits", (out / "h\xFF.bin").string(), "--json"});
  EXPECT_EQ(t.code, 0) << t.err;
  EXPECT_EQ(fs::file_size(out / "h\xFF.bin"), 4u * 20u);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
