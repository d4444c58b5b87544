#pragma once
// Opening input files safely: only regular files are read (a directory, FIFO, socket or device gets
// a clear message, and a FIFO never blocks in open()), and an output path is never one of the inputs
// (compared by device and inode, so hard links and other spellings of the same path are caught).
#include <cstdint>
#include <string>

namespace rtp {

// Opens `path` read-only (O_CLOEXEC | `extra_flags`), refusing anything but a regular file.
// The open uses O_NONBLOCK (cleared afterwards) so a FIFO cannot block; the type is checked with
// fstat on the opened descriptor. `what` names the file in messages ("ray file", "package"; may be
// empty). Returns the descriptor; `size` (optional) receives the file size.
// Throws Error(kInputIo): "cannot open 'P': is a directory", "... is not a regular file (a FIFO)",
// "... no such file", or the system's reason. With O_DIRECT in `extra_flags` and a filesystem that
// refuses it, the file is opened without O_DIRECT (check with fcntl(F_GETFL)).
int open_input_file(const std::string& path, const std::string& what = "", int extra_flags = 0, uint64_t* size = nullptr);

// Reads all of a regular file (open_input_file, then exactly its size). Throws Error(kInputIo).
std::string read_input_file(const std::string& path, const std::string& what = "");

// Reads exactly `size` bytes at `offset` of `fd` (path for messages). Throws Error(kInputIo) on a
// short read.
void read_exact(int fd, uint64_t offset, void* out, size_t size, const std::string& path);

// Throws Error(kUsage) when `output` names the same file as `input` (same device and inode, through
// any spelling, symbolic link or hard link). A missing output or input is never the same file.
void check_not_same_file(const std::string& input, const std::string& output);

}  // namespace rtp
