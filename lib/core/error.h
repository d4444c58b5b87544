#pragma once
// Errors and exit codes shared by every rtpack tool (documented in docs/exit-codes.md).
#include <stdexcept>
#include <string>

namespace rtp {

// Exit codes of every rtpack tool. Stable: scripts depend on them.
enum class ExitCode : int {
  kOk = 0,
  kUsage = 1,         // bad command line
  kInputIo = 2,       // input cannot be opened or read
  kInputInvalid = 3,  // input is malformed or unsupported (message names the JSON pointer / chunk)
  kOutput = 4,        // output cannot be written
  kInternal = 5,      // a bug: please report
};

// An error with the exit code a tool should return for it.
class Error : public std::runtime_error {
 public:
  Error(ExitCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
  ExitCode code() const { return code_; }

 private:
  ExitCode code_;
};

[[noreturn]] inline void fail_invalid(const std::string& message) { throw Error(ExitCode::kInputInvalid, message); }

}  // namespace rtp
