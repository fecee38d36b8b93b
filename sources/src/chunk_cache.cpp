#include "chunk_cache.hpp"

#include <lz4frame.h>

#include <iterator>
#include <stdexcept>

namespace mobmap::sources {
namespace {

std::string mib(std::uint64_t bytes) { return std::to_string(bytes >> 20) + " MiB"; }

}  // namespace

std::string expandLz4Frame(const std::uint8_t* in, std::size_t n, ChunkBytes* out) {
  LZ4F_dctx* ctx = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION))) return "out of memory";
  std::size_t out_at = 0, in_at = 0;
  std::string err;
  while (in_at < n) {
    std::size_t out_n = out->size() - out_at, in_n = n - in_at;
    const std::size_t r = LZ4F_decompress(ctx, out->data() + out_at, &out_n, in + in_at, &in_n, nullptr);
    if (LZ4F_isError(r)) {
      err = std::string("lz4 cannot decompress it (") + LZ4F_getErrorName(r) + ")";
      break;
    }
    out_at += out_n;
    in_at += in_n;
    if (r == 0) break;
    if (out_n == 0 && in_n == 0) {
      err = "lz4 decompresses it to more than the " + std::to_string(out->size()) + " bytes it declares";
      break;
    }
  }
  LZ4F_freeDecompressionContext(ctx);
  if (err.empty() && out_at != out->size()) {
    err = "it decompresses to " + std::to_string(out_at) + " bytes, not " + std::to_string(out->size());
  }
  return err;
}

std::string InflateBudget::charge(std::uint64_t declared, bool reading_again, unsigned weight) const {
  if (declared > kMaxChunkBytes) {
    return "it claims " + std::to_string(declared) + " bytes uncompressed (mobmap reads chunks of at most " + mib(kMaxChunkBytes) + ")";
  }
  const std::uint64_t bytes = declared * weight;
  const std::uint64_t pass = (1ULL << 30) + 1024 * file_bytes_;
  const std::uint64_t limit = reading_again ? 2 * pass : pass;
  std::uint64_t spent = spent_.load();
  do {
    if (spent > limit - bytes) {
      return "the file's chunks would decompress to more than " + mib(limit) + " in all (1 GiB + 1024 times the file's " +
             std::to_string(file_bytes_) + " bytes" + (reading_again ? ", twice over with the frames read again" : "") +
             (weight > 1 ? "; bzip2's bytes count " + std::to_string(weight) + " times" : "") +
             "): a decompression bomb, or chunks far beyond any recorder's";
    }
  } while (!spent_.compare_exchange_weak(spent, spent + bytes));
  return {};
}

std::vector<std::uint8_t> ChunkCache::copy(std::uint64_t at, std::uint64_t begin, std::uint64_t n,
                                           const std::function<std::uint64_t()>& declared, const std::function<ChunkBytes()>& load) const {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = chunks_.begin();
  while (it != chunks_.end() && it->first != at) ++it;
  if (it != chunks_.end()) {
    chunks_.splice(chunks_.end(), chunks_, it);  // the most recent last
  } else {
    const std::uint64_t size = declared();
    while (!chunks_.empty() && bytes_ + size > kCacheBytes) {  // room first
      bytes_ -= chunks_.front().second.size();
      chunks_.pop_front();
    }
    ChunkBytes records = load();
    bytes_ += records.size();
    chunks_.emplace_back(at, std::move(records));
  }
  const ChunkBytes& records = chunks_.back().second;
  if (begin > records.size() || n > records.size() - begin) throw std::out_of_range("a message lies outside its chunk");
  return {records.begin() + static_cast<std::ptrdiff_t>(begin), records.begin() + static_cast<std::ptrdiff_t>(begin + n)};
}

}  // namespace mobmap::sources
