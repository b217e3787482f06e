// The one way granflow writes a file: to a temporary name beside it, every write and the close
// checked, flushed to disk where asked, then renamed over the target. A failure leaves the
// target as it was (absent, or its previous content), removes the temporary and throws an
// OutputError naming the file and the OS reason. Standard library and POSIX only.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <ostream>
#include <stdexcept>
#include <string>
#include <string_view>

namespace granflow::io {

// A file or folder could not be written. The message names the path and the OS reason.
class OutputError : public std::runtime_error {
 public:
  OutputError(const std::string& message, int os_error);
  int os_error() const { return os_error_; }
  // Full disk or quota, read-only or forbidden folder, a name that cannot be made, a file
  // size limit: the user can fix these (granflow exits 2). EIO and the like exit 1.
  bool user_fixable() const;

 private:
  int os_error_;
};

// "PATH: cannot ACTION (OS reason[, hint])", the hint saying what to do about a full disk etc.
std::string describe_os_error(const std::string& path, const std::string& action, int os_error);

// Durability of a committed file. Sync: the file's bytes and its name are on disk when commit()
// returns (checkpoints, a run's final outputs); Buffered: left to the OS (intermediate frames).
enum class Durability { Buffered, Sync };

// A file being written. stream() buffers into the temporary; nothing appears under `path`
// until commit(). Destroyed without commit() (an exception on the way), the temporary goes.
// The bytes are hashed (SHA-256) as they go to the OS; commit() records the digest for
// write_manifest (committed_file below), which then need not read the file back.
class AtomicFile {
 public:
  explicit AtomicFile(std::string path, Durability durability = Durability::Sync);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  std::ostream& stream();
  void write(std::string_view bytes) { stream().write(bytes.data(), static_cast<std::streamsize>(bytes.size())); }
  // Flushes, checks, (syncs,) closes and renames; throws OutputError with the temporary removed.
  void commit();
  const std::string& path() const { return path_; }

 private:
  class Buffer;
  [[noreturn]] void fail(const std::string& action, int err);
  void discard() noexcept;
  void record(const std::string& digest, std::uint64_t size) const;  // committed_file()
  std::string path_, temporary_;
  Durability durability_;
  int fd_ = -1;
  bool committed_ = false;
  std::unique_ptr<Buffer> buffer_;
  std::unique_ptr<std::ostream> stream_;
};

// What AtomicFile::commit() left at a path: the digest and size of the bytes it wrote, and the
// file's identity after the rename (stat). A later change of the file (a write, a truncation, a
// replacement) changes its size, inode, modification or change time.
struct CommittedFile {
  std::string sha256;
  std::uint64_t size = 0;
  bool synced = false;  // Durability::Sync: on disk since the commit
  std::uint64_t device = 0, inode = 0;
  std::int64_t mtime_ns = 0, ctime_ns = 0;
};
// The record of the last commit to `path` (any spelling of it), where the file there is still
// the one committed: same inode, size, modification and change time. Otherwise nullopt.
// A change within the file system's timestamp granularity after the commit that keeps the size
// would go unseen; Linux 6.13+ gives such a change a finer time (multigrain timestamps).
std::optional<CommittedFile> committed_file(const std::string& path);

// The whole file at once, through an AtomicFile.
void write_file(const std::string& path, std::string_view bytes, Durability durability = Durability::Sync);

// A text cell of a CSV row (RFC 4180): quoted, with inner quotes doubled, when it holds a comma,
// a quote, a line break or edge spaces, or always with `always`; as given otherwise.
std::string csv_field(std::string_view text, bool always = false);

// The temporary name a write uses ("NAME.tmp-PID"); is_temporary_name() also knows "NAME.tmp".
std::string temporary_name(const std::string& path);
bool is_temporary_name(const std::string& file_name);

// A write that a second Ctrl-C should not cut short (a checkpoint, the one a --restart needs):
// while one lives, critical_write_active() is true, and granflow's SIGINT/SIGTERM handler
// (cli/mpm_common.hpp) lets it finish before the process stops. Async-signal-safe to query.
class CriticalWrite {
 public:
  CriticalWrite();
  ~CriticalWrite();
  CriticalWrite(const CriticalWrite&) = delete;
  CriticalWrite& operator=(const CriticalWrite&) = delete;
};
bool critical_write_active();

// Creates `dir` and its parents; OutputError when it cannot (a regular file in the way, a
// read-only or forbidden parent, ...). Returns true when it created the last component.
bool make_folder(const std::string& dir);
// fsync of an existing file (opened read-only) or folder; OutputError on failure (a folder's
// EINVAL, where the file system does not sync folders, is not one).
void sync_path(const std::string& path);
// Removes a file; OutputError unless it is gone afterwards.
void remove_file(const std::string& path);

// ---- fault injection (tests) ----------------------------------------------------------------
// The steps of a write. The hook is asked before each one; a non-zero return is an errno the
// step fails with, as if the OS had returned it. For Write, `bytes` is what the call would write
// and may be lowered (a short write; the next call then fails). `path` is the target's name.
enum class WriteStep { Open, Write, Sync, Close, Rename };
using WriteFault = std::function<int(const std::string& path, WriteStep step, std::size_t& bytes)>;
// Installs a hook (empty: none) and returns the previous one. Without a hook set here, the
// environment gives one (read once):
//   GRANFLOW_FAULT_AT     open|write|sync|close|rename (default write)
//   GRANFLOW_FAULT_FILE   only targets whose path contains this text (default: every file)
//   GRANFLOW_FAULT_BYTES  write: bytes the matching files may take in all before it fails (default 0)
//   GRANFLOW_FAULT_ERRNO  ENOSPC (default), EDQUOT, EIO, EROFS, EACCES or EFBIG
//   GRANFLOW_FAULT_DELAY_MS  every step of the matching files first waits this long; alone
//                         (without _AT or _BYTES) nothing fails: a slow disk
// Once a step has failed, every later matching step fails too, as on a disk that stays full.
WriteFault set_write_fault(WriteFault hook);
// The hook in force for one step (0: none); used by this layer and the lock file writer.
int write_fault(const std::string& path, WriteStep step, std::size_t& bytes);

}  // namespace granflow::io
