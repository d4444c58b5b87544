#pragma once
// A thread that flushes a file's written data to stable storage (fdatasync) while its writer goes on,
// so that the writer's final fsync waits only for what came after the last flush: the wait is the
// device's cache flush, which only fdatasync/fsync ask for (a new 4 MB file: 5-6 ms, 0.2 ms after an
// earlier fdatasync; docs/notes/2026-12-07-writer-measurements.md §8).
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <thread>

namespace rtp {

class BackgroundSync {
 public:
  // fail_with != 0 (tests): every flush fails with that errno instead of calling fdatasync.
  explicit BackgroundSync(int fd, int fail_with = 0);
  ~BackgroundSync();  // joins the thread (a flush in progress completes)
  BackgroundSync(const BackgroundSync&) = delete;
  BackgroundSync& operator=(const BackgroundSync&) = delete;

  // Asks for a flush of everything written so far; requests made during a flush are served by one
  // more flush after it. Never blocks on I/O.
  void request();
  // Stops the thread once the requests made so far are served (one flush serves them all). Returns the
  // errno of the first failed fdatasync, 0 if none failed: the caller must report it (after a failed
  // fdatasync the kernel may report the error to no later fsync).
  int finish();

 private:
  void run();
  int fd_, fail_with_;
  std::mutex m_;
  std::condition_variable cv_;
  uint64_t requested_ = 0, served_ = 0;
  bool stop_ = false;
  int error_ = 0;
  std::thread thread_;  // last: started once the members above exist
};

}  // namespace rtp
