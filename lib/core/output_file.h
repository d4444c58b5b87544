#pragma once
// Output files that appear only when complete and never leave a temporary name behind.
//
// The data is written to an unnamed file (O_TMPFILE) in the target's directory and linked into
// place by commit() (linkat through /proc/self/fd; when a previous output exists, linked to a fresh
// hidden name and renamed over it, so the previous file stays intact until the new one is whole).
// An interrupted run — SIGINT, SIGTERM, kill -9, a crash — leaves nothing but the previous output.
// On a filesystem without O_TMPFILE a named temporary `.NAME.tmp-PID-XXXXXX` is used instead and
// removed on destruction and on SIGINT/SIGTERM/SIGHUP (kill -9 cannot be caught there).
// An output path that is a character device (/dev/null, /dev/full) is written in place, never
// replaced; a directory, FIFO, socket or block device at the path is refused.
//
// Test hooks (environment): RTP_TEST_NO_O_TMPFILE=1 forces the named-temporary fallback;
// RTP_TEST_HOLD_OUTPUT=FILE makes commit() create FILE and wait up to 60 s before linking, so a
// test can signal a process whose output is fully written but not yet in place;
// RTP_TEST_FLUSH_FAILS=1 makes start_writeback's background flushes fail with EIO.
#include <cstdint>
#include <memory>
#include <string>

namespace rtp {

class BackgroundSync;

// Checks before any work that `path` can be written: an existing character device there is
// writable, or its directory exists and is writable, it is not a directory / FIFO / socket, and an
// existing file there is writable. Throws Error(kOutput).
void check_output_path(const std::string& path);

class OutputFile {
 public:
  // Throws Error(kOutput) when the output cannot be created.
  explicit OutputFile(const std::string& path);
  ~OutputFile();  // without commit(): nothing appears at the path, no temporary name remains
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  // pwrite of all `size` bytes at `offset` (a device: written as asked). Throws Error(kOutput).
  void write_at(uint64_t offset, const void* data, size_t size);
  // Flushes what is written so far to stable storage on a thread of its own, without waiting
  // (regular files; core/background_sync.h), so that commit's fsync waits only for the rest. A failed
  // flush fails commit.
  void start_writeback();
  // Sets the final size (regular files only; a device is left alone).
  void set_size(uint64_t size);
  // Flushes and puts the file at its path, replacing a previous one atomically. Throws Error(kOutput).
  void commit();

  bool is_device() const { return device_; }
  const std::string& path() const { return path_; }

 private:
  void link_into_place();
  std::string path_, dir_, name_, named_tmp_;  // named_tmp_: the fallback's temporary (in dir_)
  int fd_ = -1, dir_fd_ = -1;
  bool device_ = false, committed_ = false;
  std::unique_ptr<BackgroundSync> sync_;  // started by the first start_writeback
  bool no_sync_thread_ = false;           // the thread could not be started: commit's fsync does it all
};

// The whole of `size` bytes to `path` through an OutputFile. Throws Error(kOutput).
void write_output_file(const std::string& path, const void* data, size_t size);

}  // namespace rtp
