#include "mobmap/mapping/map_lock.hpp"

#include "mobmap/mapping/mobility_map.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>

namespace mobmap::mapping {

std::string mapLockPath(const std::string& ot_path) { return mapFileStem(ot_path) + ".lock"; }

MapLock::MapLock(const std::string& ot_path) : path_(mapLockPath(ot_path)) {
  std::error_code ec;
  const std::filesystem::path parent = std::filesystem::path(path_).parent_path();
  if (!parent.empty()) {
    std::filesystem::create_directories(parent, ec);
    if (ec) throw MapIoError(ot_path + ": cannot create directory " + parent.string() + ": " + ec.message());
  }
  // The file may be removed by the holder between our open() and flock(): then the lock
  // we got is on a file nobody else will see, so try again on the new one.
  for (int attempt = 0; attempt < 100; ++attempt) {
    const int fd = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) {
      throw MapIoError(ot_path + ": cannot create the lock file " + path_ + ": " + std::strerror(errno));
    }
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const int err = errno;
      char buf[32] = {};
      const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
      ::close(fd);
      if (err != EWOULDBLOCK) throw MapIoError(ot_path + ": cannot lock " + path_ + ": " + std::strerror(err));
      std::string holder = n > 0 ? std::string(buf, static_cast<std::size_t>(n)) : std::string();
      while (!holder.empty() && (holder.back() == '\n' || holder.back() == ' ')) holder.pop_back();
      throw MapIoError(ot_path + ": is being written by another process (" +
                       (holder.empty() ? std::string("it") : "pid " + holder) + " holds " + path_ +
                       "); wait for it to finish, or write another map");
    }
    struct stat held {}, named {};
    if (::fstat(fd, &held) == 0 && ::stat(path_.c_str(), &named) == 0 && held.st_ino == named.st_ino &&
        held.st_dev == named.st_dev) {
      const std::string pid = std::to_string(::getpid()) + "\n";
      if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
        // The lock holds without the note of who holds it.
      }
      fd_ = fd;
      return;
    }
    ::close(fd);  // removed or replaced since we opened it
  }
  throw MapIoError(ot_path + ": cannot lock " + path_ + ": it keeps being replaced");
}

MapLock::~MapLock() {
  if (fd_ < 0) return;
  // Remove it while still holding the lock: a writer that opened it before sees it gone
  // after its flock() and opens a new one.
  ::unlink(path_.c_str());
  ::close(fd_);
}

}  // namespace mobmap::mapping
