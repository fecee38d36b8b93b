#pragma once
// Which instruction set the hot loops run on (internal: not installed). The choice is
// made in one place, activeSimd(); every kernel asks it. All choices give the same
// results to the last bit: the vector code performs the same floating-point operations
// in the same order as the portable code (the library is built with -ffp-contract=off,
// so no compiler fuses a multiply into an add); only the speed differs. Tests pin each
// choice the machine supports with ScopedSimd and compare it with brute-force
// references and with the portable loops.

namespace mobmap::perception {

enum class Simd {
  kAuto,      ///< the widest the CPU and the operating system support
  kPortable,  ///< plain C++, any CPU
  kAvx512,    ///< x86-64 AVX-512 F/BW/DQ/VL (Intel Xeon since Skylake-SP, AMD since Zen 4)
  kAvx2,      ///< x86-64 AVX2 (Intel since Haswell, AMD since Excavator and every Zen)
};

/// Whether `simd` can run on this machine (kAuto and kPortable always can).
[[nodiscard]] bool simdSupported(Simd simd);

/// What kAuto means on this machine: AVX-512, else AVX2, else portable.
[[nodiscard]] Simd bestSimd();

/// The instruction set the calling thread's kernels use: that of the innermost
/// ScopedSimd alive on this thread, else bestSimd(). Never kAuto.
[[nodiscard]] Simd activeSimd();

/// Pins the calling thread's kernels to one instruction set while it lives (tests and
/// benchmarks). Throws std::invalid_argument if `simd` cannot run on this machine.
class ScopedSimd {
 public:
  explicit ScopedSimd(Simd simd);
  ~ScopedSimd();
  ScopedSimd(const ScopedSimd&) = delete;
  ScopedSimd& operator=(const ScopedSimd&) = delete;

 private:
  Simd previous_;
};

const char* toString(Simd simd);

}  // namespace mobmap::perception
