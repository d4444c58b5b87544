// Output files flushed on a thread of their own while they are written (core/background_sync.h,
// OutputFile::start_writeback): the committed file holds every byte, and a failed flush is reported.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "core/background_sync.h"
#include "core/error.h"
#include "core/output_file.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

TEST(BackgroundSync, ReportsAFailedFlush) {
  int p[2];
  ASSERT_EQ(::pipe(p), 0);
  {
    BackgroundSync sync(p[1]);  // fdatasync of a pipe fails (EINVAL)
    sync.request();
    sync.request();
    EXPECT_EQ(sync.finish(), EINVAL);
    EXPECT_EQ(sync.finish(), EINVAL);  // again: stopped, same answer
  }
  {
    BackgroundSync idle(p[1]);  // nothing asked: no flush, no error, and the destructor joins
    EXPECT_EQ(idle.finish(), 0);
  }
  { BackgroundSync dropped(p[1]); }  // destroyed without finish: joins, no hang
  ::close(p[0]);
  ::close(p[1]);
}

TEST(OutputFileWriteback, CommittedFileHoldsEveryByte) {
  const fs::path dir = fs::temp_directory_path() / ("rtp-output-sync-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path path = dir / "out.bin";
  std::vector<uint8_t> data(3 * 1024 * 1024 + 123);
  for (size_t i = 0; i < data.size(); ++i) data[i] = uint8_t(i * 2654435761u >> 13);
  {
    OutputFile f(path.string());
    size_t at = 0;
    for (const size_t piece : {size_t(1) << 20, size_t(1) << 20, data.size() - (size_t(2) << 20)}) {
      f.write_at(at, data.data() + at, piece);
      at += piece;
      f.start_writeback();  // flushes run while later pieces are written
    }
    EXPECT_FALSE(fs::exists(path));  // nothing at the path before commit
    f.set_size(data.size());
    f.commit();
  }
  std::ifstream in(path, std::ios::binary);
  const std::vector<uint8_t> back((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(back, data);
  {
    OutputFile dropped((dir / "dropped.bin").string());  // flushing, never committed: nothing appears
    dropped.write_at(0, data.data(), 4096);
    dropped.start_writeback();
  }
  EXPECT_FALSE(fs::exists(dir / "dropped.bin"));
  fs::remove_all(dir);
}

// A background flush that fails (the RTP_TEST_FLUSH_FAILS hook: EIO) fails commit with an output error
// naming the file, and nothing appears at the path: the kernel may report a failed flush to no later
// fsync, so commit must not rely on its own.
TEST(OutputFileWriteback, AFailedBackgroundFlushFailsCommit) {
  const fs::path dir = fs::temp_directory_path() / ("rtp-output-sync-fail-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path path = dir / "out.bin";
  ASSERT_EQ(::setenv("RTP_TEST_FLUSH_FAILS", "1", 1), 0);
  const std::vector<uint8_t> data(1 << 20, 7);
  try {
    OutputFile f(path.string());
    f.write_at(0, data.data(), data.size());
    f.start_writeback();
    f.set_size(data.size());
    f.commit();
    ADD_FAILURE() << "commit succeeded after a failed flush";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ExitCode::kOutput);
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("Input/output error"), std::string::npos) << e.what();
  }
  ::unsetenv("RTP_TEST_FLUSH_FAILS");
  EXPECT_FALSE(fs::exists(path));
  EXPECT_TRUE(fs::is_empty(dir)) << "a temporary name was left behind";
  fs::remove_all(dir);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
