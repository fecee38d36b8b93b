#pragma once
/// @file simd.hpp
/// Which instruction set the pipeline's hot loops run on. Every choice gives the same
/// results to the last bit: the vector code performs the same floating-point
/// operations in the same order as the portable code (the library is built with
/// -ffp-contract=off, so no compiler fuses a multiply into an add), and only the speed
/// differs. Tests run each choice the machine supports against brute-force references.

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

/// kAuto resolved; throws std::invalid_argument naming `caller` if `simd` cannot run here.
[[nodiscard]] Simd resolveSimd(Simd simd, const char* caller);

const char* toString(Simd simd);

}  // namespace mobmap::perception
