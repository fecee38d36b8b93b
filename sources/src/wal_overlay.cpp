#include "wal_overlay.hpp"

#include <sqlite3.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <mutex>
#include <vector>

namespace mobmap::sources {
namespace {

std::uint32_t be32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | std::uint32_t{p[3]};
}

// The log's running checksum over `n` bytes (a multiple of 8), words read big-endian
// when the magic's low bit says so, little-endian otherwise.
void checksum(const std::uint8_t* p, std::size_t n, bool big_endian, std::uint32_t s[2]) {
  for (std::size_t i = 0; i + 8 <= n; i += 8) {
    std::uint32_t x0, x1;
    if (big_endian) {
      x0 = be32(p + i);
      x1 = be32(p + i + 4);
    } else {
      std::memcpy(&x0, p + i, 4);
      std::memcpy(&x1, p + i + 4, 4);
    }
    s[0] += x0 + s[1];
    s[1] += x1 + s[0];
  }
}

}  // namespace

std::unique_ptr<WalOverlay> readWal(const std::string& wal_path, std::uint32_t page_size) {
  auto overlay = std::make_unique<WalOverlay>();
  overlay->log = std::make_unique<FileReader>(wal_path);
  const FileReader& log = *overlay->log;
  std::uint8_t head[32];
  if (!log.readAt(0, head, sizeof head)) return nullptr;
  const std::uint32_t magic = be32(head);
  if (magic != 0x377f0682 && magic != 0x377f0683) return nullptr;
  const bool big_endian = (magic & 1) != 0;
  const std::uint32_t ps = be32(head + 8);
  if (ps < 512 || ps > 65536 || (ps & (ps - 1)) != 0 || (page_size != 0 && ps != page_size)) return nullptr;
  std::uint32_t sum[2] = {0, 0};
  checksum(head, 24, big_endian, sum);
  if (sum[0] != be32(head + 24) || sum[1] != be32(head + 28)) return nullptr;
  overlay->page_size = ps;
  // Frames in order; each one's checksum continues the previous one's.
  std::vector<std::uint8_t> frame(24 + ps);
  std::vector<std::pair<std::uint32_t, std::uint64_t>> pending;  // since the last commit
  for (std::uint64_t at = 32; at + frame.size() <= log.size(); at += frame.size()) {
    if (!log.readAt(at, frame.data(), frame.size())) break;
    if (std::memcmp(frame.data() + 8, head + 16, 8) != 0) break;  // another generation's salt
    const std::uint32_t page = be32(frame.data());
    if (page == 0) break;
    std::uint32_t next[2] = {sum[0], sum[1]};
    checksum(frame.data(), 8, big_endian, next);
    checksum(frame.data() + 24, ps, big_endian, next);
    if (next[0] != be32(frame.data() + 16) || next[1] != be32(frame.data() + 20)) break;  // a torn write
    sum[0] = next[0];
    sum[1] = next[1];
    pending.emplace_back(page, at + 24);
    if (const std::uint32_t commit = be32(frame.data() + 4); commit != 0) {
      for (const auto& [p, offset] : pending) overlay->frames[p] = offset;
      overlay->committed_frames += pending.size();
      overlay->db_pages = commit;
      pending.clear();
    }
  }
  overlay->dropped_frames = pending.size();
  if (overlay->committed_frames == 0) return nullptr;
  // Pages past the committed size are not the database's any more.
  for (auto it = overlay->frames.begin(); it != overlay->frames.end();) {
    it = it->first > overlay->db_pages ? overlay->frames.erase(it) : std::next(it);
  }
  return overlay;
}

bool WalOverlay::read(const FileReader& db, std::uint64_t offset, void* out, std::size_t size) const {
  auto* dst = static_cast<std::uint8_t*>(out);
  bool whole = true;
  while (size > 0) {
    const std::uint64_t page = offset / page_size + 1;
    const std::uint64_t in_page = offset % page_size;
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(size, page_size - in_page));
    bool got = false;
    if (page <= db_pages) {
      const auto f = frames.find(static_cast<std::uint32_t>(page));
      got = f != frames.end() ? log->readAt(f->second + in_page, dst, n) : db.readAt(offset, dst, n);
    }
    if (!got) {
      std::memset(dst, 0, n);
      whole = false;
    }
    dst += n;
    offset += n;
    size -= n;
  }
  return whole;
}

// ---- the VFS: the main database through its overlay, everything else as SQLite's own ----

namespace {

std::mutex registry_mutex;
std::map<std::string, const WalOverlay*> registry;
std::uint64_t next_id = 0;

sqlite3_vfs* base() { return static_cast<sqlite3_vfs*>(sqlite3_vfs_find(nullptr)); }

struct OverlayFile {
  sqlite3_file file;  // first: SQLite sees this
  const WalOverlay* overlay;
  FileReader* db;  // the database file itself, read with pread (owned)
};

int overlayClose(sqlite3_file* f) {
  auto* o = reinterpret_cast<OverlayFile*>(f);
  delete o->db;
  o->db = nullptr;
  return SQLITE_OK;
}

int overlayRead(sqlite3_file* f, void* out, int amount, sqlite3_int64 offset) {
  auto* o = reinterpret_cast<OverlayFile*>(f);
  if (amount < 0 || offset < 0) return SQLITE_IOERR_READ;
  const bool whole = o->overlay->read(*o->db, static_cast<std::uint64_t>(offset), out, static_cast<std::size_t>(amount));
  // The header says "WAL" (bytes 18 and 19 = 2): shown as a rollback database, whose
  // pages are what SQLite reads here, so it looks for no log and no -shm.
  for (const std::uint64_t b : {18ULL, 19ULL}) {
    if (b >= static_cast<std::uint64_t>(offset) && b < static_cast<std::uint64_t>(offset) + static_cast<std::uint64_t>(amount)) {
      static_cast<std::uint8_t*>(out)[b - static_cast<std::uint64_t>(offset)] = 1;
    }
  }
  return whole ? SQLITE_OK : SQLITE_IOERR_SHORT_READ;
}

int overlayWrite(sqlite3_file*, const void*, int, sqlite3_int64) { return SQLITE_READONLY; }
int overlayTruncate(sqlite3_file*, sqlite3_int64) { return SQLITE_READONLY; }
int overlaySync(sqlite3_file*, int) { return SQLITE_OK; }
int overlaySize(sqlite3_file* f, sqlite3_int64* size) {
  auto* o = reinterpret_cast<OverlayFile*>(f);
  *size = static_cast<sqlite3_int64>(std::uint64_t{o->overlay->db_pages} * o->overlay->page_size);
  return SQLITE_OK;
}
int overlayLock(sqlite3_file*, int) { return SQLITE_OK; }
int overlayCheckReserved(sqlite3_file*, int* out) {
  *out = 0;
  return SQLITE_OK;
}
int overlayControl(sqlite3_file*, int, void*) { return SQLITE_NOTFOUND; }
int overlaySector(sqlite3_file*) { return 4096; }
int overlayDevice(sqlite3_file*) { return SQLITE_IOCAP_IMMUTABLE; }

const sqlite3_io_methods kOverlayMethods = {
    1,              overlayClose, overlayRead,   overlayWrite,          overlayTruncate, overlaySync,  overlaySize,
    overlayLock,    overlayLock,  overlayCheckReserved, overlayControl, overlaySector,   overlayDevice,
    nullptr,        nullptr,      nullptr,       nullptr,               nullptr,         nullptr};

int vfsOpen(sqlite3_vfs* vfs, const char* name, sqlite3_file* f, int flags, int* out_flags) {
  const char* id = name ? sqlite3_uri_parameter(name, "mobmap_wal") : nullptr;
  if (!(flags & SQLITE_OPEN_MAIN_DB) || !id) return base()->xOpen(base(), name, f, flags, out_flags);  // fits: szOsFile is base's or more
  (void)vfs;
  const WalOverlay* overlay = nullptr;
  {
    std::lock_guard<std::mutex> lock(registry_mutex);
    const auto it = registry.find(id);
    if (it != registry.end()) overlay = it->second;
  }
  f->pMethods = nullptr;
  if (!overlay || (flags & SQLITE_OPEN_READWRITE)) return SQLITE_CANTOPEN;
  auto* o = reinterpret_cast<OverlayFile*>(f);
  try {
    o->db = new FileReader(name);
  } catch (...) {
    o->db = nullptr;
    return SQLITE_CANTOPEN;
  }
  o->overlay = overlay;
  f->pMethods = &kOverlayMethods;
  if (out_flags) *out_flags = SQLITE_OPEN_READONLY;
  return SQLITE_OK;
}

int vfsDelete(sqlite3_vfs*, const char* name, int sync) { return base()->xDelete(base(), name, sync); }
int vfsAccess(sqlite3_vfs*, const char* name, int flags, int* out) { return base()->xAccess(base(), name, flags, out); }
int vfsFullPath(sqlite3_vfs*, const char* name, int n, char* out) { return base()->xFullPathname(base(), name, n, out); }
int vfsRandom(sqlite3_vfs*, int n, char* out) { return base()->xRandomness(base(), n, out); }
int vfsSleep(sqlite3_vfs*, int us) { return base()->xSleep(base(), us); }
int vfsTime(sqlite3_vfs*, double* t) { return base()->xCurrentTime(base(), t); }
int vfsError(sqlite3_vfs*, int n, char* out) { return base()->xGetLastError(base(), n, out); }

}  // namespace

const char* walOverlayVfs() {
  static sqlite3_vfs vfs;
  static std::once_flag once;
  std::call_once(once, [] {
    vfs.iVersion = 1;
    vfs.szOsFile = std::max<int>(base()->szOsFile, static_cast<int>(sizeof(OverlayFile)));
    vfs.mxPathname = base()->mxPathname;
    vfs.zName = "mobmap-wal-overlay";
    vfs.xOpen = vfsOpen;
    vfs.xDelete = vfsDelete;
    vfs.xAccess = vfsAccess;
    vfs.xFullPathname = vfsFullPath;
    vfs.xRandomness = vfsRandom;
    vfs.xSleep = vfsSleep;
    vfs.xCurrentTime = vfsTime;
    vfs.xGetLastError = vfsError;
    sqlite3_vfs_register(&vfs, 0);
  });
  return vfs.zName;
}

std::string registerWal(const WalOverlay* overlay) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  const std::string id = std::to_string(++next_id);
  registry[id] = overlay;
  return id;
}

void unregisterWal(const std::string& id) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  registry.erase(id);
}

}  // namespace mobmap::sources
