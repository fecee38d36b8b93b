#pragma once
/// @file map_lock.hpp
/// One writer per map: an exclusive lock on a map's files for as long as a program
/// writes them (`mobmap build`, a program fusing frames into a map on disk).

#include <string>

namespace mobmap::mapping {

/// Holds MAP.lock beside MAP.ot, locked with flock(2), from construction to destruction.
/// The operating system releases the lock when the process ends, however it ends, so a
/// crashed writer never blocks the next one; the file itself is removed on release and
/// is harmless if left behind. Readers do not take it: maps are replaced by rename, so a
/// reader sees the old files or the new ones.
class MapLock {
 public:
  /// Takes the lock at once or throws MapIoError "MAP.ot: is being written by another
  /// process (pid N holds MAP.lock); ..." naming the holder's process id, or the reason the
  /// lock file cannot be created. Never waits.
  explicit MapLock(const std::string& ot_path);
  ~MapLock();
  MapLock(const MapLock&) = delete;
  MapLock& operator=(const MapLock&) = delete;

  /// MAP.lock's path.
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
};

/// "maps/x.ot" -> "maps/x.lock".
std::string mapLockPath(const std::string& ot_path);

}  // namespace mobmap::mapping
