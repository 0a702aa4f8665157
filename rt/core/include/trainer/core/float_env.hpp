// The haptic cycle's floating-point environment: subnormal (denormal) numbers flushed to zero,
// as audio and control DSP do. A duct left alone rings down; its modal coordinates decay into
// the subnormal range, where every multiply on them runs at the CPU's microcoded slow path
// (measured: the 10 kHz cbd reconstruction at ~120 µs instead of ~5 µs for 7.6 % of a session,
// docs/performance.md). Values below ~1.2e-38 (float) are physically zero here: metres,
// newtons and modal amplitudes of that size mean nothing.
//
// HapticApp::run_cycle holds a FlushDenormalsScope for the cycle, so every caller of the cycle
// (the real-time loop, simulated time, replay, benchmarks, tests) computes in the same mode and
// replay stays bit-exact; the caller's own mode is restored after the cycle.
//
// x86-64: MXCSR's FTZ (bit 15) and DAZ (bit 6); AArch64: FPCR's FZ (bit 24); elsewhere a no-op
// (documented in docs/performance.md).
#pragma once

#include <cstdint>

#if defined(__x86_64__) || defined(__i386__)
#include <xmmintrin.h>
#endif

namespace trainer::core {

class FlushDenormalsScope {
 public:
  FlushDenormalsScope() noexcept : saved_(read()) { write(saved_ | kFlushBits); }
  ~FlushDenormalsScope() { write(saved_); }
  FlushDenormalsScope(const FlushDenormalsScope&) = delete;
  FlushDenormalsScope& operator=(const FlushDenormalsScope&) = delete;

  // True when this thread now flushes subnormals (false on an architecture without the bits).
  static bool active() noexcept { return kFlushBits != 0 && (read() & kFlushBits) == kFlushBits; }

 private:
#if defined(__x86_64__) || defined(__i386__)
  static constexpr std::uint64_t kFlushBits = 0x8040;  // FTZ | DAZ
  static std::uint64_t read() noexcept { return _mm_getcsr(); }
  static void write(std::uint64_t value) noexcept {
    _mm_setcsr(static_cast<unsigned int>(value));
  }
#elif defined(__aarch64__)
  static constexpr std::uint64_t kFlushBits = std::uint64_t{1} << 24;  // FPCR.FZ
  static std::uint64_t read() noexcept {
    std::uint64_t value = 0;
    asm volatile("mrs %0, fpcr" : "=r"(value));
    return value;
  }
  static void write(std::uint64_t value) noexcept { asm volatile("msr fpcr, %0" : : "r"(value)); }
#else
  static constexpr std::uint64_t kFlushBits = 0;
  static std::uint64_t read() noexcept { return 0; }
  static void write(std::uint64_t) noexcept {}
#endif
  std::uint64_t saved_;
};

}  // namespace trainer::core
