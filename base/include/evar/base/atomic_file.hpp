#pragma once
// A file that appears whole or not at all. Every writer of the node's outputs (meshes,
// pictures, reports, sessions) goes through it: the bytes go to "<name>.partial-XXXXXX"
// beside the target, are flushed to the disk, the close is checked (NFS and quotas report
// late), and the file is renamed over the target, then the directory is synced so the
// rename survives a power cut. A writer killed or failing half-way leaves the old file,
// or none, never a truncated one.
//
// A target that exists and is not a regular file (a device such as /dev/stdout or
// /dev/full, a FIFO) cannot be replaced: it is written in place, and never removed.
#include <filesystem>
#include <string_view>

#include "evar/base/unique_fd.hpp"

namespace evar::base {

/// How far a finished file is pushed before commit() returns.
enum class Durability {
  Synced,    ///< the file and its directory are on the disk (fsync): reports, meshes, indices
  Deferred,  ///< renamed into place, left in the page cache; the caller syncs later (the
             ///< frames of a recording, which one fsync each would slow to a crawl)
};

class AtomicFile {
 public:
  /// Creates the partial file beside `target`; std::system_error naming it when it cannot.
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

}  // namespace evar::base
