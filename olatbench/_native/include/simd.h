// SIMD helpers shared by the C++ kernels (shading.cpp, rasterize.cpp's light pass): exp, log1p and sqrt on
// fixed-width vectors through the GCC / Clang vector extensions, with an AVX2 check for run-time dispatch.
#pragma once

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace {

// exp and softplus on fixed-width SIMD vectors through the GCC / Clang vector extensions: glibc's scalar exp and
// log1p made up most of the kernel's time, and without -ffast-math the compiler does not vectorise them itself.
// W = 16 bytes (2 doubles or 4 floats, the baseline instruction set: SSE2 on x86-64), and on x86-64 CPUs with AVX2
// a 32-byte copy selected at run time (same operations lane by lane, no FMA: identical results). Branch-free
// (selects are bit masks); accurate to a few ulp, like the vectorised (Sleef) functions torch's CPU kernels use.
template <typename F>
struct FloatBits;
template <>
struct FloatBits<float> {
  using Int = int32_t;
  static constexpr int kMantissa = 23, kBias = 127, kExpDegree = 7, kLogTerms = 6;
  static constexpr float kRound = 12582912.0f;  // 1.5 * 2^23: (x + kRound) - kRound rounds x to an integer
  static constexpr float kShift = 8388608.0f;   // 2^23
  static constexpr float kExpMin = -87.0f;      // exp below: 0 (true value < 1.7e-38, the normal range's end)
};
template <>
struct FloatBits<double> {
  using Int = int64_t;
  static constexpr int kMantissa = 52, kBias = 1023, kExpDegree = 13, kLogTerms = 11;
  static constexpr double kRound = 6755399441055744.0;  // 1.5 * 2^52
  static constexpr double kShift = 4503599627370496.0;  // 2^52
  static constexpr double kExpMin = -708.0;             // exp below: 0 (true value < 3.3e-308)
};
template <typename F, int W = 16>
struct Simd : FloatBits<F> {
  typedef F V __attribute__((vector_size(W)));
  typedef typename FloatBits<F>::Int I __attribute__((vector_size(W)));
  static constexpr int kLanes = W / int(sizeof(F));
};
constexpr double kLn2 = 0.6931471805599453094;
constexpr double kLn2Hi = 0.693145751953125;  // ln 2 = hi + lo, hi with 16 significant bits: n hi is exact
constexpr double kLn2Lo = 1.428606820309417232e-06;

// Always inlined, so that the AVX2 entry points below compile them for AVX2 (hence no ABI concern about passing
// 32-byte vectors between functions, which GCC's -Wpsabi warns about; disabled at the top of this header).
#define OLATBENCH_SIMD inline __attribute__((always_inline))

template <typename F, int W = 16>
OLATBENCH_SIMD typename Simd<F, W>::V splat(F x) {
  typename Simd<F, W>::V v;
  for (int i = 0; i < Simd<F, W>::kLanes; ++i) v[i] = x;
  return v;
}
// mask ? a : b lane-wise (mask lanes all ones or all zeros, as vector comparisons give).
template <typename F, int W = 16>
OLATBENCH_SIMD typename Simd<F, W>::V select(const typename Simd<F, W>::I& mask, const typename Simd<F, W>::V& a,
                                             const typename Simd<F, W>::V& b) {
  using I = typename Simd<F, W>::I;
  return (typename Simd<F, W>::V)(((I)a & mask) | ((I)b & ~mask));
}

// Polynomial coefficients: 1/d! (exp's Taylor series) and 1/(2k+1) (2 atanh(s) / s in powers of s^2).
struct ExpCoefficients {
  static constexpr double at(int d) {
    double factorial = 1.0;  // exact up to 18!
    for (int i = 2; i <= d; ++i) factorial *= i;
    return 1.0 / factorial;
  }
};
struct AtanhCoefficients {
  static constexpr double at(int k) { return 1.0 / (2 * k + 1); }
};
constexpr int pow2_below(int n) {  // the largest power of two < n (n >= 2)
  int p = 1;
  while (2 * p < n) p *= 2;
  return p;
}
constexpr int log2_exact(int p) { return p == 1 ? 0 : 1 + log2_exact(p / 2); }

// sum_{d < Count} C::at(Lo + d) x^d by Estrin's scheme (split at a power of two h: low + high x^h), given
// powers[k] = x^(2^k): a dependency chain of log2(Count) multiply-adds instead of Horner's Count, which
// made the kernel latency-bound.
template <typename F, int W, typename C, int Lo, int Count>
OLATBENCH_SIMD typename Simd<F, W>::V estrin(const typename Simd<F, W>::V* powers) {
  if constexpr (Count == 1) {
    return splat<F, W>(F(C::at(Lo)));
  } else {
    constexpr int h = pow2_below(Count);
    return estrin<F, W, C, Lo, h>(powers) + estrin<F, W, C, Lo + h, Count - h>(powers) * powers[log2_exact(h)];
  }
}
template <typename F, int W>
OLATBENCH_SIMD void powers_of(const typename Simd<F, W>::V& x, typename Simd<F, W>::V* powers, int count) {
  powers[0] = x;
  for (int k = 1; k < count; ++k) powers[k] = powers[k - 1] * powers[k - 1];
}

// exp(x) for x <= 0: x = n ln2 + r with |r| <= ln2 / 2 (Cody-Waite), exp(r) by its Taylor polynomial (degree
// 7 for float, 13 for double: below 1 ulp on that interval), 2^n assembled in the exponent bits (n >= -126
// resp. -1022 after the clamp at kExpMin, so 2^n is normal; below kExpMin the result is 0). The rounding uses
// the add-and-subtract trick, which needs IEEE arithmetic without -ffast-math (the build's flags).
template <typename F, int W = 16>
OLATBENCH_SIMD typename Simd<F, W>::V exp_nonpositive(const typename Simd<F, W>::V& arg) {
  using S = Simd<F, W>;
  using V = typename S::V;
  using I = typename S::I;
  const V low = splat<F, W>(S::kExpMin);
  const I flush = arg < low;
  const V x = select<F, W>(flush, low, arg);
  const V n = (x * F(1.4426950408889634) + S::kRound) - S::kRound;  // round(x / ln 2)
  const V r = (x - n * F(kLn2Hi)) - n * F(kLn2Lo);
  V powers[4];
  powers_of<F, W>(r, powers, 4);
  const V poly = estrin<F, W, ExpCoefficients, 0, S::kExpDegree + 1>(powers);
  I bits = (I)(n + F(S::kBias) + S::kShift);  // n + bias as an integer in the low mantissa bits
  bits = bits << S::kMantissa;                // ... moved into the exponent field: 2^n
  return select<F, W>(flush, splat<F, W>(F(0)), poly * (V)bits);
}

// log1p(u) for u in [0, 1]: above sqrt(2) - 1 use log1p(u) = ln 2 + log1p((u - 1) / 2), so the argument v lies
// in (-0.293, 0.415]; then log1p(v) = 2 atanh(s) = 2 s sum_k s^(2k) / (2k + 1) with s = v / (2 + v),
// |s| <= 0.172, truncated below 1 ulp (6 terms for float, 11 for double).
template <typename F, int W>
OLATBENCH_SIMD typename Simd<F, W>::V log1p_unit(const typename Simd<F, W>::V& u) {
  using S = Simd<F, W>;
  using V = typename S::V;
  const typename S::I high = u > splat<F, W>(F(0.41421356237309503));
  const V v = select<F, W>(high, (u - F(1)) * F(0.5), u);
  const V s = v / (v + F(2));
  V powers[4];
  powers_of<F, W>(s * s, powers, 4);
  const V poly = estrin<F, W, AtanhCoefficients, 0, S::kLogTerms>(powers);
  const V result = s * F(2) * poly;
  return select<F, W>(high, result + F(kLn2), result);
}

// Square root of a scalar or of a 16-byte vector, lane-wise (correctly rounded, as std::sqrt).
inline float root(float x) { return std::sqrt(x); }
inline double root(double x) { return std::sqrt(x); }
inline Simd<float>::V root(Simd<float>::V x) {
#if defined(__SSE2__)
  return _mm_sqrt_ps(x);
#else
  for (int i = 0; i < Simd<float>::kLanes; ++i) x[i] = std::sqrt(x[i]);
  return x;
#endif
}
inline Simd<double>::V root(Simd<double>::V x) {
#if defined(__SSE2__)
  return _mm_sqrt_pd(x);
#else
  for (int i = 0; i < Simd<double>::kLanes; ++i) x[i] = std::sqrt(x[i]);
  return x;
#endif
}

template <typename F, int W>
OLATBENCH_SIMD typename Simd<F, W>::V load(const F* p, int64_t count) {  // lanes from count on are 0
  typename Simd<F, W>::V v = splat<F, W>(F(0));
  if (count >= Simd<F, W>::kLanes) std::memcpy(&v, p, sizeof(v));  // constant size: one vector load
  else std::memcpy(&v, p, sizeof(F) * size_t(count));
  return v;
}
template <typename F, int W>
OLATBENCH_SIMD void store(F* p, int64_t count, const typename Simd<F, W>::V& v) {  // the first min(count, lanes) lanes
  if (count >= Simd<F, W>::kLanes) std::memcpy(p, &v, sizeof(v));
  else std::memcpy(p, &v, sizeof(F) * size_t(count));
}

// On x86-64 with GCC or Clang, kernels may carry a 32-byte (AVX2) copy chosen at run time with have_avx2(), unless
// the environment variable OLATBENCH_NATIVE_SIMD is "baseline" when the library first asks (the 16-byte copy then
// runs everywhere: the way to check that both copies give the same bits, benchmarks/numerics_trace.py settings).
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define OLATBENCH_SIMD_AVX2 1
inline bool have_avx2() {
  static const bool yes = [] {
    const char* forced = std::getenv("OLATBENCH_NATIVE_SIMD");
    if (forced != nullptr && std::strcmp(forced, "baseline") == 0) return false;
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return yes;
}
#endif

}  // namespace
