// The calling thread's floating-point mode, carried into OpenMP workers.
//
// Flush-to-zero and denormals-are-zero (set by torch.set_flush_denormal(True), among others) and the rounding
// direction live in a per-thread register (x86: MXCSR). OpenMP workers keep whatever mode they were created
// with, so a region whose caller flushes denormals would compute part of its work with them and part without,
// and results would depend on the thread count. Every parallel region therefore starts with
//   const FloatModeScope scope(mode);   // mode = FloatMode::of_this_thread(), taken before the region
// which gives each worker the caller's mode until the region ends (parallel_for_static below does this for a
// plain loop). Elsewhere than x86 this is a no-op.
#pragma once

#if defined(__SSE__) || defined(__x86_64__)
#include <xmmintrin.h>
#define OLATBENCH_HAVE_MXCSR 1
#endif

namespace {

struct FloatMode {
  unsigned bits = 0;
#ifdef OLATBENCH_HAVE_MXCSR
  static constexpr unsigned kMask = 0x8000u | 0x6000u | 0x0040u;  // flush-to-zero, rounding, denormals-are-zero
  static FloatMode of_this_thread() { return FloatMode{_mm_getcsr() & kMask}; }
#else
  static FloatMode of_this_thread() { return FloatMode{}; }
#endif
};

// Puts `mode` on the running thread for the scope's lifetime, then restores the thread's own.
class FloatModeScope {
 public:
  explicit FloatModeScope(FloatMode mode) {
#ifdef OLATBENCH_HAVE_MXCSR
    saved_ = _mm_getcsr();
    _mm_setcsr((saved_ & ~FloatMode::kMask) | mode.bits);
#else
    (void)mode;
#endif
  }
  ~FloatModeScope() {
#ifdef OLATBENCH_HAVE_MXCSR
    _mm_setcsr(saved_);
#endif
  }
  FloatModeScope(const FloatModeScope&) = delete;
  FloatModeScope& operator=(const FloatModeScope&) = delete;

 private:
  unsigned saved_ = 0;
};

// body(i) for i in [0, n), statically scheduled over `threads` OpenMP threads, each in the caller's float mode.
template <typename Index, typename Body>
void parallel_for_static(Index n, int threads, Body body) {
  const FloatMode mode = FloatMode::of_this_thread();
#pragma omp parallel num_threads(threads)
  {
    const FloatModeScope scope(mode);
#pragma omp for schedule(static)
    for (Index i = 0; i < n; ++i) body(i);
  }
}

}  // namespace
