// ContextFile: the SQLite store's append-only file of large contexts
// ("<database>.contexts"). A context kept in SQLite is written twice, into
// the write-ahead log at its commit and into the database when the log is
// checkpointed; kept here it is written once, and the event's row holds
// only where it is (offset and length). The event's selection checksum
// covers the context's bytes, so a damaged or missing range reads as
// DATA_LOSS naming the event.
//
// Durability: the store appends a group's contexts, Sync()s the file, and
// only then commits the rows that point at them, so a committed row never
// points at bytes that are not on disk. Bytes appended by a group that did
// not commit stay unreferenced (never reused: appends go after them).
// Deleted events' ranges are zeroed and freed (Erase), so a deleted user's
// contexts do not stay on disk; what a crash or a write that never
// committed left unreferenced is erased at the next open, or by the checks
// that follow it (SqliteEventStore::RunDeferredChecks; EraseAllBut). A
// new file is made whole under a temporary name, then renamed.
//
// The file starts with a 16-byte header that names it; each context starts
// at a 4 KB boundary. Not thread-safe for
// writers (the store appends and erases under its own mutex); Read may run
// from any thread.
#ifndef BITEWISE_SERVICES_BANDIT_STORE_CONTEXT_FILE_H_
#define BITEWISE_SERVICES_BANDIT_STORE_CONTEXT_FILE_H_

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace bitewise::bandit {

class ContextFile {
 public:
  // Opens `path`, or creates it (owner-only, its directory synced) when it
  // does not exist and the database refers to nothing in it
  // (`referenced_end` 0). DATA_LOSS naming the path when the database
  // refers to contexts (up to `referenced_end`) that a missing file held,
  // or when the file's header is not ours; UNAVAILABLE when it cannot be
  // opened or created.
  static absl::StatusOr<std::unique_ptr<ContextFile>> Open(
      const std::string& path, int64_t referenced_end);

  ContextFile(const ContextFile&) = delete;
  ContextFile& operator=(const ContextFile&) = delete;
  ~ContextFile();

  // Writes `bytes` after everything appended so far and returns where;
  // durable only after the next Sync. RESOURCE_EXHAUSTED for a full disk,
  // UNAVAILABLE for another write error (both naming the file).
  absl::StatusOr<int64_t> Append(absl::string_view bytes);
  // Whether bytes were appended since the last Sync.
  bool dirty() const { return dirty_; }
  // Appends a block, syncs it and erases it again: whether the file takes
  // writes (a store's ProbeWrite). The block stays unreferenced.
  absl::Status Probe();
  // Makes every Append so far durable (fdatasync).
  absl::Status Sync();
  // The `length` bytes at `offset`; fewer when the file is shorter or
  // cannot be read (the caller's checksum then fails).
  std::string Read(int64_t offset, int64_t length) const;
  // Zeroes the ranges (offset, length) and frees their whole blocks: the
  // contexts of deleted events. UNAVAILABLE naming the file on failure.
  absl::Status Erase(const std::vector<std::pair<int64_t, int64_t>>& ranges);
  // Erases every whole block that none of the `live` ranges touches: the
  // contexts of writes that never committed, or whose erasure was lost to
  // a crash between their deletion's commit and the erase (run at open or
  // just after).
  absl::Status EraseAllBut(std::vector<std::pair<int64_t, int64_t>> live);

  // Appends go after `referenced_end` too (the furthest range the
  // database points at, when found after Open).
  void ExtendTo(int64_t referenced_end) {
    end_ = std::max(end_, referenced_end);
  }

  const std::string& path() const { return path_; }
  // The file's identity when opened, to notice it being replaced.
  uint64_t device() const { return device_; }
  uint64_t inode() const { return inode_; }

  static constexpr int64_t kHeaderBytes = 16;
  // Contexts start at multiples of this (the file system's and the page
  // cache's block).
  static constexpr int64_t kBlockBytes = 4096;

 private:
  ContextFile(int fd, std::string path, int64_t end, uint64_t device,
              uint64_t inode);

  const int fd_;
  const std::string path_;
  int64_t end_;
  bool dirty_ = false;
  const uint64_t device_;
  const uint64_t inode_;
};

}  // namespace bitewise::bandit

#endif  // BITEWISE_SERVICES_BANDIT_STORE_CONTEXT_FILE_H_
