// Run folders (granflow mpm, granflow calibrate): one run at a time owns a folder through a lock
// file; a run that ends by itself leaves a manifest of every file; --force replaces only a folder
// granflow made, --restart continues one that has a checkpoint. Formats: docs/reliability_outputs.md.
#pragma once

#include <cstdint>
#include <memory>

#include "output.hpp"
#include <string>
#include <vector>

namespace granflow::io {

inline constexpr const char* kLockFile = "granflow.lock";
inline constexpr const char* kManifestFile = "granflow.manifest";

// Exclusive ownership of an output, held from the constructor to release(): the file
// `lock_path` names this process (pid, host) and is flock'ed. A lock held by a live run is
// refused with an InputError naming that run; one left by a run that is gone (same host) is
// taken over, and took_over() says whose it was.
class OutputLock {
 public:
  // `what` names the protected output in messages, e.g. "output folder 'o'".
  OutputLock(std::string lock_path, const std::string& what);
  ~OutputLock() { release(); }
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;
  // Unlocks; `remove` deletes the lock file first (otherwise it stays, unlocked, as a marker).
  void release(bool remove = true) noexcept;
  // Unlocks leaving the file as it was found (a refused run changes nothing, a stale lock included).
  void release_unchanged() noexcept;
  const std::string& took_over() const { return took_over_; }  // "pid N on host H", or empty
  const std::string& path() const { return path_; }

 private:
  std::string path_, took_over_, previous_;
  int fd_ = -1;
};

// The owner a lock file names ("pid N on host H"), empty when it cannot be read.
std::string lock_owner(const std::string& lock_path);

// ---- manifests ----------------------------------------------------------------------------

struct ManifestEntry {
  std::string name, sha256;
  std::uint64_t size = 0;
};
struct Manifest {
  std::string status;  // "complete", "stopped at ...", "failed: ..."
  std::vector<ManifestEntry> files;
};
// Syncs every regular file below `dir` (not the lock, the manifest or temporaries) to disk, then
// writes the manifest listing them by relative path ("png/runout.png") with size and SHA-256.
// A file an AtomicFile committed and nothing changed since (committed_file) is not read back:
// its digest is the one computed as it was written, and it is synced only if it was Buffered.
void write_manifest(const std::string& dir, const std::string& status);
// Reads DIR/granflow.manifest (InputError when it is absent or malformed).
Manifest read_manifest(const std::string& dir);
// What does not match the manifest: missing, changed and unlisted files (empty: all good).
std::vector<std::string> verify_manifest(const std::string& dir);

// ---- a folder a run writes in place (granflow mpm) ----------------------------------------

enum class FolderUse {
  Fresh,    // the folder must be absent or empty
  Force,    // a granflow run folder is emptied first (subfolders too); anything else is refused
  Restart,  // the folder must exist; the caller checks its checkpoint, then keep_only()
};

class RunFolder {
 public:
  // Creates the folder where needed, takes its lock, then applies `use` (errors: InputError,
  // OutputError). `checkpoint` names the run's checkpoint file (a marker of a run folder).
  RunFolder(std::string dir, FolderUse use, std::string checkpoint);
  // Without complete(): the lock goes, and so does a folder this created and nothing was written
  // to; where outputs but no checkpoint remain, the lock file stays (unlocked) to mark them.
  ~RunFolder();
  RunFolder(const RunFolder&) = delete;
  RunFolder& operator=(const RunFolder&) = delete;

  // --restart, once the checkpoint is accepted: removes everything but the files `names` and
  // the lock (frames written after the checkpoint, a stopped run's final frame, manifest and
  // snapshot folder, temporaries).
  void keep_only(const std::vector<std::string>& names);
  // The run ended by itself: writes the manifest as the last act and releases the lock.
  void complete(const std::string& status);
  const std::string& dir() const { return dir_; }

 private:
  void engage();     // the run uses the folder from here on
  void disengage();  // leaves the folder as found (a refused run)
  std::string dir_, checkpoint_;
  bool created_ = false, completed_ = false, engaged_ = false;
  std::unique_ptr<OutputLock> lock_;
};

// ---- a folder made aside and swapped in at the end (granflow calibrate) ------------------

class StagedFolder {
 public:
  // Locks DIR.lock beside DIR; refuses an existing DIR unless `force` and DIR holds a manifest.
  StagedFolder(std::string dir, bool force);
  ~StagedFolder();  // not committed: the staging folder goes, and the lock
  StagedFolder(const StagedFolder&) = delete;
  StagedFolder& operator=(const StagedFolder&) = delete;

  // DIR.tmp-PID, created on first use: the run writes its files here.
  const std::string& staging();
  // Writes the manifest into the staging folder, then puts it in DIR's place (the old DIR is
  // removed only once the new one is there) and releases the lock.
  void commit(const std::string& status);
  // A write into the staging folder failed: the same error, naming the file under DIR and
  // saying what DIR holds now (its previous results, or nothing).
  OutputError explain(const OutputError& e) const;
  const std::string& dir() const { return dir_; }

 private:
  std::string dir_, staging_;
  bool force_ = false, committed_ = false;
  std::unique_ptr<OutputLock> lock_;
};

// Notes for the user (a stale lock taken over, a leftover removed) go here; default stderr.
void set_note_sink(void (*sink)(const std::string& line));
void note(const std::string& line);

}  // namespace granflow::io
