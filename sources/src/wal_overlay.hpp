#pragma once
// An SQLite database left with its write-ahead log by a writer that never closed it (a
// ROS 2 recorder killed mid-run): the log's committed pages laid over the database's, as
// SQLite's own recovery would see them, without writing anything beside the files (no
// -shm, no checkpoint). The log is read as the file format describes it (sqlite.org's
// "Database File Format", section 4): a header, then frames of a page each with a
// running checksum; frames count up to the last valid commit frame.

#include "file_reader.hpp"

#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>

namespace mobmap::sources {

struct WalOverlay {
  std::uint32_t page_size = 0;
  std::uint32_t db_pages = 0;  ///< the database's size in pages after the last commit
  std::unordered_map<std::uint32_t, std::uint64_t> frames;  ///< page number -> its newest committed copy's offset in the log
  std::size_t committed_frames = 0;  ///< frames up to the last commit
  std::size_t dropped_frames = 0;    ///< valid frames after it (a transaction the writer never finished)
  std::unique_ptr<FileReader> log;

  /// `size` bytes of the database as the overlay shows it, from `offset`; false where
  /// neither file holds them (the caller zero-fills).
  bool read(const FileReader& db, std::uint64_t offset, void* out, std::size_t size) const;
};

/// The committed frames of `wal_path` for a database whose pages are `page_size` bytes
/// (0: take the log's), or nullptr when the log holds no valid committed frame. The
/// frames after an invalid one (a torn write, an older generation's salt) are not read.
std::unique_ptr<WalOverlay> readWal(const std::string& wal_path, std::uint32_t page_size);

/// The name of the SQLite VFS that opens a database through the overlay registered for
/// it (a URI with `mobmap_wal=ID`); registers it on first use.
const char* walOverlayVfs();
/// Makes `overlay` the one a URI with `mobmap_wal=ID` opens until unregisterWal(ID).
std::string registerWal(const WalOverlay* overlay);
void unregisterWal(const std::string& id);

}  // namespace mobmap::sources
