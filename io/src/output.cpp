#include <granflow/io/output.hpp>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <mutex>
#include <streambuf>
#include <thread>
#include <vector>

#include <granflow/io/sha256.hpp>

namespace granflow::io {

namespace fs = std::filesystem;

OutputError::OutputError(const std::string& message, int os_error)
    : std::runtime_error(message), os_error_(os_error) {}

bool OutputError::user_fixable() const {
  switch (os_error_) {
    case ENOSPC: case EDQUOT: case EROFS: case EACCES: case EPERM: case EFBIG: case ENOTDIR: case EISDIR:
    case ENAMETOOLONG: case EEXIST: case ENOENT: case ELOOP: case ENOTEMPTY: case EMLINK:
      return true;
    default:
      return false;
  }
}

std::string describe_os_error(const std::string& path, const std::string& action, int os_error) {
  std::string m = path + ": cannot " + action + ": " + std::strerror(os_error);
  switch (os_error) {
    case ENOSPC: return m + " (the file system is full: free space there, or write elsewhere)";
    case EDQUOT: return m + " (the disk quota is used up)";
    case EROFS: return m + " (the file system is mounted read-only: write elsewhere)";
    case EFBIG: return m + " (the file exceeds the size limit, see ulimit -f)";
    default: return m;
  }
}

// ---- fault injection ----------------------------------------------------------------------

namespace {

std::mutex g_fault_mutex;
WriteFault g_hook;

struct EnvFault {
  bool active = false;
  WriteStep at = WriteStep::Write;
  std::string file;
  std::size_t budget = 0, used = 0;
  int err = ENOSPC;
  bool tripped = false;
  long delay_ms = 0;  // every step of a matching file waits this long first
  bool fails = true;  // false: a delay only

  EnvFault() {
    const char* at_s = std::getenv("GRANFLOW_FAULT_AT");
    const char* file_s = std::getenv("GRANFLOW_FAULT_FILE");
    const char* bytes_s = std::getenv("GRANFLOW_FAULT_BYTES");
    const char* errno_s = std::getenv("GRANFLOW_FAULT_ERRNO");
    const char* delay_s = std::getenv("GRANFLOW_FAULT_DELAY_MS");
    active = at_s || file_s || bytes_s || delay_s;
    if (!active) return;
    if (delay_s) delay_ms = std::strtol(delay_s, nullptr, 10);
    fails = !delay_s || at_s || bytes_s;
    if (at_s) {
      const std::string a = at_s;
      at = a == "open" ? WriteStep::Open : a == "sync" ? WriteStep::Sync : a == "close" ? WriteStep::Close
         : a == "rename" ? WriteStep::Rename : WriteStep::Write;
    }
    if (file_s) file = file_s;
    if (bytes_s) budget = std::strtoull(bytes_s, nullptr, 10);
    if (errno_s) {
      const std::string e = errno_s;
      err = e == "EDQUOT" ? EDQUOT : e == "EIO" ? EIO : e == "EROFS" ? EROFS : e == "EACCES" ? EACCES
          : e == "EFBIG" ? EFBIG : ENOSPC;
    }
  }

  int operator()(const std::string& path, WriteStep step, std::size_t& bytes) {
    if (!active || path.find(file) == std::string::npos) return 0;
    if (delay_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
    if (!fails || step != at) return 0;
    if (tripped) return err;
    if (step != WriteStep::Write) {
      tripped = true;
      return err;
    }
    const std::size_t left = budget - used;
    if (bytes <= left) {
      used += bytes;
      return 0;
    }
    tripped = true;
    if (left == 0) return err;
    bytes = left;  // a short write, then the failure
    used = budget;
    return 0;
  }
};

}  // namespace

namespace {
std::atomic<int> g_critical_writes{0};
static_assert(std::atomic<int>::is_always_lock_free, "read in a signal handler");
}  // namespace

CriticalWrite::CriticalWrite() { ++g_critical_writes; }
CriticalWrite::~CriticalWrite() { --g_critical_writes; }
bool critical_write_active() { return g_critical_writes.load() > 0; }

WriteFault set_write_fault(WriteFault hook) {
  std::lock_guard<std::mutex> lk(g_fault_mutex);
  std::swap(g_hook, hook);
  return hook;
}

int write_fault(const std::string& path, WriteStep step, std::size_t& bytes) {
  std::lock_guard<std::mutex> lk(g_fault_mutex);
  if (g_hook) return g_hook(path, step, bytes);
  static EnvFault env;
  return env(path, step, bytes);
}

// ---- AtomicFile ---------------------------------------------------------------------------

// Buffers into the temporary's descriptor, hashing the bytes as they go out; the first failed
// write is kept for commit(). A piece of at least the buffer's size skips the copy into it.
class AtomicFile::Buffer : public std::streambuf {
 public:
  Buffer(int fd, const std::string& path) : fd_(fd), path_(path), buf_(1 << 16) {
    setp(buf_.data(), buf_.data() + buf_.size());
  }
  int error() const { return error_; }
  bool drain() {
    const bool ok = write_all(pbase(), static_cast<std::size_t>(pptr() - pbase()));
    setp(buf_.data(), buf_.data() + buf_.size());
    return ok;
  }
  // The digest and size of what was written; call once, after the last drain().
  std::string digest() { return hash_.hex(); }
  std::uint64_t written() const { return written_; }

 protected:
  int_type overflow(int_type c) override {
    if (!drain()) return traits_type::eof();
    if (!traits_type::eq_int_type(c, traits_type::eof())) {
      *pptr() = traits_type::to_char_type(c);
      pbump(1);
    }
    return traits_type::not_eof(c);
  }
  std::streamsize xsputn(const char* s, std::streamsize n) override {
    if (n < static_cast<std::streamsize>(buf_.size())) return std::streambuf::xsputn(s, n);
    return drain() && write_all(s, static_cast<std::size_t>(n)) ? n : 0;
  }
  int sync() override { return drain() ? 0 : -1; }

 private:
  // Pieces of at most 1 MiB: each is hashed while it is still in the cache.
  bool write_all(const char* p, std::size_t n) {
    if (error_) return false;
    while (n > 0) {
      std::size_t want = std::min<std::size_t>(n, 1 << 20);
      if (const int e = write_fault(path_, WriteStep::Write, want)) {
        error_ = e;
        return false;
      }
      const ssize_t k = ::write(fd_, p, want);
      if (k < 0 && errno == EINTR) continue;
      if (k <= 0) {
        error_ = k < 0 ? errno : EIO;
        return false;
      }
      hash_.update(std::string_view(p, static_cast<std::size_t>(k)));
      written_ += static_cast<std::uint64_t>(k);
      p += k;
      n -= static_cast<std::size_t>(k);
    }
    return true;
  }
  int fd_;
  const std::string& path_;
  std::vector<char> buf_;
  int error_ = 0;
  Sha256 hash_;
  std::uint64_t written_ = 0;
};

// ---- the files commit() wrote (write_manifest) --------------------------------------------

namespace {

std::mutex g_committed_mutex;
std::map<std::string, CommittedFile> g_committed;  // by absolute, normalised path

std::string registry_key(const std::string& path) {
  std::error_code ec;
  const fs::path a = fs::absolute(path, ec);
  return (ec ? fs::path(path) : a).lexically_normal().string();
}

std::int64_t nanoseconds(const struct timespec& t) { return std::int64_t(t.tv_sec) * 1000000000 + t.tv_nsec; }

bool same_file(const CommittedFile& c, const struct stat& st) {
  return c.device == static_cast<std::uint64_t>(st.st_dev) && c.inode == static_cast<std::uint64_t>(st.st_ino) &&
         c.size == static_cast<std::uint64_t>(st.st_size) && c.mtime_ns == nanoseconds(st.st_mtim) &&
         c.ctime_ns == nanoseconds(st.st_ctim);
}

}  // namespace

std::optional<CommittedFile> committed_file(const std::string& path) {
  const std::string key = registry_key(path);
  std::lock_guard<std::mutex> lk(g_committed_mutex);
  const auto it = g_committed.find(key);
  if (it == g_committed.end()) return std::nullopt;
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || !same_file(it->second, st)) return std::nullopt;
  return it->second;
}

std::string csv_field(std::string_view text, bool always) {
  const bool edge = !text.empty() && (text.front() == ' ' || text.back() == ' ');
  if (!always && !edge && text.find_first_of(",\"\r\n") == std::string_view::npos) return std::string(text);
  std::string q = "\"";
  for (char c : text) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string temporary_name(const std::string& path) { return path + ".tmp-" + std::to_string(::getpid()); }

bool is_temporary_name(const std::string& name) {
  const auto at = name.rfind(".tmp");
  if (at == std::string::npos || at == 0) return false;
  const std::string tail = name.substr(at + 4);
  if (tail.empty()) return true;
  if (tail.size() < 2 || tail[0] != '-') return false;
  return tail.find_first_not_of("0123456789", 1) == std::string::npos;
}

AtomicFile::AtomicFile(std::string path, Durability durability)
    : path_(std::move(path)), temporary_(temporary_name(path_)), durability_(durability) {
  std::size_t none = 0;
  if (const int e = write_fault(path_, WriteStep::Open, none)) fail("write", e);
  fd_ = ::open(temporary_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd_ < 0) fail("write", errno);
  buffer_ = std::make_unique<Buffer>(fd_, path_);
  stream_ = std::make_unique<std::ostream>(buffer_.get());
}

AtomicFile::~AtomicFile() {
  if (!committed_) discard();
}

std::ostream& AtomicFile::stream() { return *stream_; }

void AtomicFile::discard() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  ::unlink(temporary_.c_str());
}

void AtomicFile::fail(const std::string& action, int err) {
  discard();
  struct stat st {};
  const bool had = ::stat(path_.c_str(), &st) == 0;
  throw OutputError(describe_os_error(path_, action, err) +
                        (had ? "; the file keeps its previous content" : "; nothing was written"),
                    err);
}

void AtomicFile::commit() {
  if (committed_) return;
  stream_->flush();
  if (!buffer_->drain() || buffer_->error()) fail("write", buffer_->error() ? buffer_->error() : EIO);
  const std::string digest = buffer_->digest();
  const std::uint64_t size = buffer_->written();
  std::size_t none = 0;
  if (durability_ == Durability::Sync) {
    int e = write_fault(path_, WriteStep::Sync, none);
    if (!e && ::fsync(fd_) != 0) e = errno;
    if (e) fail("write", e);
  }
  int e = write_fault(path_, WriteStep::Close, none);
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0 && !e) e = errno;  // NFS and quotas report late errors here
  if (e) fail("write", e);
  e = write_fault(path_, WriteStep::Rename, none);
  if (!e && ::rename(temporary_.c_str(), path_.c_str()) != 0) e = errno;
  if (e) fail("replace", e);
  committed_ = true;
  record(digest, size);
  if (durability_ == Durability::Sync) {
    // the new name on disk too; best effort: the file is in place whatever this says
    const fs::path parent = fs::path(path_).parent_path();
    const int dfd = ::open(parent.empty() ? "." : parent.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd >= 0) {
      (void)::fsync(dfd);
      ::close(dfd);
    }
  }
}

void AtomicFile::record(const std::string& digest, std::uint64_t size) const {
  struct stat st {};
  const std::string key = registry_key(path_);
  std::lock_guard<std::mutex> lk(g_committed_mutex);
  if (::stat(path_.c_str(), &st) != 0 || static_cast<std::uint64_t>(st.st_size) != size) {
    g_committed.erase(key);  // changed already: write_manifest reads it
    return;
  }
  CommittedFile& c = g_committed[key];
  c.sha256 = digest;
  c.size = size;
  c.synced = durability_ == Durability::Sync;
  c.device = static_cast<std::uint64_t>(st.st_dev);
  c.inode = static_cast<std::uint64_t>(st.st_ino);
  c.mtime_ns = nanoseconds(st.st_mtim);
  c.ctime_ns = nanoseconds(st.st_ctim);
}

void write_file(const std::string& path, std::string_view bytes, Durability durability) {
  AtomicFile f(path, durability);
  f.write(bytes);
  f.commit();
}

// ---- folders ------------------------------------------------------------------------------

bool make_folder(const std::string& dir) {
  std::error_code ec;
  if (fs::is_directory(dir, ec)) return false;
  // name the component in the way, not the OS's "File exists"
  fs::path prefix;
  for (const auto& part : fs::path(dir)) {
    prefix /= part;
    const auto st = fs::status(prefix, ec);
    if (ec) break;
    if (fs::exists(st) && !fs::is_directory(st))
      throw OutputError(prefix.string() + ": is a file, not a folder (" + dir + " cannot be created)", ENOTDIR);
  }
  const bool made = fs::create_directories(dir, ec);
  if (ec) throw OutputError(describe_os_error(dir, "create the folder", ec.value()), ec.value());
  return made;
}

void sync_path(const std::string& path) {
  std::size_t none = 0;
  int e = write_fault(path, WriteStep::Sync, none);
  if (e) throw OutputError(describe_os_error(path, "write", e), e);
  struct stat st {};
  const bool dir = ::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | (dir ? O_DIRECTORY : 0));
  if (fd < 0) throw OutputError(describe_os_error(path, "open", errno), errno);
  if (::fsync(fd) != 0 && !(dir && errno == EINVAL)) e = errno;
  ::close(fd);
  if (e) throw OutputError(describe_os_error(path, "write", e), e);
}

void remove_file(const std::string& path) {
  if (::unlink(path.c_str()) != 0 && errno != ENOENT)
    throw OutputError(describe_os_error(path, "remove", errno), errno);
}

}  // namespace granflow::io
