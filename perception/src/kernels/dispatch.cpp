#include "kernels/simd.hpp"

#include "kernels/kernels.hpp"

#include <stdexcept>
#include <string>

namespace mobmap::perception {

bool simdSupported(Simd simd) {
  switch (simd) {
    case Simd::kAuto:
    case Simd::kPortable: return true;
    case Simd::kAvx512:
#if MOBMAP_X86_KERNELS
      // libgcc's CPU check also asks the OS (XGETBV) whether it saves the zmm state.
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
             __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512vl");
#else
      return false;
#endif
    case Simd::kAvx2:
#if MOBMAP_X86_KERNELS
      // As above, libgcc's "avx2" includes the operating system's ymm support.
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt");
#else
      return false;
#endif
  }
  return false;
}

Simd bestSimd() {
  static const Simd best = simdSupported(Simd::kAvx512) ? Simd::kAvx512
                           : simdSupported(Simd::kAvx2) ? Simd::kAvx2
                                                        : Simd::kPortable;
  return best;
}

namespace {
// kAuto: no ScopedSimd alive on this thread.
thread_local Simd pinned = Simd::kAuto;
}  // namespace

Simd activeSimd() { return pinned == Simd::kAuto ? bestSimd() : pinned; }

ScopedSimd::ScopedSimd(Simd simd) : previous_(pinned) {
  if (!simdSupported(simd)) {
    throw std::invalid_argument(std::string("ScopedSimd: ") + toString(simd) + " is not available on this machine");
  }
  pinned = simd;
}

ScopedSimd::~ScopedSimd() { pinned = previous_; }

const char* toString(Simd simd) {
  switch (simd) {
    case Simd::kAuto: return "auto";
    case Simd::kPortable: return "portable";
    case Simd::kAvx512: return "AVX-512";
    case Simd::kAvx2: return "AVX2";
  }
  return "unknown";
}

}  // namespace mobmap::perception
