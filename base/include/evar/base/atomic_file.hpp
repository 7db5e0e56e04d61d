#pragma once
// A file that appears whole or not at all. The node's outputs (meshes, pictures, reports,
// session files) are written through it: the bytes go to "<name>.partial-XXXXXX" beside
// the target, are flushed to the disk, the close is checked (NFS and quotas report late),
// and the file is renamed over the target, then the directory is synced so the rename
// survives a power cut. A writer killed or failing half-way leaves the old file, or none,
// never a truncated one. The new file gets the old one's permissions (or, for a new file,
// those the umask gives), and a file we may not write is not replaced.
//
// Written in place, as a plain write would: a target that is a symbolic link (its file
// keeps its links and owner), one that is not a regular file (a device such as /dev/null
// or /dev/full, a FIFO), and an existing file in a folder we may not write to. Those are
// never removed.
#include <filesystem>
#include <string>
#include <string_view>

#include "evar/base/unique_fd.hpp"

namespace evar::base {

/// How far a finished file is pushed before commit() returns.
enum class Durability {
  Synced,    ///< the file and its directory are on the disk (fsync): finished reports, meshes, indices
  Deferred,  ///< renamed into place, left in the page cache: files rewritten often on a thread
             ///< that must not wait for the disk (a recording's frames and its report in
             ///< progress, the node's snapshots); whoever needs them on the disk syncs later
};

class AtomicFile {
 public:
  /// Opens the partial file beside `target` (or the target itself, see above);
  /// std::system_error naming the target when it cannot.
  explicit AtomicFile(std::filesystem::path target, Durability durability = Durability::Synced);
  /// Not committed: the partial file is removed and the target left as it was.
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  /// Appends (buffered); std::system_error naming the target on failure ("disk full?" for
  /// ENOSPC and EDQUOT).
  void write(std::string_view bytes);
  /// Flushes, syncs as `durability` says, closes with its result checked and renames the
  /// file into place. Nothing may be written after it.
  void commit();

  const std::filesystem::path& target() const { return target_; }

 private:
  void write_out(std::string_view bytes);
  void flush();
  [[noreturn]] void fail(const char* what, int error) const;

  std::filesystem::path target_;
  std::filesystem::path partial_;  ///< empty when the target is written in place
  Durability durability_;
  UniqueFd fd_;
  std::string buffer_;
  bool committed_ = false;
};

/// The whole of `bytes` as `target`, through an AtomicFile.
void write_file_atomically(const std::filesystem::path& target, std::string_view bytes,
                           Durability durability = Durability::Synced);

/// Flushes everything written to the filesystem holding `path` to the disk (syncfs): one
/// call for the many Deferred files of a recording when it finishes. False if it could not.
bool sync_filesystem_of(const std::filesystem::path& path);

}  // namespace evar::base
