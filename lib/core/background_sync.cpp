// Background fdatasync of a file being written (core/background_sync.h).
#include "core/background_sync.h"

#include <unistd.h>

#include <cerrno>

namespace rtp {

BackgroundSync::BackgroundSync(int fd, int fail_with) : fd_(fd), fail_with_(fail_with), thread_([this] { run(); }) {}

BackgroundSync::~BackgroundSync() { finish(); }

void BackgroundSync::request() {
  {
    std::lock_guard<std::mutex> lock(m_);
    ++requested_;
  }
  cv_.notify_one();
}

int BackgroundSync::finish() {
  {
    std::lock_guard<std::mutex> lock(m_);
    stop_ = true;
  }
  cv_.notify_one();
  if (thread_.joinable()) thread_.join();
  return error_;
}

void BackgroundSync::run() {
  std::unique_lock<std::mutex> lock(m_);
  for (;;) {
    cv_.wait(lock, [&] { return stop_ || requested_ != served_; });
    if (requested_ == served_) return;  // stopped with nothing asked: the final fsync does the rest
    const uint64_t upto = requested_;
    lock.unlock();
    int e = 0;
    if (fail_with_) {
      e = fail_with_;  // test hook (BackgroundSync's constructor)
    } else {
      while (::fdatasync(fd_) != 0) {
        if (errno == EINTR) continue;
        e = errno;
        break;
      }
    }
    lock.lock();
    served_ = upto;
    if (e != 0 && error_ == 0) error_ = e;
    if (stop_) return;  // requests made during this flush: the final fsync follows at once
  }
}

}  // namespace rtp
