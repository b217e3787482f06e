#include <granflow/io/run_folder.hpp>

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <thread>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <sstream>

#include <granflow/io/input_error.hpp>
#include <granflow/io/output.hpp>
#include <granflow/io/sha256.hpp>

namespace granflow::io {

namespace fs = std::filesystem;

namespace {

void default_sink(const std::string& line) { std::cerr << "granflow: note: " << line << "\n"; }
void (*g_sink)(const std::string&) = default_sink;

std::string host_name() {
  char buf[256] = {};
  if (::gethostname(buf, sizeof buf - 1) != 0) return "unknown";
  return buf;
}

bool process_alive(long pid) { return pid > 0 && (::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM); }

struct LockContent {
  long pid = 0;
  std::string host;
  std::string owner() const { return "pid " + std::to_string(pid) + " on host " + host; }
};

LockContent parse_lock(const std::string& text) {
  LockContent c;
  std::istringstream is(text);
  for (std::string key, value; is >> key >> value;) {
    if (key == "pid") c.pid = std::atol(value.c_str());
    if (key == "host") c.host = value;
  }
  return c;
}

std::string read_fd(int fd) {
  std::string s;
  char buf[4096];
  for (off_t at = 0;;) {
    const ssize_t k = ::pread(fd, buf, sizeof buf, at);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) break;
    s.append(buf, static_cast<std::size_t>(k));
    at += k;
    if (s.size() > 65536) break;
  }
  return s;
}

// Regular files and other entries of a folder, by name, sorted.
std::vector<std::string> entries(const std::string& dir, bool regular_only = false) {
  std::vector<std::string> names;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code e2;
    if (regular_only && !it->is_regular_file(e2)) continue;
    names.push_back(it->path().filename().string());
  }
  if (ec) throw OutputError(describe_os_error(dir, "read the folder", ec.value()), ec.value());
  std::sort(names.begin(), names.end());
  return names;
}

// Regular files below `dir`, as paths relative to it ("png/runout.png"), sorted.
std::vector<std::string> files_below(const std::string& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code e2;
    if (it->is_regular_file(e2)) names.push_back(fs::relative(it->path(), dir, e2).generic_string());
  }
  if (ec) throw OutputError(describe_os_error(dir, "read the folder", ec.value()), ec.value());
  std::sort(names.begin(), names.end());
  return names;
}

// Removes a file or a folder with what it holds.
void remove_entry(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(fs::symlink_status(path, ec))) {
    fs::remove_all(path, ec);
    if (ec) throw OutputError(describe_os_error(path, "remove", ec.value()), ec.value());
  } else {
    remove_file(path);
  }
}

bool has(const std::vector<std::string>& names, const std::string& n) {
  return std::find(names.begin(), names.end(), n) != names.end();
}

std::string join(const std::string& dir, const std::string& name) { return (fs::path(dir) / name).string(); }

// "a/b/" -> "a/b": the folder's own name must be the last component.
std::string trimmed(std::string dir) {
  while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
  return dir;
}

}  // namespace

void set_note_sink(void (*sink)(const std::string&)) { g_sink = sink ? sink : default_sink; }
void note(const std::string& line) { g_sink(line); }

// ---- OutputLock ---------------------------------------------------------------------------

std::string lock_owner(const std::string& lock_path) {
  const int fd = ::open(lock_path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return "";
  const LockContent c = parse_lock(read_fd(fd));
  ::close(fd);
  return c.pid > 0 ? c.owner() : "";
}

OutputLock::OutputLock(std::string lock_path, const std::string& what) : path_(std::move(lock_path)) {
  const std::string host = host_name();
  for (int attempt = 0;; ++attempt) {
    const int fd = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) throw OutputError(describe_os_error(path_, "create the lock file", errno), errno);
    bool kernel_lock = true;
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const int e = errno;
      if (e == EWOULDBLOCK) {
        // The owner writes its pid right after taking the lock: give it a moment to appear.
        LockContent c = parse_lock(read_fd(fd));
        for (int wait = 0; c.pid == 0 && wait < 50; ++wait) {
          std::this_thread::sleep_for(std::chrono::milliseconds(2));
          c = parse_lock(read_fd(fd));
        }
        ::close(fd);
        throw InputError(what + " is in use by another granflow run (" +
                         (c.pid > 0 ? c.owner() + ", " : std::string()) + "lock file " + path_ +
                         "): wait until it has finished, or choose another --out");
      }
      kernel_lock = false;  // a file system without flock: the pid in the file decides
    }
    // The owner may have removed the file between our open and flock: lock the file at the name.
    struct stat held {}, named {};
    if (::fstat(fd, &held) != 0 || ::stat(path_.c_str(), &named) != 0 || held.st_ino != named.st_ino ||
        held.st_dev != named.st_dev) {
      ::close(fd);
      if (attempt < 10) continue;
      throw InputError(what + ": its lock file " + path_ + " keeps changing; is another run starting there?");
    }
    previous_ = read_fd(fd);
    const LockContent old = parse_lock(previous_);
    if (old.pid > 0) {
      if (old.host != host) {
        ::close(fd);
        throw InputError(what + " is locked by " + old.owner() + " (lock file " + path_ + "); if no run on " +
                         old.host + " uses it any more, remove that file");
      }
      if (!kernel_lock && old.pid != ::getpid() && process_alive(old.pid)) {
        ::close(fd);
        throw InputError(what + " is in use by another granflow run (" + old.owner() + ", lock file " + path_ +
                         "): wait until it has finished, or choose another --out");
      }
      took_over_ = old.owner();
    }
    const std::string text = "granflow lock\npid " + std::to_string(::getpid()) + "\nhost " + host + "\n";
    std::size_t n = text.size();
    int e = write_fault(path_, WriteStep::Write, n);
    if (!e && ::ftruncate(fd, 0) != 0) e = errno;
    if (!e) {
      const ssize_t k = ::pwrite(fd, text.data(), n, 0);
      if (k < 0) e = errno;
      else if (static_cast<std::size_t>(k) < text.size()) e = ENOSPC;
    }
    if (e) {
      if (old.pid == 0) ::unlink(path_.c_str());  // ours, and empty
      ::close(fd);
      throw OutputError(describe_os_error(path_, "write the lock file", e), e);
    }
    fd_ = fd;
    return;
  }
}

void OutputLock::release_unchanged() noexcept {
  if (fd_ < 0) return;
  if (previous_.empty()) {
    release(true);
    return;
  }
  if (::ftruncate(fd_, 0) == 0) (void)!::pwrite(fd_, previous_.data(), previous_.size(), 0);
  release(false);
}

void OutputLock::release(bool remove) noexcept {
  if (fd_ < 0) return;
  if (remove) ::unlink(path_.c_str());  // while still locked: see the inode check above
  ::close(fd_);
  fd_ = -1;
}

// ---- manifests ----------------------------------------------------------------------------

namespace {

constexpr const char* kManifestHeader =
    "# granflow run manifest 1: SHA-256, size in bytes and name of every file in this folder\n";

bool listed_in_manifest(const std::string& relative) {
  const std::string name = fs::path(relative).filename().string();
  return relative != kLockFile && relative != kManifestFile && !is_temporary_name(name);
}

ManifestEntry hash_file(const std::string& path, const std::string& name, bool sync) {
  ManifestEntry e;
  e.name = name;
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw OutputError(describe_os_error(path, "read back", errno), errno);
  Sha256 h;
  std::vector<char> buf(1 << 20);
  for (;;) {
    const ssize_t k = ::read(fd, buf.data(), buf.size());
    if (k < 0 && errno == EINTR) continue;
    if (k < 0) {
      const int err = errno;
      ::close(fd);
      throw OutputError(describe_os_error(path, "read back", err), err);
    }
    if (k == 0) break;
    h.update(std::string_view(buf.data(), static_cast<std::size_t>(k)));
    e.size += static_cast<std::uint64_t>(k);
  }
  int err = 0;
  if (sync) {
    std::size_t none = 0;
    err = write_fault(path, WriteStep::Sync, none);
    if (!err && ::fsync(fd) != 0) err = errno;
  }
  ::close(fd);
  if (err) throw OutputError(describe_os_error(path, "write", err), err);
  e.sha256 = h.hex();
  return e;
}

// A file as AtomicFile::commit() left it is not read again: its digest is the one computed as
// it was written, and a file committed with Durability::Sync is on disk already. Any other
// file, or one changed since, is read back and synced.
ManifestEntry committed_entry(const std::string& path, const std::string& name) {
  const std::optional<CommittedFile> c = committed_file(path);
  if (!c) return hash_file(path, name, true);
  if (!c->synced) sync_path(path);
  ManifestEntry e;
  e.name = name;
  e.sha256 = c->sha256;
  e.size = c->size;
  return e;
}

}  // namespace

void write_manifest(const std::string& dir, const std::string& status) {
  std::string text = kManifestHeader;
  std::string one_line = status;
  std::replace(one_line.begin(), one_line.end(), '\n', ' ');
  text += "# status: " + one_line + "\n";
  for (const auto& name : files_below(dir)) {
    if (!listed_in_manifest(name)) continue;
    const ManifestEntry e = committed_entry(join(dir, name), name);
    text += e.sha256 + "  " + std::to_string(e.size) + "  " + e.name + "\n";
  }
  write_file(join(dir, kManifestFile), text, Durability::Sync);
}

Manifest read_manifest(const std::string& dir) {
  const std::string path = join(dir, kManifestFile);
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw InputError(where(path) + "cannot open the manifest (" + std::strerror(errno) + ")");
  std::string text;
  char buf[65536];
  for (ssize_t k; (k = ::read(fd, buf, sizeof buf)) != 0;) {
    if (k < 0 && errno == EINTR) continue;
    if (k < 0) break;
    text.append(buf, static_cast<std::size_t>(k));
  }
  ::close(fd);
  Manifest m;
  std::istringstream is(text);
  std::string line;
  long no = 0;
  if (!std::getline(is, line) || line + "\n" != kManifestHeader)
    throw InputError(where(path, 1) + "not a granflow run manifest");
  ++no;
  while (std::getline(is, line)) {
    ++no;
    if (line.rfind("# status: ", 0) == 0) {
      m.status = line.substr(10);
      continue;
    }
    if (!line.empty() && line[0] == '#') continue;
    std::istringstream ls(line);
    ManifestEntry e;
    if (!(ls >> e.sha256 >> e.size >> e.name) || e.sha256.size() != 64)
      throw InputError(where(path, no) + "expected 'SHA256  SIZE  NAME', got '" + line + "'");
    m.files.push_back(e);
  }
  return m;
}

std::vector<std::string> verify_manifest(const std::string& dir) {
  const Manifest m = read_manifest(dir);
  std::vector<std::string> problems;
  std::vector<std::string> listed;
  for (const auto& e : m.files) {
    listed.push_back(e.name);
    const std::string p = join(dir, e.name);
    std::error_code ec;
    if (!fs::is_regular_file(p, ec)) {
      problems.push_back(e.name + ": missing");
      continue;
    }
    const ManifestEntry now = hash_file(p, e.name, false);
    if (now.size != e.size) problems.push_back(e.name + ": " + std::to_string(now.size) + " bytes, the manifest says " +
                                               std::to_string(e.size));
    else if (now.sha256 != e.sha256) problems.push_back(e.name + ": checksum differs");
  }
  for (const auto& name : files_below(dir))
    if (listed_in_manifest(name) && !has(listed, name)) problems.push_back(name + ": not in the manifest");
  return problems;
}

// ---- RunFolder ----------------------------------------------------------------------------

RunFolder::RunFolder(std::string dir, FolderUse use, std::string checkpoint)
    : dir_(trimmed(std::move(dir))), checkpoint_(std::move(checkpoint)) {
  std::error_code ec;
  const auto st = fs::status(dir_, ec);
  if (fs::exists(st) && !fs::is_directory(st))
    throw InputError(where(dir_) + "is a file, not a folder: --out names the run's output folder");
  if (use == FolderUse::Restart && !fs::exists(st))
    throw InputError("--restart: output directory '" + dir_ +
                     "' does not exist: nothing to continue (start the run without --restart)");
  created_ = make_folder(dir_);
  try {
    lock_ = std::make_unique<OutputLock>(join(dir_, kLockFile), "output folder '" + dir_ + "'");
    std::vector<std::string> names = entries(dir_);
    names.erase(std::remove(names.begin(), names.end(), std::string(kLockFile)), names.end());
    const bool ckpt = !checkpoint_.empty() && has(names, checkpoint_);
    if (use == FolderUse::Fresh && !names.empty())
      throw InputError("output directory '" + dir_ + "' exists and is not empty; use --force to overwrite it" +
                       (ckpt ? " or --restart to continue from its checkpoint" : ""));
    if (use == FolderUse::Force && !names.empty() && !has(names, kManifestFile) && !ckpt &&
        lock_->took_over().empty())
      throw InputError("output directory '" + dir_ + "' is not a granflow run folder (it has no " + kManifestFile +
                       ", " + kLockFile + (checkpoint_.empty() ? "" : " or " + checkpoint_) +
                       "): --force replaces only folders granflow wrote; remove it yourself or choose another --out");
    if (use != FolderUse::Restart) engage();
    if (use == FolderUse::Force)
      for (const auto& n : entries(dir_))
        if (n != kLockFile) remove_entry(join(dir_, n));
  } catch (...) {
    disengage();
    throw;
  }
}

void RunFolder::engage() {
  if (engaged_) return;
  engaged_ = true;
  if (!lock_->took_over().empty())
    note(lock_->path() + ": took over the lock of " + lock_->took_over() + ", a run that is no longer running");
}

void RunFolder::disengage() {
  if (!lock_) {
    if (created_) ::rmdir(dir_.c_str());
    return;
  }
  if (!lock_->took_over().empty()) {
    lock_->release_unchanged();
    return;
  }
  lock_->release(true);
  if (created_) ::rmdir(dir_.c_str());
}

RunFolder::~RunFolder() {
  if (completed_ || !lock_) return;
  if (!engaged_) {
    disengage();
    return;
  }
  try {
    auto names = entries(dir_);
    names.erase(std::remove(names.begin(), names.end(), std::string(kLockFile)), names.end());
    if (names.empty()) {
      lock_->release(true);
      if (created_) ::rmdir(dir_.c_str());
    } else {
      // outputs without a checkpoint or manifest: the lock file stays to mark them as a run's
      lock_->release(has(names, kManifestFile) || (!checkpoint_.empty() && has(names, checkpoint_)));
    }
  } catch (...) {
    lock_->release(false);
  }
}

void RunFolder::keep_only(const std::vector<std::string>& names) {
  engage();
  for (const auto& n : entries(dir_))
    if (n != kLockFile && !has(names, n)) remove_entry(join(dir_, n));
}

void RunFolder::complete(const std::string& status) {
  engage();
  write_manifest(dir_, status);
  lock_->release(true);
  completed_ = true;
}

// ---- StagedFolder -------------------------------------------------------------------------

StagedFolder::StagedFolder(std::string dir, bool force) : dir_(trimmed(std::move(dir))), force_(force) {
  const fs::path target(dir_);
  const std::string parent = target.parent_path().empty() ? "." : target.parent_path().string();
  std::error_code ec;
  const auto st = fs::status(dir_, ec);
  if (fs::exists(st) && !fs::is_directory(st))
    throw InputError(where(dir_) + "is a file, not a folder: --out names the folder of the results");
  make_folder(parent);
  lock_ = std::make_unique<OutputLock>(dir_ + ".lock", "output folder '" + dir_ + "'");
  if (fs::exists(fs::status(dir_, ec))) {
    std::string refusal;
    if (!force_)
      refusal = where(dir_) + "output directory exists; pass --force to replace it";
    else if (!fs::exists(join(dir_, kManifestFile), ec) && !fs::is_empty(dir_, ec))
      refusal = where(dir_) + "not a granflow run folder (it has no " + kManifestFile +
                "): --force replaces only folders granflow wrote; remove it yourself or choose another --out";
    if (!refusal.empty()) {
      lock_->release_unchanged();
      throw InputError(refusal);
    }
  }
  if (!lock_->took_over().empty())
    note(lock_->path() + ": took over the lock of " + lock_->took_over() + ", a run that is no longer running");
  // Folders NAME.tmp-PID / NAME.old-PID of runs that died before they finished (we hold the lock).
  const std::string stem = target.filename().string();
  for (const auto& n : entries(parent)) {
    for (const char* kind : {".tmp-", ".old-"}) {
      const std::string pre = stem + kind;
      if (n.rfind(pre, 0) != 0 || n.size() == pre.size()) continue;
      const std::string digits = n.substr(pre.size());
      if (digits.find_first_not_of("0123456789") != std::string::npos) continue;
      const long pid = std::atol(digits.c_str());
      if (pid == ::getpid() || process_alive(pid) || !fs::is_directory(join(parent, n), ec)) continue;
      fs::remove_all(join(parent, n), ec);
      if (!ec) note("removed " + join(parent, n) + ", left by a run (pid " + digits + ") that did not finish");
    }
  }
}

StagedFolder::~StagedFolder() {
  if (!committed_ && !staging_.empty()) {
    std::error_code ec;
    fs::remove_all(staging_, ec);
  }
}

const std::string& StagedFolder::staging() {
  if (staging_.empty()) {
    const std::string s = dir_ + ".tmp-" + std::to_string(::getpid());
    std::error_code ec;
    fs::remove_all(s, ec);
    make_folder(s);
    staging_ = s;
  }
  return staging_;
}

OutputError StagedFolder::explain(const OutputError& e) const {
  std::string m = e.what();
  if (!staging_.empty())
    for (std::size_t at; (at = m.find(staging_ + "/")) != std::string::npos;) m.replace(at, staging_.size(), dir_);
  std::error_code ec;
  m += fs::exists(dir_, ec) ? "; " + dir_ + " keeps its previous results" : "; no " + dir_ + " was made";
  return OutputError(m, e.os_error());
}

void StagedFolder::commit(const std::string& status) {
  write_manifest(staging(), status);
  std::error_code ec;
  std::size_t none = 0;
  int e = write_fault(dir_, WriteStep::Rename, none);
  const std::string old = dir_ + ".old-" + std::to_string(::getpid());
  const bool replace = fs::exists(dir_, ec);
  if (!e && replace && ::rename(dir_.c_str(), old.c_str()) != 0) e = errno;
  if (e) throw OutputError(describe_os_error(dir_, "replace the folder", e), e);
  if (::rename(staging_.c_str(), dir_.c_str()) != 0) {
    e = errno;
    if (replace) ::rename(old.c_str(), dir_.c_str());
    throw OutputError(describe_os_error(dir_, "put the results in place", e), e);
  }
  committed_ = true;
  if (replace) fs::remove_all(old, ec);
  try {
    sync_path(fs::path(dir_).parent_path().empty() ? "." : fs::path(dir_).parent_path().string());
  } catch (const OutputError&) {
    // the results are in place; a file system that cannot sync folders changes nothing here
  }
  lock_->release(true);
}

}  // namespace granflow::io
