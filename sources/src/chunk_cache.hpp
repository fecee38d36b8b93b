#pragma once
// What reading compressed chunks (MCAP's, a ROS 1 bag's) may cost, whoever wrote them:
// a chunk holds at most kMaxChunkBytes uncompressed; all of a file's chunks together
// decompress to at most InflateBudget's bound in the pass over the file and twice that
// with the frames read again; the chunks kept for reading again hold at most
// kCacheBytes (or the one chunk last read, when it alone is larger).

#include <sys/mman.h>

#include <atomic>
#include <cstdint>
#include <new>
#include <functional>
#include <list>
#include <mutex>
#include <string>
#include <vector>

namespace mobmap::sources {

/// Recorders close a chunk past a threshold (rosbag2's MCAP default is 768 KiB,
/// rosbag's 768 KiB) and one message: this is far above what they write.
constexpr std::uint64_t kMaxChunkBytes = 128ULL << 20;
constexpr std::uint64_t kCacheBytes = 64ULL << 20;

/// Memory for decompressed chunks straight from the OS and back to it when freed:
/// `mobmap` keeps large blocks in its heap for reuse (apps/src/main.cpp), where chunks
/// of varying sizes would leave the heap as large as several of them.
template <typename T>
struct PageAllocator {
  using value_type = T;
  PageAllocator() = default;
  template <typename U>
  explicit PageAllocator(const PageAllocator<U>&) {}
  T* allocate(std::size_t n) {
    void* p = ::mmap(nullptr, n * sizeof(T), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    return static_cast<T*>(p);
  }
  void deallocate(T* p, std::size_t n) { ::munmap(p, n * sizeof(T)); }
  template <typename U>
  bool operator==(const PageAllocator<U>&) const { return true; }
  template <typename U>
  bool operator!=(const PageAllocator<U>&) const { return false; }
};
/// A chunk's records, decompressed.
using ChunkBytes = std::vector<std::uint8_t, PageAllocator<std::uint8_t>>;

/// Expands the LZ4 frame (or frames) `in` into `out`, which holds the size it declares;
/// "" when it fills `out` exactly, else why not.
std::string expandLz4Frame(const std::uint8_t* in, std::size_t n, ChunkBytes* out);

/// Decompressed bytes a file may cost: 1 GiB + 1024 times its size for the pass over
/// it, twice that with its frames read again.
class InflateBudget {
 public:
  explicit InflateBudget(std::uint64_t file_bytes) : file_bytes_(file_bytes) {}
  /// Counts `bytes` for a chunk about to be decompressed, `weight` times (8 for bzip2,
  /// ~30 times slower than zstd to expand a run); "" when it fits, else why not (a chunk
  /// larger than kMaxChunkBytes, or the file's bound passed).
  [[nodiscard]] std::string charge(std::uint64_t bytes, bool reading_again, unsigned weight = 1) const;

 private:
  std::uint64_t file_bytes_;
  mutable std::atomic<std::uint64_t> spent_{0};
};

/// Decompressed chunks by their offset in the file, bounded in bytes. A chunk several
/// threads want is decompressed once: loading happens under the cache's lock, and so
/// does copying a message out, so the chunks in memory are the cache's alone.
class ChunkCache {
 public:
  /// Bytes [begin, begin + n) of the chunk at `at`; when it is not cached, `declared`
  /// gives the size it will have (room is made first) and `load` loads it.
  /// std::out_of_range when the range lies outside the chunk; what `load` throws passes
  /// through.
  std::vector<std::uint8_t> copy(std::uint64_t at, std::uint64_t begin, std::uint64_t n, const std::function<std::uint64_t()>& declared,
                                 const std::function<ChunkBytes()>& load) const;

 private:
  mutable std::mutex mutex_;
  mutable std::list<std::pair<std::uint64_t, ChunkBytes>> chunks_;  // oldest first
  mutable std::uint64_t bytes_ = 0;
};

}  // namespace mobmap::sources
