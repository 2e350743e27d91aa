// olatbench CPU kernels for SSD-GS's per-Gaussian shading (olatbench/methods/ssdgs/shading_cpu.py): the
// closed-form parts of `Shader.forward` fused into two kernels with hand-written backwards.
//
//   geometry:  (positions, frame quaternions, scales, camera position, light position)
//              -> wi, wo (unit directions to the light / camera), shading frames, 1 / max(d^2, 1e-12)
//   combine:   (wi, wo, frames, 1/d^2, intensity, raw colours and ASG weights, ASG lobe frames and sharpness,
//              SSS profile and shadow from the two MLPs) -> colour, diffuse, specular, sss
//   rotations: quaternions -> rotation matrices (quat_to_rotmat, for the few ASG lobe frames)
//
// They compute what the torch code of olatbench/methods/ssdgs/{shader,shading,specular}.py (ASG form "xu")
// computes, up to rounding, with its conventions at non-smooth points: F.normalize (v / max(|v|, 1e-8); the
// norm's gradient passes when |v| >= 1e-8), clamp / clamp_min (gradient passes where min <= x <= max,
// boundaries included), ELU (slope alpha exp(x) for x <= 0), softplus (identity above 20, gradient z / (1 + z)
// with z = exp(x) below), argmin (first minimum), and constant flip signs / permutations (no gradient).
//
// Plain C ABI on raw C-contiguous pointers, called through ctypes. Every function exists for float (_f32) and
// double (_f64); arithmetic is in that type, as torch does it. OpenMP over fixed blocks of kBlock Gaussians;
// within a block, SIMD across Gaussians. Per-Gaussian gradients are written (never accumulated across
// Gaussians); the gradients of inputs shared by all Gaussians (camera, light, intensity, lobe frames and
// sharpness) are summed in double per block in a fixed order, then the block sums are added serially in block
// order, so results do not depend on the number of threads. Build without -ffast-math and with
// -ffp-contract=off (olatbench/_native's flags).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "export.h"
#include "float_mode.h"
#include "rotation.h"
#include "simd.h"

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kNormEps = 1e-8;      // F.normalize's eps (safe_normalize)
constexpr double kDist2Min = 1e-12;    // clamp of the squared distance to the light
constexpr double kSmoothAlpha = 0.01;  // ELU slope of the smooth cosine (shading.SMOOTH_COSINE_ALPHA)
constexpr double kSmoothOffset = 0.006321205588285576;  // a (1 - 1/e), as shading.lambert_cosine computes it
constexpr double kSoftplusThreshold = 20.0;
constexpr int64_t kBlock = 256;  // Gaussians per reduction block (fixed, so sums do not depend on threads)

// exp of x[0, count), all <= 0, into out[] (may alias x).
template <typename F, int W>
OLATBENCH_SIMD void exp_block(const F* x, int64_t count, F* out) {
  for (int64_t i = 0; i < count; i += Simd<F, W>::kLanes)
    store<F, W>(out + i, count - i, exp_nonpositive<F, W>(load<F, W>(x + i, count - i)));
}

// softplus (beta 1, threshold 20, as F.softplus) of raw[0, count) into value[] and its derivative (torch's
// exp(x) / (1 + exp(x)), 1 above the threshold) into grad[]:
// softplus(x) = max(x, 0) + log1p(u), sigmoid(x) = (x >= 0 ? 1 : u) / (1 + u) with u = exp(-|x|).
template <typename F, int W>
OLATBENCH_SIMD void softplus_block(const F* raw, int64_t count, F* value, F* grad) {
  using S = Simd<F, W>;
  using V = typename S::V;
  const V zero = splat<F, W>(F(0)), one = splat<F, W>(F(1));
  for (int64_t i = 0; i < count; i += S::kLanes) {
    const V x = load<F, W>(raw + i, count - i);
    const typename S::I positive = x >= zero, linear = x > splat<F, W>(F(kSoftplusThreshold));
    const V u = exp_nonpositive<F, W>(select<F, W>(positive, -x, x));
    store<F, W>(value + i, count - i,
                select<F, W>(linear, x, select<F, W>(positive, x, zero) + log1p_unit<F, W>(u)));
    store<F, W>(grad + i, count - i, select<F, W>(linear, one, select<F, W>(positive, one, u) / (u + F(1))));
  }
}

// On x86-64, 32-byte (AVX2) copies of the vectorised passes, used when the CPU has AVX2 (simd.h's have_avx2).
#ifdef OLATBENCH_SIMD_AVX2
#define OLATBENCH_SHADING_AVX2 1
template <typename F>
__attribute__((target("avx2"))) void softplus_block_avx2(const F* raw, int64_t count, F* value, F* grad) {
  softplus_block<F, 32>(raw, count, value, grad);
}
#endif

template <typename F>
void softplus_array(const F* raw, int64_t count, F* value, F* grad) {
#ifdef OLATBENCH_SHADING_AVX2
  if (have_avx2()) return softplus_block_avx2(raw, count, value, grad);
#endif
  softplus_block<F, 16>(raw, count, value, grad);
}

template <typename T>
inline T dot3(const T* a, const T* b) {
  return (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2];
}

// Runs body(state, begin, end, acc) on the fixed blocks [begin, end) of kBlock Gaussians, in parallel; `state` is
// make_state()'s result, made once per thread (working memory reused over its blocks), and acc points at the
// block's `width` double accumulators (zeroed). Returns the block sums added in block order (size `width`).
template <typename MakeState, typename Body>
std::vector<double> blocked_reduce(int64_t n, int width, int threads, MakeState make_state, Body body) {
  const int64_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<double> partial(size_t(blocks) * width, 0.0);
  const FloatMode mode = FloatMode::of_this_thread();
#pragma omp parallel num_threads(threads)
  {
    const FloatModeScope scope(mode);
    auto state = make_state();
#pragma omp for schedule(static)
    for (int64_t b = 0; b < blocks; ++b)
      body(state, b * kBlock, std::min(n, (b + 1) * kBlock), partial.data() + size_t(b) * width);
  }
  std::vector<double> total(width, 0.0);
  for (int64_t b = 0; b < blocks; ++b)
    for (int k = 0; k < width; ++k) total[k] += partial[size_t(b) * width + k];
  return total;
}

// ------------------------------------------------------------------------------------------------ lanes
//
// The per-Gaussian work runs on lanes of Simd<F>::kLanes Gaussians at once (SIMD across Gaussians): it is a long
// chain of divisions and square roots that one Gaussian at a time leaves mostly latency-bound. The rotation
// templates (rotation.h) serve scalars (T = F, for the lobe rotations) and lanes (T = Simd<F>::V).

template <typename F>
using Lanes = typename Simd<F>::V;
template <typename F>
using LaneMask = typename Simd<F>::I;

// std::max(a, b) = a < b ? b : a, lane-wise.
template <typename F>
inline Lanes<F> lane_max(Lanes<F> a, Lanes<F> b) {
  return select<F>(a < b, b, a);
}
// Lane i <- p[stride i] for i < count (the other lanes 0), and back.
template <typename F>
inline Lanes<F> gather(const F* p, int stride, int count) {
  Lanes<F> v = splat<F>(F(0));
  for (int i = 0; i < count; ++i) v[i] = p[stride * i];
  return v;
}
template <typename F>
inline void scatter(F* p, int stride, int count, Lanes<F> v) {
  for (int i = 0; i < count; ++i) p[stride * i] = v[i];
}

// ------------------------------------------------------------------------------------------------ geometry

template <typename F>
struct GeometryInputs {
  const F *positions, *quats, *scales, *camera, *light;  // scales null: the learned frame (no permutation)
  int64_t n;
  bool orient;
};

// Everything the geometry forward computes for the lanes of Gaussians [k, k + count) (the backward re-evaluates
// it). Frame columns x, y, z are the rotation's columns (k+1, k+2, k) % 3 for the normal axis k of smallest scale
// (first on ties), or the rotation itself without scales; x and z are negated where flip.
template <typename F>
struct Geometry {
  using V = Lanes<F>;
  V to_light[3], dist2_raw, dist2, rsq;  // L - p, |L - p|^2, its clamp at 1e-12, 1/sqrt of the clamp
  V view[3], view_norm, view_den;        // c - p, |c - p|, max(|c - p|, 1e-8)
  Rotation<V> rotation;                  // of the frame quaternion
  LaneMask<F> axis1, axis2, flip;        // normal axis 1, normal axis 2 (else 0; with scales only), flipped
  V wi[3], wo[3], inv_dist2;
  V frame[3][3];                         // [i][j]: component i of column j (x, y, z = normal)
};

template <typename F>
void geometry_eval(const GeometryInputs<F>& in, int64_t k, int count, Geometry<F>& g) {
  using V = Lanes<F>;
  V p[3], quat[4];
  for (int i = 0; i < 3; ++i) p[i] = gather(in.positions + 3 * k + i, 3, count);
  for (int i = 0; i < 4; ++i) quat[i] = gather(in.quats + 4 * k + i, 4, count);
  for (int i = 0; i < 3; ++i) g.to_light[i] = in.light[i] - p[i];
  g.dist2_raw = dot3(g.to_light, g.to_light);
  g.dist2 = lane_max<F>(g.dist2_raw, splat<F>(F(kDist2Min)));
  g.rsq = F(1) / root(g.dist2);
  for (int i = 0; i < 3; ++i) g.wi[i] = g.to_light[i] * g.rsq;
  g.inv_dist2 = F(1) / g.dist2;

  for (int i = 0; i < 3; ++i) g.view[i] = in.camera[i] - p[i];
  g.view_norm = root(dot3(g.view, g.view));
  g.view_den = lane_max<F>(g.view_norm, splat<F>(F(kNormEps)));
  for (int i = 0; i < 3; ++i) g.wo[i] = g.view[i] / g.view_den;

  rotation_eval<F>(quat, g.rotation);
  const auto& R = g.rotation.R;
  if (in.scales) {
    V s[3];
    for (int i = 0; i < 3; ++i) s[i] = gather(in.scales + 3 * k + i, 3, count);
    const LaneMask<F> less1 = s[1] < s[0];
    g.axis2 = s[2] < select<F>(less1, s[1], s[0]);
    g.axis1 = less1 & ~g.axis2;
    for (int i = 0; i < 3; ++i) {
      g.frame[i][0] = select<F>(g.axis1, R[i][2], select<F>(g.axis2, R[i][0], R[i][1]));
      g.frame[i][1] = select<F>(g.axis1, R[i][0], select<F>(g.axis2, R[i][1], R[i][2]));
      g.frame[i][2] = select<F>(g.axis1, R[i][1], select<F>(g.axis2, R[i][2], R[i][0]));
    }
  } else {
    std::memcpy(g.frame, R, sizeof(g.frame));
  }
  const V normal[3] = {g.frame[0][2], g.frame[1][2], g.frame[2][2]};
  g.flip = dot3(normal, g.wo) < F(0);
  if (!in.orient) g.flip = LaneMask<F>{};
  for (int i = 0; i < 3; ++i) {
    g.frame[i][0] = select<F>(g.flip, -g.frame[i][0], g.frame[i][0]);
    g.frame[i][2] = select<F>(g.flip, -g.frame[i][2], g.frame[i][2]);
  }
}

template <typename F>
void geometry_forward(const GeometryInputs<F>& in, int threads, F* wi, F* wo, F* frames, F* inv_dist2) {
  constexpr int L = Simd<F>::kLanes;
  const int64_t groups = (in.n + L - 1) / L;
  parallel_for_static(groups, threads, [&](int64_t group) {
    const int64_t k = group * L;
    const int count = int(std::min<int64_t>(L, in.n - k));
    Geometry<F> g;
    geometry_eval(in, k, count, g);
    for (int i = 0; i < 3; ++i) {
      scatter(wi + 3 * k + i, 3, count, g.wi[i]);
      scatter(wo + 3 * k + i, 3, count, g.wo[i]);
      for (int j = 0; j < 3; ++j) scatter(frames + 9 * k + 3 * i + j, 9, count, g.frame[i][j]);
    }
    scatter(inv_dist2 + k, 1, count, g.inv_dist2);
  });
}

// Gradients of the outputs may be null (zero). Writes grad_positions (n,3), grad_quats (n,4); grad_camera (3)
// and grad_light (3) are block-reduced (per block in Gaussian order).
template <typename F>
void geometry_backward(const GeometryInputs<F>& in, int threads, const F* g_wi, const F* g_wo, const F* g_frames,
                       const F* g_inv, F* grad_positions, F* grad_quats, F* grad_camera, F* grad_light) {
  using V = Lanes<F>;
  constexpr int L = Simd<F>::kLanes;
  const auto grad_or_zero = [](const F* p, int stride, int count) {
    return p ? gather(p, stride, count) : splat<F>(F(0));
  };
  const auto body = [&](int, int64_t begin, int64_t end, double* acc) {
    for (int64_t k = begin; k < end; k += L) {
      const int count = int(std::min<int64_t>(L, end - k));
      Geometry<F> g;
      geometry_eval(in, k, count, g);
      // Frame -> rotation: undo the flip (a constant sign) and route each frame column's gradient back to the
      // rotation column it was taken from (the permutation's adjoint).
      V gR[3][3];
      for (int i = 0; i < 3; ++i) {
        V gf[3];
        for (int j = 0; j < 3; ++j) gf[j] = grad_or_zero(g_frames ? g_frames + 9 * k + 3 * i + j : nullptr, 9, count);
        gf[0] = select<F>(g.flip, -gf[0], gf[0]);
        gf[2] = select<F>(g.flip, -gf[2], gf[2]);
        if (in.scales) {
          gR[i][0] = select<F>(g.axis1, gf[1], select<F>(g.axis2, gf[0], gf[2]));
          gR[i][1] = select<F>(g.axis1, gf[2], select<F>(g.axis2, gf[1], gf[0]));
          gR[i][2] = select<F>(g.axis1, gf[0], select<F>(g.axis2, gf[2], gf[1]));
        } else {
          for (int j = 0; j < 3; ++j) gR[i][j] = gf[j];
        }
      }
      V grad_quat[4];
      rotation_backward<F>(g.rotation, gR, grad_quat);
      for (int i = 0; i < 4; ++i) scatter(grad_quats + 4 * k + i, 4, count, grad_quat[i]);

      // wo = safe_normalize(c - p): d/dv = (g - wo (wo . g)) / |v| where the norm is used (|v| >= 1e-8),
      // g / 1e-8 where the clamp is.
      V gwo[3], g_view[3];
      for (int i = 0; i < 3; ++i) gwo[i] = grad_or_zero(g_wo ? g_wo + 3 * k + i : nullptr, 3, count);
      const V wo_g = dot3(g.wo, gwo);
      const LaneMask<F> norm_used = g.view_norm >= F(kNormEps);
      for (int i = 0; i < 3; ++i) g_view[i] = select<F>(norm_used, gwo[i] - g.wo[i] * wo_g, gwo[i]) / g.view_den;
      // wi = t rsqrt(d2), 1/d2 with d2 = max(t.t, 1e-12), t = L - p:
      // dwi/dt = rsqrt(d2) (direct) and d rsqrt(d2)/d d2 = -rsqrt(d2)^3 / 2, d(1/d2)/d d2 = -(1/d2)^2,
      // d d2/dt = 2 t where the clamp passes (t.t >= 1e-12).
      V gwi[3];
      for (int i = 0; i < 3; ++i) gwi[i] = grad_or_zero(g_wi ? g_wi + 3 * k + i : nullptr, 3, count);
      const V g_inv_k = grad_or_zero(g_inv ? g_inv + k : nullptr, 1, count);
      const V g_rsq = dot3(gwi, g.to_light);
      const V g_d2 = g_rsq * (F(-0.5) * g.rsq * g.rsq * g.rsq) - g_inv_k * g.inv_dist2 * g.inv_dist2;
      const LaneMask<F> through = g.dist2_raw >= F(kDist2Min);
      V g_t[3];
      for (int i = 0; i < 3; ++i)
        g_t[i] = gwi[i] * g.rsq + select<F>(through, F(2) * g.to_light[i] * g_d2, splat<F>(F(0)));
      for (int i = 0; i < 3; ++i) scatter(grad_positions + 3 * k + i, 3, count, -(g_t[i] + g_view[i]));
      for (int j = 0; j < count; ++j)  // in Gaussian order
        for (int i = 0; i < 3; ++i) {
          acc[i] += double(g_view[i][j]);
          acc[3 + i] += double(g_t[i][j]);
        }
    }
  };
  const std::vector<double> shared = blocked_reduce(in.n, 6, threads, [] { return 0; }, body);
  for (int i = 0; i < 3; ++i) { grad_camera[i] = F(shared[i]); grad_light[i] = F(shared[3 + i]); }
}

// ------------------------------------------------------------------------------------------------ combine
//
// The combine kernels work on blocks [begin, begin + B) of kBlock Gaussians. The block's per-Gaussian rows are
// first transposed into planar scratch, so that the per-Gaussian math runs on lanes of Simd<F>::kLanes
// consecutive Gaussians with contiguous loads, and the work over the N ASG lobes runs in simple loops over the
// block's Gaussians (which the compiler vectorises):
//   forward:  softplus passes; per lane group the half vector h, h in the frame (hl) and the Fresnel factor; per
//             lobe hx, hy, hz and the exponent; one exp pass; D = sum_l w_l max(hz_l, 0) e_l; per lane group the
//             outputs, transposed back to rows;
//   backward: the same up to D (softplus values and exponentials read from the forward's cache); per lane group
//             every gradient but the lobes' path; per lobe that path; per lane group back through hl and h.

// Inputs of the combine kernel. specular / sss / shadow null: that term is off (asg_weights, lobe_axes, lam,
// mu go with specular; profile with sss).
template <typename F>
struct CombineInputs {
  const F *wi, *wo, *frames, *inv_dist2, *intensity, *diffuse;
  const F *specular, *asg_weights, *lobe_axes, *lam, *mu;  // (n,3), (n,N), (N,3,3), (N,), (N,)
  int num_lobes;
  const F *sss, *profile;  // (n,3), (n,profile_channels)
  int profile_channels;    // 1 (broadcast over RGB) or 3
  const F* shadow;         // (n,1)
  int64_t n;
  bool smooth_cosine, shadow_on_sss;
  double f0;
};

// What the combine forward saves for its backward (n (18 + 3N) values, so that the backward evaluates neither
// softplus nor the lobes' exp again): softplus and its derivative of the raw diffuse, specular and sss colours (3 per
// Gaussian each) and of the ASG weights (N), and the lobe exponentials e_l = exp(-lam_l hx_l^2 - mu_l hy_l^2) (N).
// Each section holds the blocks in order, each block [begin, begin + B) planar: value c of Gaussian begin + b at
// width begin + c B + b (width 3 or N).
struct CacheLayout {
  int64_t sd, sd_grad, ss, ss_grad, sp, sp_grad, sw, sw_grad, e;
  CacheLayout(int64_t n, int N)
      : sd(0), sd_grad(3 * n), ss(6 * n), ss_grad(9 * n), sp(12 * n), sp_grad(15 * n), sw(18 * n),
        sw_grad(sw + N * n), e(sw_grad + N * n) {}
};

// Planar scratch for a block's per-Gaussian values: value (plane) c of the block's Gaussian b at c kBlock + b.
// from_rows / to_rows transpose rows [begin, begin + count) of an (n, width) row-major array to / from planes
// first, ..., first + width - 1.
template <typename F>
struct Planar {
  std::vector<F> data;
  explicit Planar(int planes) : data(size_t(planes) * kBlock) {}
  F* plane(int c) { return data.data() + c * kBlock; }
  const F* plane(int c) const { return data.data() + c * kBlock; }
  void from_rows(const F* rows, int width, int64_t begin, int64_t count, int first = 0) {
    for (int64_t b = 0; b < count; ++b)
      for (int c = 0; c < width; ++c) data[(first + c) * kBlock + b] = rows[(begin + b) * width + c];
  }
  void to_rows(F* rows, int width, int64_t begin, int64_t count, int first = 0) const {
    for (int64_t b = 0; b < count; ++b)
      for (int c = 0; c < width; ++c) rows[(begin + b) * width + c] = data[(first + c) * kBlock + b];
  }
  Lanes<F> lanes(int c, int64_t b, int count) const { return load<F, 16>(plane(c) + b, count); }
  void set(int c, int64_t b, int count, const Lanes<F>& v) { store<F, 16>(plane(c) + b, count, v); }
};

// Half-vector values of a lane group (specular term).
template <typename F>
struct Half {
  using V = Lanes<F>;
  V hnorm, hden, h[3];          // |wi + wo|, its clamp at 1e-8, h = safe_normalize(wi + wo)
  V hl[3];                      // h in the shading frame: h . frame column c
  V cos_f_raw, cos_f, fresnel;  // wi . h, clamped to [0, 1], Schlick's f0 + (1 - f0)(1 - cos_f)^5
};

// The other forward values of a lane group.
template <typename F>
struct Shade {
  using V = Lanes<F>;
  V wi[3], normal[3], cos, lambert;   // wi, n, n . wi, f_d
  V sd[3], ss[3], sp[3], profile[3];  // softplus of the raw diffuse, specular, sss colours; the SSS profile
  V dbase[3], sbase[3], ssbase[3];    // sd / pi f_d, ss fresnel D, sp profile
  V inv_dist2, inc[3];                // 1/d^2, I * (1/d^2)
  V S;                                // shadow (1 when off)
  V d[3], s[3], t[3], colour[3];      // outputs: diffuse, specular, sss, colour
};

// Per-lobe loops over the B Gaussians of a block, on restrict pointers so that they vectorise (with AVX2 where the
// CPU has it: the passes below). A: the lobe's axes, A[3 m + c] = component m of axis c (x, y, z); hl0..2: the
// half vectors in the frames.

// (hx, hy, hz) = hl . (x, y, z), and with `arg` the exponent -lam hx^2 - mu hy^2 (<= 0: lam, mu > 0).
template <typename F>
OLATBENCH_SIMD void lobe_project(int64_t B, const F* A, F lam, F mu, const F* __restrict hl0, const F* __restrict hl1,
                  const F* __restrict hl2, F* __restrict hx, F* __restrict hy, F* __restrict hz, F* __restrict arg) {
  const F x0 = A[0], x1 = A[3], x2 = A[6], y0 = A[1], y1 = A[4], y2 = A[7], z0 = A[2], z1 = A[5], z2 = A[8];
  for (int64_t b = 0; b < B; ++b) {
    hx[b] = (hl0[b] * x0 + hl1[b] * x1) + hl2[b] * x2;
    hy[b] = (hl0[b] * y0 + hl1[b] * y1) + hl2[b] * y2;
    hz[b] = (hl0[b] * z0 + hl1[b] * z1) + hl2[b] * z2;
  }
  if (arg)
    for (int64_t b = 0; b < B; ++b) arg[b] = -lam * (hx[b] * hx[b]) - mu * (hy[b] * hy[b]);
}

// D += w max(hz, 0) e (D per Gaussian; called for the lobes in order).
template <typename F>
OLATBENCH_SIMD void lobe_mix(int64_t B, const F* __restrict w, const F* __restrict hz, const F* __restrict e,
                             F* __restrict D) {
  for (int64_t b = 0; b < B; ++b) D[b] += w[b] * ((hz[b] < F(0) ? F(0) : hz[b]) * e[b]);
}

// Backward of lobe_mix and lobe_project given g_D = dL/dD: d e / d a = e, max passes the gradient for hz >= 0.
// Writes dL/d(raw weight) `g_w`, dL/da `g_arg`, dL/d(hx, hy, hz) and adds dL/d hl into g_hl0..2.
template <typename F>
OLATBENCH_SIMD void lobe_backward(int64_t B, const F* A, F lam, F mu, const F* __restrict hx, const F* __restrict hy,
                   const F* __restrict hz, const F* __restrict e, const F* __restrict w,
                   const F* __restrict w_grad, const F* __restrict g_D, F* __restrict g_w, F* __restrict g_arg,
                   F* __restrict g_hx, F* __restrict g_hy, F* __restrict g_hz, F* __restrict g_hl0,
                   F* __restrict g_hl1, F* __restrict g_hl2) {
  const F x0 = A[0], x1 = A[3], x2 = A[6], y0 = A[1], y1 = A[4], y2 = A[7], z0 = A[2], z1 = A[5], z2 = A[8];
  for (int64_t b = 0; b < B; ++b) {
    const F z = hz[b];
    const F zpos = z < F(0) ? F(0) : z;
    g_w[b] = g_D[b] * (zpos * e[b]) * w_grad[b];
    const F g_e = g_D[b] * w[b] * e[b];  // dL/d max(hz, 0)
    const F ga = g_e * zpos;             // dL/da
    g_arg[b] = ga;
    g_hz[b] = z < F(0) ? F(0) : g_e;
    g_hx[b] = -ga * lam * F(2) * hx[b];
    g_hy[b] = -ga * mu * F(2) * hy[b];
    g_hl0[b] += (g_hx[b] * x0 + g_hy[b] * y0) + g_hz[b] * z0;
    g_hl1[b] += (g_hx[b] * x1 + g_hy[b] * y1) + g_hz[b] * z1;
    g_hl2[b] += (g_hx[b] * x2 + g_hy[b] * y2) + g_hz[b] * z2;
  }
}

// sum_b x(b) over b < count in double: eight partial sums (b mod 8), added pairwise at the end. A fixed order,
// written so that the loop vectorises.
template <typename F, typename Term>
OLATBENCH_SIMD double lane_sum(int64_t count, Term x) {
  double part[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int64_t b = 0;
  for (; b + 8 <= count; b += 8)
    for (int j = 0; j < 8; ++j) part[j] += double(x(b + j));
  for (int j = 0; b + j < count; ++j) part[j] += double(x(b + j));
  return ((part[0] + part[1]) + (part[2] + part[3])) + ((part[4] + part[5]) + (part[6] + part[7]));
}

// One block's lobe data: B Gaussians, N lobes; per-lobe arrays hold lobe l of Gaussian b at l B + b.
template <typename F>
struct LobeBlock {
  int64_t B;
  int N;
  const F *axes, *lam, *mu;  // (N,3,3), (N,), (N,)
  const F *hl0, *hl1, *hl2;  // the half vectors in the frames (B each)
  const F *w, *w_grad;       // softplus of the ASG weights and its derivative (the cache's)
  F *hx, *hy, *hz;
};

// Forward: hx, hy, hz, and D = sum_l w_l max(hz_l, 0) e_l; with e_out (the forward) the exponentials are computed
// into it first (then e = e_out).
template <typename F, int W>
OLATBENCH_SIMD void lobes_forward_pass(const LobeBlock<F>& lb, F* e_out, const F* e, F* D) {
  const int64_t B = lb.B;
  for (int l = 0; l < lb.N; ++l)
    lobe_project(B, lb.axes + 9 * l, lb.lam[l], lb.mu[l], lb.hl0, lb.hl1, lb.hl2, lb.hx + l * B, lb.hy + l * B,
                 lb.hz + l * B, e_out ? e_out + l * B : nullptr);
  if (e_out) exp_block<F, W>(e_out, lb.N * B, e_out);
  std::fill(D, D + B, F(0));
  for (int l = 0; l < lb.N; ++l) lobe_mix(B, lb.w + l * B, lb.hz + l * B, e + l * B, D);  // lobes in order
}

// Backward given g_D = dL/dD: dL/d(raw weights) into g_w (per lobe at l B + b), dL/d hl added into g_hl0..2, and
// the shared gradients added to acc (9N lobe axes as (N,3,3), then N lam, N mu): d/d lam_l = sum_b -g_arg hx^2,
// d/d mu_l = sum_b -g_arg hy^2, d/d A_l[m][c] = sum_b d/d(hx, hy, hz)_c hl_m. `work`: 4 B scratch values.
template <typename F>
OLATBENCH_SIMD void lobes_backward_pass(const LobeBlock<F>& lb, const F* e, const F* g_D, F* g_w, F* work,
                                        F* g_hl0, F* g_hl1, F* g_hl2, double* acc) {
  const int64_t B = lb.B;
  const int N = lb.N;
  const F *g_arg = work, *g_hx = work + B, *g_hy = work + 2 * B, *g_hz = work + 3 * B;
  const F* hl[3] = {lb.hl0, lb.hl1, lb.hl2};
  for (int l = 0; l < N; ++l) {
    const int64_t o = l * B;
    const F *px = lb.hx + o, *py = lb.hy + o;
    lobe_backward(B, lb.axes + 9 * l, lb.lam[l], lb.mu[l], px, py, lb.hz + o, e + o, lb.w + o, lb.w_grad + o, g_D,
                  g_w + o, work, work + B, work + 2 * B, work + 3 * B, g_hl0, g_hl1, g_hl2);
    acc[9 * N + l] += lane_sum<F>(B, [&](int64_t b) { return -g_arg[b] * (px[b] * px[b]); });
    acc[10 * N + l] += lane_sum<F>(B, [&](int64_t b) { return -g_arg[b] * (py[b] * py[b]); });
    for (int m = 0; m < 3; ++m) {
      const F* h = hl[m];
      double* g_axes = acc + 9 * l + 3 * m;
      g_axes[0] += lane_sum<F>(B, [&](int64_t b) { return g_hx[b] * h[b]; });
      g_axes[1] += lane_sum<F>(B, [&](int64_t b) { return g_hy[b] * h[b]; });
      g_axes[2] += lane_sum<F>(B, [&](int64_t b) { return g_hz[b] * h[b]; });
    }
  }
}

#ifdef OLATBENCH_SHADING_AVX2
template <typename F>
__attribute__((target("avx2"))) void lobes_forward_avx2(const LobeBlock<F>& lb, F* e_out, const F* e, F* D) {
  lobes_forward_pass<F, 32>(lb, e_out, e, D);
}
template <typename F>
__attribute__((target("avx2"))) void lobes_backward_avx2(const LobeBlock<F>& lb, const F* e, const F* g_D, F* g_w,
                                                         F* work, F* g_hl0, F* g_hl1, F* g_hl2, double* acc) {
  lobes_backward_pass(lb, e, g_D, g_w, work, g_hl0, g_hl1, g_hl2, acc);
}
#endif

template <typename F>
void lobes_forward(const LobeBlock<F>& lb, F* e_out, const F* e, F* D) {
#ifdef OLATBENCH_SHADING_AVX2
  if (have_avx2()) return lobes_forward_avx2(lb, e_out, e, D);
#endif
  lobes_forward_pass<F, 16>(lb, e_out, e, D);
}
template <typename F>
void lobes_backward(const LobeBlock<F>& lb, const F* e, const F* g_D, F* g_w, F* work, F* g_hl0, F* g_hl1,
                    F* g_hl2, double* acc) {
#ifdef OLATBENCH_SHADING_AVX2
  if (have_avx2()) return lobes_backward_avx2(lb, e, g_D, g_w, work, g_hl0, g_hl1, g_hl2, acc);
#endif
  lobes_backward_pass(lb, e, g_D, g_w, work, g_hl0, g_hl1, g_hl2, acc);
}

// Working memory of one block [begin, begin + size) and the phases both kernels share.
template <typename F>
struct CombineBlock {
  using V = Lanes<F>;
  static constexpr int L = Simd<F>::kLanes;
  const CombineInputs<F>& in;
  const CacheLayout& at;
  const int N;
  int64_t begin = 0, size = 0;
  Planar<F> wi{3}, wo{3}, frames{9}, inv_dist2{1}, shadow{1}, profile{3};  // the inputs (frames: 3 i + c)
  std::vector<Half<F>> half;  // per lane group: Gaussians [begin + L g, begin + L g + L)
  Planar<F> hl{3};            // half[g].hl, planar for the lobe loops
  std::vector<F> D;           // per Gaussian b: sum_l w_l max(hz_l, 0) e_l
  std::vector<F> hx, hy, hz;  // per lobe l and Gaussian b, at l size + b
  std::vector<F> buffer;      // N size scratch (transposed raw weights, weight gradients)

  CombineBlock(const CombineInputs<F>& inputs, const CacheLayout& layout)
      : in(inputs), at(layout), N(inputs.num_lobes), half(kBlock / L), D(kBlock), hx(kBlock * N), hy(kBlock * N),
        hz(kBlock * N), buffer(kBlock * std::max(N, 3)) {}

  // Start the block: its rows of the per-Gaussian inputs, planar.
  void start(int64_t first, int64_t end) {
    begin = first;
    size = end - first;
    wi.from_rows(in.wi, 3, begin, size);
    if (in.specular) wo.from_rows(in.wo, 3, begin, size);
    frames.from_rows(in.frames, 9, begin, size);
    inv_dist2.from_rows(in.inv_dist2, 1, begin, size);
    if (in.shadow) shadow.from_rows(in.shadow, 1, begin, size);
    if (in.sss) profile.from_rows(in.profile, in.profile_channels, begin, size);
  }
  int lanes(int64_t b) const { return int(std::min<int64_t>(L, size - b)); }

  // Softplus values and derivatives of the block's raw attributes into the cache (forward), in vectorised passes.
  void activate(F* cache) {
    const auto run = [&](const F* raw, int width, int64_t value, int64_t grad) {
      for (int64_t b = 0; b < size; ++b)  // planar
        for (int c = 0; c < width; ++c) buffer[c * size + b] = raw[(begin + b) * width + c];
      softplus_array(buffer.data(), width * size, cache + value + width * begin, cache + grad + width * begin);
    };
    run(in.diffuse, 3, at.sd, at.sd_grad);
    if (in.sss) run(in.sss, 3, at.sp, at.sp_grad);
    if (in.specular) {
      run(in.specular, 3, at.ss, at.ss_grad);
      run(in.asg_weights, N, at.sw, at.sw_grad);
    }
  }
  // Lanes of the cache's planar section `section` (width 3) of this block.
  V cached(const F* cache, int64_t section, int c, int64_t b, int count) const {
    return load<F, 16>(cache + section + 3 * begin + c * size + b, count);
  }

  void half_eval(int64_t b, int count, Half<F>& v) const {
    V w[3], hsum[3];
    for (int i = 0; i < 3; ++i) {
      w[i] = wi.lanes(i, b, count);
      hsum[i] = w[i] + wo.lanes(i, b, count);
    }
    v.hnorm = root(dot3(hsum, hsum));
    v.hden = lane_max<F>(v.hnorm, splat<F>(F(kNormEps)));
    for (int i = 0; i < 3; ++i) v.h[i] = hsum[i] / v.hden;
    for (int c = 0; c < 3; ++c)
      v.hl[c] = (v.h[0] * frames.lanes(c, b, count) + v.h[1] * frames.lanes(3 + c, b, count)) +
                v.h[2] * frames.lanes(6 + c, b, count);
    v.cos_f_raw = dot3(w, v.h);
    const V lower = select<F>(v.cos_f_raw < F(0), splat<F>(F(0)), v.cos_f_raw);  // std::min(std::max(c, 0), 1)
    v.cos_f = select<F>(F(1) < lower, splat<F>(F(1)), lower);
    const V m = F(1) - v.cos_f;
    v.fresnel = F(in.f0) + F(1.0 - in.f0) * (((m * m) * (m * m)) * m);
  }

  // Half vectors, the lobes' hx, hy, hz and D. With `e_out` (the forward) the exponentials are computed into it,
  // otherwise read from the cache.
  void lobes(const F* cache, F* e_out) {
    const int64_t B = size;
    for (int64_t b = 0; b < B; b += L) {
      half_eval(b, lanes(b), half[b / L]);
      for (int m = 0; m < 3; ++m) hl.set(m, b, lanes(b), half[b / L].hl[m]);
    }
    lobes_forward(lobe_block(cache), e_out, cache + at.e + N * begin, D.data());
  }
  LobeBlock<F> lobe_block(const F* cache) {
    return LobeBlock<F>{size, N, in.lobe_axes, in.lam, in.mu, hl.plane(0), hl.plane(1), hl.plane(2),
                        cache + at.sw + N * begin, cache + at.sw_grad + N * begin, hx.data(), hy.data(), hz.data()};
  }

  // The outputs of lane group b as Shader.forward computes them.
  void shade_eval(const F* cache, int64_t b, int count, Shade<F>& v) const {
    const V zero = splat<F>(F(0));
    const Half<F>* h = in.specular ? &half[b / L] : nullptr;
    const V Db = load<F, 16>(&D[b], count);
    for (int i = 0; i < 3; ++i) {
      v.wi[i] = wi.lanes(i, b, count);
      v.normal[i] = frames.lanes(3 * i + 2, b, count);
    }
    v.cos = dot3(v.normal, v.wi);
    if (in.smooth_cosine) {  // (ELU_a(c) + o) / (1 + o), o = a (1 - 1/e)
      const V negative = F(kSmoothAlpha) * (exp_nonpositive<F>(select<F>(v.cos < F(0), v.cos, zero)) - F(1));
      v.lambert = (select<F>(v.cos > F(0), v.cos, negative) + F(kSmoothOffset)) / F(1.0 + kSmoothOffset);
    } else {
      v.lambert = select<F>(v.cos < F(0), zero, v.cos);
    }
    v.S = in.shadow ? shadow.lanes(0, b, count) : splat<F>(F(1));
    v.inv_dist2 = inv_dist2.lanes(0, b, count);
    for (int c = 0; c < 3; ++c) {
      v.inc[c] = in.intensity[c] * v.inv_dist2;
      v.sd[c] = cached(cache, at.sd, c, b, count);
      v.dbase[c] = v.sd[c] / F(kPi) * v.lambert;
      v.sbase[c] = v.ssbase[c] = zero;
      if (h) {
        v.ss[c] = cached(cache, at.ss, c, b, count);
        v.sbase[c] = v.ss[c] * h->fresnel * Db;
      }
      if (in.sss) {  // the profile broadcast over RGB when it has one channel
        v.sp[c] = cached(cache, at.sp, c, b, count);
        v.profile[c] = profile.lanes(in.profile_channels == 3 ? c : 0, b, count);
        v.ssbase[c] = v.sp[c] * v.profile[c];
      }
      v.d[c] = v.dbase[c] * v.inc[c];
      v.s[c] = v.sbase[c] * v.inc[c];
      v.t[c] = v.ssbase[c] * v.inc[c];
      v.colour[c] = in.shadow_on_sss ? (v.d[c] + v.s[c] + v.t[c]) * v.S : (v.d[c] + v.s[c]) * v.S + v.t[c];
    }
  }
};

// Forward; fills `cache` (see CacheLayout) for the backward.
template <typename F>
void combine_forward(const CombineInputs<F>& in, int threads, F* colour, F* diffuse, F* specular, F* sss,
                     F* cache) {
  constexpr int L = Simd<F>::kLanes;
  const CacheLayout at(in.n, in.num_lobes);
  struct State {
    CombineBlock<F> block;
    Planar<F> out{12};  // colour, diffuse, specular, sss
    State(const CombineInputs<F>& inputs, const CacheLayout& layout) : block(inputs, layout) {}
  };
  const auto make_state = [&] { return State(in, at); };
  blocked_reduce(in.n, 0, threads, make_state, [&](State& state, int64_t begin, int64_t end, double*) {
    CombineBlock<F>& block = state.block;
    block.start(begin, end);
    block.activate(cache);
    if (in.specular) block.lobes(cache, cache + at.e + in.num_lobes * begin);
    Shade<F> v;
    for (int64_t b = 0; b < block.size; b += L) {
      const int count = block.lanes(b);
      block.shade_eval(cache, b, count, v);
      for (int c = 0; c < 3; ++c) {
        state.out.set(c, b, count, v.colour[c]);
        state.out.set(3 + c, b, count, v.d[c]);
        state.out.set(6 + c, b, count, v.s[c]);
        state.out.set(9 + c, b, count, v.t[c]);
      }
    }
    F* rows[4] = {colour, diffuse, specular, sss};
    for (int o = 0; o < 4; ++o) state.out.to_rows(rows[o], 3, begin, block.size, 3 * o);
  });
}

// Gradients of the combine kernel. Output gradients (g_*) may be null (zero). Per-Gaussian results are
// written; grad_specular, grad_asg_weights are only written when specular is on, grad_sss, grad_profile when
// sss is, grad_shadow when shadow is. grad_intensity (3), grad_lobe_axes (N,3,3), grad_lam, grad_mu (N) are
// block-reduced (the lobe ones only when specular is on). `cache`: as filled by the forward.
template <typename F>
void combine_backward(const CombineInputs<F>& in, int threads, const F* cache, const F* g_colour,
                      const F* g_diffuse, const F* g_specular, const F* g_sss, F* grad_wi, F* grad_wo,
                      F* grad_frames, F* grad_inv, F* grad_intensity, F* grad_diffuse, F* grad_specular,
                      F* grad_asg_weights, F* grad_lobe_axes, F* grad_lam, F* grad_mu, F* grad_sss,
                      F* grad_profile, F* grad_shadow) {
  using V = Lanes<F>;
  constexpr int L = Simd<F>::kLanes;
  const int N = in.num_lobes;
  const CacheLayout at(in.n, N);
  const V zero = splat<F>(F(0));
  const F* g_outputs[4] = {g_colour, g_diffuse, g_specular, g_sss};
  // Working memory besides the block's: the output gradients and every per-Gaussian result, planar.
  struct State {
    CombineBlock<F> block;
    Planar<F> g_out{12};                                  // dL/d(colour, diffuse, specular, sss)
    Planar<F> g_wi{3}, g_wo{3}, g_frames{9}, g_inv{1}, g_shadow{1}, g_profile{3};
    Planar<F> g_raw{9};                                   // dL/d raw diffuse, specular, sss
    Planar<F> g_D{1}, work{4};                            // dL/dD, lobes_backward_pass's scratch
    Planar<F> g_h{3}, g_hl{3};                            // dL/dh from the Fresnel factor, dL/d hl
    State(const CombineInputs<F>& inputs, const CacheLayout& layout) : block(inputs, layout) {}
  };
  const auto make_state = [&] { return State(in, at); };
  // Shared accumulators: intensity (3), then lobe axes (9N, as (N,3,3)), lam (N), mu (N).
  const int width = 3 + (in.specular ? 11 * N : 0);
  const auto body = [&](State& state, int64_t begin, int64_t end, double* acc) {
    CombineBlock<F>& block = state.block;
    block.start(begin, end);
    const int64_t B = block.size;
    for (int o = 0; o < 4; ++o)
      if (g_outputs[o]) state.g_out.from_rows(g_outputs[o], 3, begin, B, 3 * o);
    if (in.specular) block.lobes(cache, nullptr);
    Shade<F> v;
    for (int64_t b = 0; b < B; b += L) {
      const int count = block.lanes(b);
      const Half<F>* half = in.specular ? &block.half[b / L] : nullptr;
      const V D = load<F, 16>(&block.D[b], count);
      block.shade_eval(cache, b, count, v);
      const auto output_grad = [&](int o, int c) {
        return g_outputs[o] ? state.g_out.lanes(3 * o + c, b, count) : zero;
      };
      V g_lambert = zero, g_fresnel = zero, g_D = zero, g_S = zero, g_inv = zero, g_profile1 = zero;
      for (int c = 0; c < 3; ++c) {
        // colour = (d + s + t) S  or  (d + s) S + t: each output's total gradient adds colour's share.
        const V gc = output_grad(0, c);
        const V g_d = output_grad(1, c) + gc * v.S;
        const V g_s = output_grad(2, c) + gc * v.S;
        const V g_t = output_grad(3, c) + (in.shadow_on_sss ? gc * v.S : gc);
        g_S += gc * (in.shadow_on_sss ? v.d[c] + v.s[c] + v.t[c] : v.d[c] + v.s[c]);
        // Each output is base * inc with inc = I_c / d^2 = I_c * inv_dist2.
        const V g_inc = g_d * v.dbase[c] + g_s * v.sbase[c] + g_t * v.ssbase[c];
        const V g_intensity = g_inc * v.inv_dist2;
        for (int j = 0; j < count; ++j) acc[c] += double(g_intensity[j]);  // in Gaussian order
        g_inv += g_inc * in.intensity[c];
        // dbase = softplus(raw) / pi * f_d.
        const V g_dbase = g_d * v.inc[c];
        state.g_raw.set(c, b, count, g_dbase * v.lambert / F(kPi) * block.cached(cache, at.sd_grad, c, b, count));
        g_lambert += g_dbase * (v.sd[c] / F(kPi));
        if (half) {  // sbase = softplus(raw) * fresnel * D
          const V g_sbase = g_s * v.inc[c];
          state.g_raw.set(3 + c, b, count,
                          g_sbase * half->fresnel * D * block.cached(cache, at.ss_grad, c, b, count));
          g_fresnel += g_sbase * v.ss[c] * D;
          g_D += g_sbase * v.ss[c] * half->fresnel;
        }
        if (in.sss) {  // ssbase = softplus(raw) * profile
          const V g_ssbase = g_t * v.inc[c];
          state.g_raw.set(6 + c, b, count, g_ssbase * v.profile[c] * block.cached(cache, at.sp_grad, c, b, count));
          if (in.profile_channels == 3) state.g_profile.set(c, b, count, g_ssbase * v.sp[c]);
          else g_profile1 += g_ssbase * v.sp[c];
        }
      }
      state.g_inv.set(0, b, count, g_inv);
      if (in.sss && in.profile_channels == 1) state.g_profile.set(0, b, count, g_profile1);
      if (in.shadow) state.g_shadow.set(0, b, count, g_S);
      // f_d: clamped max(c, 0) passes the gradient for c >= 0; smooth (ELU_a(c) + o) / (1 + o) has slope
      // 1 / (1 + o) for c > 0 and a exp(c) / (1 + o) for c <= 0. c = n . wi.
      V g_cos;
      if (in.smooth_cosine) {
        const V g_elu = g_lambert / F(1.0 + kSmoothOffset);
        const V slope = F(kSmoothAlpha) * exp_nonpositive<F>(select<F>(v.cos < F(0), v.cos, zero));
        g_cos = select<F>(v.cos > F(0), g_elu, g_elu * slope);
      } else {
        g_cos = select<F>(v.cos >= F(0), g_lambert, zero);
      }
      V g_wi[3];
      for (int i = 0; i < 3; ++i) {
        g_wi[i] = g_cos * v.normal[i];
        for (int c = 0; c < 2; ++c) state.g_frames.set(3 * i + c, b, count, zero);
        state.g_frames.set(3 * i + 2, b, count, g_cos * v.wi[i]);
        state.g_wo.set(i, b, count, zero);
      }
      if (half) {
        // fresnel = f0 + (1 - f0)(1 - c)^5 with c = clamp(wi . h, 0, 1): d/dc = -5 (1 - f0)(1 - c)^4 where
        // 0 <= wi . h <= 1.
        const LaneMask<F> inside = (half->cos_f_raw >= F(0)) & (half->cos_f_raw <= F(1));
        const V m = F(1) - half->cos_f;
        const V g_c = select<F>(inside, -(g_fresnel * F(1.0 - in.f0) * (F(5) * ((m * m) * (m * m)))), zero);
        for (int i = 0; i < 3; ++i) {
          g_wi[i] += g_c * half->h[i];
          state.g_h.set(i, b, count, g_c * v.wi[i]);
        }
        state.g_D.set(0, b, count, g_D);
      }
      for (int i = 0; i < 3; ++i) state.g_wi.set(i, b, count, g_wi[i]);
    }

    if (in.specular) {
      // The lobes (D = sum_l w_l max(hz_l, 0) e_l): see lobes_backward_pass.
      std::fill(state.g_hl.data.begin(), state.g_hl.data.end(), F(0));
      lobes_backward(block.lobe_block(cache), cache + at.e + N * begin, state.g_D.plane(0), block.buffer.data(),
                     state.work.plane(0), state.g_hl.plane(0), state.g_hl.plane(1), state.g_hl.plane(2), acc + 3);
      for (int64_t b = 0; b < B; ++b)  // weight gradients back to rows (n, N)
        for (int l = 0; l < N; ++l) grad_asg_weights[(begin + b) * N + l] = block.buffer[l * B + b];

      // Back through hl_c = h . frame column c and h = safe_normalize(wi + wo) (as in the geometry's wo).
      for (int64_t b = 0; b < B; b += L) {
        const int count = block.lanes(b);
        const Half<F>& half = block.half[b / L];
        V gh[3], ghl[3];
        for (int i = 0; i < 3; ++i) {
          gh[i] = state.g_h.lanes(i, b, count);
          ghl[i] = state.g_hl.lanes(i, b, count);
        }
        for (int i = 0; i < 3; ++i)
          for (int c = 0; c < 3; ++c) {
            gh[i] += ghl[c] * block.frames.lanes(3 * i + c, b, count);
            state.g_frames.set(3 * i + c, b, count, state.g_frames.lanes(3 * i + c, b, count) + ghl[c] * half.h[i]);
          }
        const V h_g = dot3(half.h, gh);
        const LaneMask<F> norm_used = half.hnorm >= F(kNormEps);
        for (int i = 0; i < 3; ++i) {
          const V g_hsum = select<F>(norm_used, gh[i] - half.h[i] * h_g, gh[i]) / half.hden;
          state.g_wi.set(i, b, count, state.g_wi.lanes(i, b, count) + g_hsum);
          state.g_wo.set(i, b, count, g_hsum);
        }
      }
    }

    // The per-Gaussian results back to rows.
    state.g_wi.to_rows(grad_wi, 3, begin, B);
    state.g_wo.to_rows(grad_wo, 3, begin, B);
    state.g_frames.to_rows(grad_frames, 9, begin, B);
    state.g_inv.to_rows(grad_inv, 1, begin, B);
    if (in.shadow) state.g_shadow.to_rows(grad_shadow, 1, begin, B);
    if (in.sss) state.g_profile.to_rows(grad_profile, in.profile_channels, begin, B);
    state.g_raw.to_rows(grad_diffuse, 3, begin, B, 0);
    if (in.specular) state.g_raw.to_rows(grad_specular, 3, begin, B, 3);
    if (in.sss) state.g_raw.to_rows(grad_sss, 3, begin, B, 6);
  };
  const std::vector<double> shared = blocked_reduce(in.n, width, threads, make_state, body);
  for (int c = 0; c < 3; ++c) grad_intensity[c] = F(shared[c]);
  if (in.specular) {
    for (int i = 0; i < 9 * N; ++i) grad_lobe_axes[i] = F(shared[3 + i]);
    for (int l = 0; l < N; ++l) {
      grad_lam[l] = F(shared[3 + 9 * N + l]);
      grad_mu[l] = F(shared[3 + 10 * N + l]);
    }
  }
}

}  // namespace

// The combine kernel's inputs, in the order both exported combine functions take them.
#define OLATBENCH_SHADING_COMBINE_ARGS(F)                                                                   \
  const F *wi, const F *wo, const F *frames, const F *inv_dist2, const F *intensity, const F *diffuse,      \
      const F *specular, const F *asg_weights, const F *lobe_axes, const F *lam, const F *mu, int num_lobes, \
      const F *sss, const F *profile, int profile_channels, const F *shadow, int64_t n, int smooth_cosine,  \
      int shadow_on_sss, double f0, int threads
#define OLATBENCH_SHADING_COMBINE_INPUTS(F)                                                                 \
  CombineInputs<F> {                                                                                        \
    wi, wo, frames, inv_dist2, intensity, diffuse, specular, asg_weights, lobe_axes, lam, mu, num_lobes, sss, \
        profile, profile_channels, shadow, n, smooth_cosine != 0, shadow_on_sss != 0, f0                    \
  }

#define OLATBENCH_SHADING_DEFINE(F, SUFFIX)                                                                  \
  OLATBENCH_EXPORT void olatbench_shading_rotations_forward_##SUFFIX(const F* quats, int64_t n,             \
                                                                             F* rotations) {                \
    for (int64_t k = 0; k < n; ++k) {                                                                       \
      Rotation<F> r;                                                                                        \
      rotation_eval<F>(quats + 4 * k, r);                                                                   \
      std::memcpy(rotations + 9 * k, r.R, sizeof(r.R));                                                     \
    }                                                                                                       \
  }                                                                                                         \
  OLATBENCH_EXPORT void olatbench_shading_rotations_backward_##SUFFIX(                                      \
      const F* quats, int64_t n, const F* grad_rotations, F* grad_quats) {                                  \
    for (int64_t k = 0; k < n; ++k) {                                                                       \
      Rotation<F> r;                                                                                        \
      rotation_eval<F>(quats + 4 * k, r);                                                                   \
      F gR[3][3];                                                                                           \
      std::memcpy(gR, grad_rotations + 9 * k, sizeof(gR));                                                  \
      rotation_backward<F>(r, gR, grad_quats + 4 * k);                                                      \
    }                                                                                                       \
  }                                                                                                         \
  OLATBENCH_EXPORT void olatbench_shading_geometry_forward_##SUFFIX(                                        \
      const F* positions, const F* quats, const F* scales, const F* camera, const F* light, int64_t n,      \
      int orient, int threads, F* wi, F* wo, F* frames, F* inv_dist2) {                                     \
    geometry_forward<F>(GeometryInputs<F>{positions, quats, scales, camera, light, n, orient != 0}, threads, wi,\
                        wo, frames, inv_dist2);                                                             \
  }                                                                                                         \
  OLATBENCH_EXPORT void olatbench_shading_geometry_backward_##SUFFIX(                                       \
      const F* positions, const F* quats, const F* scales, const F* camera, const F* light, int64_t n,      \
      int orient, int threads, const F* g_wi, const F* g_wo, const F* g_frames, const F* g_inv,             \
      F* grad_positions, F* grad_quats, F* grad_camera, F* grad_light) {                                    \
    geometry_backward<F>(GeometryInputs<F>{positions, quats, scales, camera, light, n, orient != 0}, threads,\
                         g_wi, g_wo, g_frames, g_inv, grad_positions, grad_quats, grad_camera, grad_light); \
  }                                                                                                         \
  OLATBENCH_EXPORT void olatbench_shading_combine_forward_##SUFFIX(                                         \
      OLATBENCH_SHADING_COMBINE_ARGS(F), F* colour, F* diffuse_out, F* specular_out, F* sss_out,            \
      F* cache) {                                                                                           \
    combine_forward<F>(OLATBENCH_SHADING_COMBINE_INPUTS(F), threads, colour, diffuse_out, specular_out,     \
                       sss_out, cache);                                                                     \
  }                                                                                                         \
  OLATBENCH_EXPORT void olatbench_shading_combine_backward_##SUFFIX(                                        \
      OLATBENCH_SHADING_COMBINE_ARGS(F), const F* cache, const F* g_colour, const F* g_diffuse,             \
      const F* g_specular, const F* g_sss, F* grad_wi, F* grad_wo, F* grad_frames, F* grad_inv,             \
      F* grad_intensity, F* grad_diffuse, F* grad_specular, F* grad_asg_weights, F* grad_lobe_axes,         \
      F* grad_lam, F* grad_mu, F* grad_sss, F* grad_profile, F* grad_shadow) {                              \
    combine_backward<F>(OLATBENCH_SHADING_COMBINE_INPUTS(F), threads, cache, g_colour, g_diffuse,           \
                        g_specular, g_sss, grad_wi, grad_wo, grad_frames, grad_inv, grad_intensity,         \
                        grad_diffuse, grad_specular, grad_asg_weights, grad_lobe_axes, grad_lam, grad_mu,   \
                        grad_sss, grad_profile, grad_shadow);                                               \
  }

OLATBENCH_SHADING_DEFINE(float, f32)
OLATBENCH_SHADING_DEFINE(double, f64)

OLATBENCH_DEFINE_ABI_VERSION()
