// olatbench CPU SSIM training loss: forward and hand-written backward of the "3dgs" SSIM
// (3D Gaussian Splatting's utils/loss_utils.ssim): 11-tap Gaussian window (sigma 1.5) applied separably with
// ZERO padding of 5 px ('same' output size), K1 = 0.01, K2 = 0.03, data range 1, population covariances,
// mean of the SSIM map over every pixel of every plane.
//
// Plain C ABI on raw pointers (no torch headers): called from Python through ctypes (metrics/ssim_cpu.py).
// Every function exists for float (_f32) and double (_f64). pred and gt are (B, C, H, W) images given by a
// pointer and four element strides (b, c, y, x) each, so NCHW, NHWC (channels-last) and broadcast layouts are
// read in place; grad_pred is written with pred's strides (so pred must not overlap itself). Rows
// r = (b * C + c) * H + y run over the B*C planes of H x W; the derivative maps are planar (3 blocks of
// B*C*H*W). The rows are split into one contiguous chunk per OpenMP thread; every value is computed by the
// same arithmetic whichever chunk holds it, the SSIM map is summed per row in double and the row sums are then
// added in row order, so results do not depend on the thread count.
//
// Blur: separable, horizontal then vertical. Each thread walks its rows in order, keeping the horizontal
// blurs of the rows its current vertical window needs in a ring of 11 rows (cache-resident, no image-sized
// scratch). Out-of-image samples read zeros (a zero-bordered row copy horizontally, a zero row vertically),
// i.e. zero padding.
//
// Backward. The forward stores the three derivatives below at every pixel (when a gradient is wanted); the
// backward blurs them and combines them with the images. With mu_p = blur(p), mu_g = blur(g),
// E_pp = blur(p*p), E_gg = blur(g*g), E_pg = blur(p*g),
//   var_p = E_pp - mu_p^2, var_g = E_gg - mu_g^2, cov = E_pg - mu_p mu_g,
//   A1 = 2 mu_p mu_g + C1, A2 = 2 cov + C2, B1 = mu_p^2 + mu_g^2 + C1, B2 = var_p + var_g + C2,
//   s = A1 A2 / (B1 B2), so ds = s (dA1/A1 + dA2/A2 - dB1/B1 - dB2/B2), and holding mu_g, E_gg fixed:
//   dA1/dmu_p = 2 mu_g, dA2/dmu_p = -2 mu_g, dA2/dE_pg = 2, dB1/dmu_p = 2 mu_p, dB2/dmu_p = -2 mu_p,
//   dB2/dE_pp = 1, giving
//   ds/dmu_p = 2 mu_g (A2 - A1) / (B1 B2) + 2 mu_p s (1/B2 - 1/B1),
//   ds/dE_pp = -s / B2,
//   ds/dE_pg = 2 A1 / (B1 B2).
// The loss is L = 1 - sum(s) / N (N = B*C*H*W); the caller passes grad_scale = -dOut/N. The zero-padded
// 'same' blur with a symmetric kernel is a symmetric matrix (M[y][q] = t[q - y + 5] = t[y - q + 5]), hence its
// own adjoint, and the chain rule through mu_p = blur(p), E_pp = blur(p^2), E_pg = blur(p g) gives
//   dL/dp = grad_scale * (blur(ds/dmu_p) + 2 p blur(ds/dE_pp) + g blur(ds/dE_pg)).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "export.h"
#include "float_mode.h"

namespace {

constexpr int kRadius = 5;
constexpr int kTaps = 2 * kRadius + 1;
constexpr double kSigma = 1.5;
constexpr double kC1 = 0.01 * 0.01;  // (K1 * data range)^2
constexpr double kC2 = 0.03 * 0.03;  // (K2 * data range)^2

template <typename F>
struct Taps {
  F t[kTaps];
};

// exp(-(i - 5)^2 / (2 sigma^2)) normalised to sum 1, computed in double then cast (as metrics/ssim.py does).
template <typename F>
Taps<F> gaussian_taps() {
  double raw[kTaps];
  double sum = 0.0;
  for (int i = 0; i < kTaps; ++i) {
    const double d = double(i - kRadius);
    raw[i] = std::exp(-(d * d) / (2.0 * kSigma * kSigma));
    sum += raw[i];
  }
  Taps<F> taps;
  for (int i = 0; i < kTaps; ++i) taps.t[i] = F(raw[i] / sum);
  return taps;
}

// out[x] = sum_k t[k] * padded[x + k] for x in [0, width): the horizontal blur of a row stored with kRadius
// zeros on each side. The taps are symmetric (t[k] = t[kTaps - 1 - k]), so mirrored samples share a product.
template <typename F>
inline void blur_row(const F* __restrict padded, int64_t width, const Taps<F>& taps, F* __restrict out) {
  const Taps<F> t = taps;
  for (int64_t x = 0; x < width; ++x) {
    F acc = t.t[kRadius] * padded[x + kRadius];
#pragma GCC unroll 8
    for (int k = 0; k < kRadius; ++k) acc += t.t[k] * (padded[x + k] + padded[x + kTaps - 1 - k]);
    out[x] = acc;
  }
}

// out[x] = sum_k t[k] * rows[k][x]: the vertical blur; rows outside the image point at a zero row.
template <typename F>
inline void blur_column(const F* const* rows, int64_t width, const Taps<F>& taps, F* __restrict out) {
  const Taps<F> t = taps;
  const F* __restrict r[kTaps];
  for (int k = 0; k < kTaps; ++k) r[k] = rows[k];
  for (int64_t x = 0; x < width; ++x) {
    F acc = t.t[kRadius] * r[kRadius][x];
#pragma GCC unroll 8
    for (int k = 0; k < kRadius; ++k) acc += t.t[k] * (r[k][x] + r[kTaps - 1 - k][x]);
    out[x] = acc;
  }
}

// One thread's share of the rows [0, B*C*H) (row r = plane * H + y): rows are processed in
// order, and the horizontal blurs of the `maps` quantities of the rows a vertical window needs are kept in a
// ring of kTaps rows per quantity, each computed once per chunk (the chunking does not change any value).
template <typename F>
class Ring {
 public:
  Ring(int maps, int64_t height, int64_t width)
      : maps_(maps), height_(height), width_(width), stride_(width + 2 * kRadius),
        rows_(size_t(maps) * kTaps * size_t(width)), padded_(size_t(maps) * size_t(stride_), F(0)),
        zeros_(size_t(width), F(0)) {}

  // Zero-bordered row of quantity m to fill before `blur_pending`.
  F* padded(int m) { return padded_.data() + m * stride_ + kRadius; }

  // Rows still to be blurred horizontally so that output row r's vertical window is available, in order.
  void pending(int64_t r, int64_t* first, int64_t* last) {
    const int64_t y = r % height_, base = r - y;
    *first = std::max(next_, base + std::max<int64_t>(0, y - kRadius));
    *last = base + std::min(height_ - 1, y + kRadius);
    next_ = *last + 1;
  }

  // Horizontal blur of the filled padded rows into the ring slot of row q.
  void blur_pending(int64_t q, const Taps<F>& taps) {
    for (int m = 0; m < maps_; ++m) blur_row(padded_.data() + m * stride_, width_, taps, slot(m, q));
  }

  // Vertical blur of quantity m at output row r.
  void blur_vertical(int m, int64_t r, const Taps<F>& taps, F* out) {
    const int64_t y = r % height_;
    const F* window[kTaps];
    for (int k = 0; k < kTaps; ++k) {
      const int64_t yy = y + k - kRadius;
      window[k] = (yy >= 0 && yy < height_) ? slot(m, r + k - kRadius) : zeros_.data();
    }
    blur_column(window, width_, taps, out);
  }

 private:
  F* slot(int m, int64_t q) { return rows_.data() + (size_t(m) * kTaps + size_t(q % kTaps)) * size_t(width_); }

  int maps_;
  int64_t height_, width_, stride_, next_ = 0;
  std::vector<F> rows_, padded_, zeros_;
};

// A (B, C, H, W) image with element strides (b, c, y, x): any dense, channels-last or broadcast layout.
template <typename F>
struct Image {
  F* data;
  const int64_t* strides;

  // First element of row r = (b * channels + c) * height + y; its pixels are step() elements apart.
  F* row(int64_t r, int64_t channels, int64_t height) const {
    const int64_t plane = r / height, y = r % height;
    return data + (plane / channels) * strides[0] + (plane % channels) * strides[1] + y * strides[2];
  }
  int64_t step() const { return strides[3]; }
};

// The five quantities the forward blurs (p, g, p^2, g^2, p g) of one row, into q_p .. q_pg. Called with
// literal unit steps for contiguous rows, so that this copy of the loop vectorises.
template <typename F>
inline void fill_products(const F* __restrict p, int64_t sp, const F* __restrict g, int64_t sg, int64_t width,
                          F* __restrict q_p, F* __restrict q_g, F* __restrict q_pp, F* __restrict q_gg,
                          F* __restrict q_pg) {
  for (int64_t x = 0; x < width; ++x) {
    const F px = p[x * sp], gx = g[x * sg];
    q_p[x] = px;
    q_g[x] = gx;
    q_pp[x] = px * px;
    q_gg[x] = gx * gx;
    q_pg[x] = px * gx;
  }
}

// out = scale * (b_mu + 2 p b_pp + g b_pg) for one row; out has p's step. Unit steps as for fill_products.
template <typename F>
inline void combine_gradient(const F* __restrict b_mu, const F* __restrict b_pp, const F* __restrict b_pg,
                             const F* __restrict p, int64_t sp, const F* __restrict g, int64_t sg, F scale,
                             int64_t width, F* __restrict out) {
  for (int64_t x = 0; x < width; ++x)
    out[x * sp] = scale * (b_mu[x] + F(2) * p[x * sp] * b_pp[x] + g[x * sg] * b_pg[x]);
}

// One chunk of rows per thread (at least 1, at most one per row).
inline int chunk_count(int64_t rows, int threads) {
  return int(std::max<int64_t>(1, std::min<int64_t>(threads, rows)));
}

// Rows [first, last) of chunk c out of `chunks` (a partition of [0, rows)).
inline void chunk_rows(int64_t rows, int chunks, int c, int64_t* first, int64_t* last) {
  *first = rows * c / chunks;
  *last = rows * (c + 1) / chunks;
}

// Sum of a row in double, as kLanes partial sums (of x = j mod kLanes) added in a fixed order: independent
// add chains instead of one latency-bound chain, and a value that depends only on the row.
template <typename F>
inline double row_sum(const F* __restrict s, int64_t width) {
  constexpr int kLanes = 8;
  double part[kLanes] = {};
  int64_t x = 0;
  for (; x + kLanes <= width; x += kLanes)
    for (int j = 0; j < kLanes; ++j) part[j] += double(s[x + j]);
  for (int j = 0; x < width; ++x, ++j) part[j] += double(s[x]);
  double sum = 0.0;
  for (int j = 0; j < kLanes; ++j) sum += part[j];
  return sum;
}

// The derivatives of the SSIM map at one row with respect to mu_p, E_pp and E_pg (see the header comment).
template <typename F>
inline void ssim_derivatives(const F* __restrict mu_p, const F* __restrict mu_g, const F* __restrict e_pp,
                             const F* __restrict e_gg, const F* __restrict e_pg, int64_t width, F* __restrict d_mu,
                             F* __restrict d_pp, F* __restrict d_pg) {
  const F c1 = F(kC1), c2 = F(kC2);
  for (int64_t x = 0; x < width; ++x) {
    const F mp = mu_p[x], mg = mu_g[x];
    const F a1 = F(2) * mp * mg + c1;
    const F a2 = F(2) * (e_pg[x] - mp * mg) + c2;
    const F inv_b1 = F(1) / (mp * mp + mg * mg + c1);
    const F inv_b2 = F(1) / ((e_pp[x] - mp * mp) + (e_gg[x] - mg * mg) + c2);
    const F inv_b1b2 = inv_b1 * inv_b2;
    const F s = a1 * a2 * inv_b1b2;
    d_mu[x] = F(2) * (mg * (a2 - a1) * inv_b1b2 + mp * s * (inv_b2 - inv_b1));
    d_pp[x] = -s * inv_b2;
    d_pg[x] = F(2) * a1 * inv_b1b2;
  }
}

// *ssim_sum = sum of the SSIM map (double). If `derivatives` is not null it receives 3 blocks of B*C*H*W:
// ds/dmu_p, ds/dE_pp, ds/dE_pg at every pixel, all the backward needs besides the images.
template <typename F>
void forward_impl(Image<const F> pred, Image<const F> gt, int64_t batch, int64_t channels, int64_t height,
                  int64_t width, int threads, F* derivatives, double* ssim_sum) {
  constexpr int kMaps = 5;  // mu_p, mu_g, E_pp, E_gg, E_pg
  const Taps<F> taps = gaussian_taps<F>();
  const int64_t planes = batch * channels, total = planes * height * width, rows = planes * height;
  const int64_t sp = pred.step(), sg = gt.step();
  const F c1 = F(kC1), c2 = F(kC2);
  const int chunks = chunk_count(rows, threads);
  std::vector<double> row_sums(size_t(rows), 0.0);
  parallel_for_static(chunks, chunks, [&](int c) {
    int64_t r0, r1;
    chunk_rows(rows, chunks, c, &r0, &r1);
    Ring<F> ring(kMaps, height, width);
    std::vector<F> blurred(static_cast<size_t>(kMaps * width)), ssim_row(static_cast<size_t>(width));
    const F* __restrict mu_p = blurred.data();
    const F* __restrict mu_g = mu_p + width;
    const F* __restrict e_pp = mu_p + 2 * width;
    const F* __restrict e_gg = mu_p + 3 * width;
    const F* __restrict e_pg = mu_p + 4 * width;
    for (int64_t r = r0; r < r1; ++r) {
      int64_t first, last;
      ring.pending(r, &first, &last);
      for (int64_t q = first; q <= last; ++q) {
        const F* p = pred.row(q, channels, height);
        const F* g = gt.row(q, channels, height);
        F *q_p = ring.padded(0), *q_g = ring.padded(1), *q_pp = ring.padded(2), *q_gg = ring.padded(3),
          *q_pg = ring.padded(4);
        if (sp == 1 && sg == 1)
          fill_products(p, 1, g, 1, width, q_p, q_g, q_pp, q_gg, q_pg);
        else
          fill_products(p, sp, g, sg, width, q_p, q_g, q_pp, q_gg, q_pg);
        ring.blur_pending(q, taps);
      }
      for (int m = 0; m < kMaps; ++m) ring.blur_vertical(m, r, taps, blurred.data() + m * width);
      F* __restrict s = ssim_row.data();
      for (int64_t x = 0; x < width; ++x) {  // same expression as metrics/ssim.py::ssim_map_torch
        const F var_p = e_pp[x] - mu_p[x] * mu_p[x], var_g = e_gg[x] - mu_g[x] * mu_g[x];
        const F cov = e_pg[x] - mu_p[x] * mu_g[x];
        const F numerator = (F(2) * mu_p[x] * mu_g[x] + c1) * (F(2) * cov + c2);
        const F denominator = (mu_p[x] * mu_p[x] + mu_g[x] * mu_g[x] + c1) * (var_p + var_g + c2);
        s[x] = numerator / denominator;
      }
      row_sums[size_t(r)] = row_sum(s, width);
      if (derivatives) {
        F* d = derivatives + r * width;
        ssim_derivatives(mu_p, mu_g, e_pp, e_gg, e_pg, width, d, d + total, d + 2 * total);
      }
    }
  });
  double sum = 0.0;
  for (int64_t r = 0; r < rows; ++r) sum += row_sums[size_t(r)];
  *ssim_sum = sum;
}

// grad_pred = grad_scale * (blur(ds/dmu_p) + 2 p blur(ds/dE_pp) + g blur(ds/dE_pg)), see the header comment;
// `derivatives` as written by forward_impl.
template <typename F>
void backward_impl(Image<const F> pred, Image<const F> gt, const F* derivatives, int64_t batch, int64_t channels,
                   int64_t height, int64_t width, int threads, double grad_scale, F* grad_pred) {
  constexpr int kGrads = 3;
  const Taps<F> taps = gaussian_taps<F>();
  const int64_t planes = batch * channels, total = planes * height * width, rows = planes * height;
  const int64_t sp = pred.step(), sg = gt.step();
  const Image<F> grad{grad_pred, pred.strides};
  const F scale = F(grad_scale);
  const int chunks = chunk_count(rows, threads);
  parallel_for_static(chunks, chunks, [&](int c) {
    int64_t r0, r1;
    chunk_rows(rows, chunks, c, &r0, &r1);
    Ring<F> ring(kGrads, height, width);
    std::vector<F> blurred(static_cast<size_t>(kGrads * width));
    for (int64_t r = r0; r < r1; ++r) {
      int64_t first, last;
      ring.pending(r, &first, &last);
      for (int64_t q = first; q <= last; ++q) {
        for (int m = 0; m < kGrads; ++m) {
          const F* __restrict d = derivatives + m * total + q * width;
          F* __restrict padded = ring.padded(m);
          for (int64_t x = 0; x < width; ++x) padded[x] = d[x];
        }
        ring.blur_pending(q, taps);
      }
      for (int m = 0; m < kGrads; ++m) ring.blur_vertical(m, r, taps, blurred.data() + m * width);
      const F *b_mu = blurred.data(), *b_pp = b_mu + width, *b_pg = b_mu + 2 * width;
      const F* p = pred.row(r, channels, height);
      const F* g = gt.row(r, channels, height);
      F* out = grad.row(r, channels, height);
      if (sp == 1 && sg == 1)
        combine_gradient(b_mu, b_pp, b_pg, p, 1, g, 1, scale, width, out);
      else
        combine_gradient(b_mu, b_pp, b_pg, p, sp, g, sg, scale, width, out);
    }
  });
}

}  // namespace

#define OLATBENCH_SSIM_DEFINE(F, SUFFIX)                                                                      \
  OLATBENCH_EXPORT void olatbench_ssim_loss_forward_##SUFFIX(                                                \
      const F* pred, const int64_t* pred_strides, const F* gt, const int64_t* gt_strides, int64_t batch,     \
      int64_t channels, int64_t height, int64_t width, int threads, F* derivatives, double* ssim_sum) {      \
    forward_impl<F>(Image<const F>{pred, pred_strides}, Image<const F>{gt, gt_strides}, batch, channels,     \
                    height, width, threads, derivatives, ssim_sum);                                         \
  }                                                                                                         \
  OLATBENCH_EXPORT void olatbench_ssim_loss_backward_##SUFFIX(                                               \
      const F* pred, const int64_t* pred_strides, const F* gt, const int64_t* gt_strides,                   \
      const F* derivatives, int64_t batch, int64_t channels, int64_t height, int64_t width, int threads,     \
      double grad_scale, F* grad_pred) {                                                                    \
    backward_impl<F>(Image<const F>{pred, pred_strides}, Image<const F>{gt, gt_strides}, derivatives, batch, \
                     channels, height, width, threads, grad_scale, grad_pred);                              \
  }

OLATBENCH_SSIM_DEFINE(float, f32)
OLATBENCH_SSIM_DEFINE(double, f64)

OLATBENCH_DEFINE_ABI_VERSION()
