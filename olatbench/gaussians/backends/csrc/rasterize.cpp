// olatbench CPU rasterizer: tile-based front-to-back Gaussian compositing (3DGS rules) with a hand-written,
// deterministic backward, plus the forward-only light-view "shadow gather" pass.
//
// Plain C ABI on raw pointers (no torch headers): called from Python through ctypes.
// Every function exists for float (_f32) and double (_f64). Arrays are C-contiguous:
//   means2d (N,2) px, conics (N,3) = (a,b,c) of [[a,b],[b,c]], opacities (N,), features (N,C),
//   offsets (T+1,) int64 and ids (M,) int64: tile t holds ids[offsets[t]:offsets[t+1]], front to back.
// Pixel (x, y) is evaluated at its centre (x + 0.5, y + 0.5). Tiles run in parallel (OpenMP); each tile is
// handled by one thread in a fixed pixel order and gradients are first accumulated per (tile, Gaussian)
// pair, then reduced serially in pair order, so results do not depend on the number of threads.
// Build without -ffast-math and with -ffp-contract=off: the backward re-evaluates each alpha and must
// reproduce the forward's skip decisions bit for bit.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace {

constexpr double kAlphaMax = 0.99;
constexpr double kAlphaMin = 1.0 / 255.0;
constexpr double kTMin = 1e-4;

struct Grid {
  int width, height, tile, tiles_x, tiles_y;
  int64_t num_tiles() const { return int64_t(tiles_x) * tiles_y; }
};

// The tile's Gaussians gathered into contiguous arrays (better locality than indexing through ids).
template <typename F>
struct TileData {
  std::vector<F> mx, my, ca, cb, cc, op, feat;
  int64_t n = 0;
  void load(const F* means2d, const F* conics, const F* opac, const F* features, int channels,
            const int64_t* ids, int64_t start, int64_t end) {
    n = end - start;
    mx.resize(n); my.resize(n); ca.resize(n); cb.resize(n); cc.resize(n); op.resize(n);
    feat.resize(size_t(n) * channels);
    for (int64_t k = 0; k < n; ++k) {
      const int64_t g = ids[start + k];
      mx[k] = means2d[2 * g]; my[k] = means2d[2 * g + 1];
      ca[k] = conics[3 * g]; cb[k] = conics[3 * g + 1]; cc[k] = conics[3 * g + 2];
      op[k] = opac[g];
      if (features) for (int c = 0; c < channels; ++c) feat[size_t(k) * channels + c] = features[g * channels + c];
    }
  }
  // power = -1/2 d^T conic d with d = mean - pixel centre (same expression in forward and backward).
  inline F power(int64_t k, F px, F py, F& dx, F& dy) const {
    dx = mx[k] - px; dy = my[k] - py;
    return F(-0.5) * (ca[k] * dx * dx + cc[k] * dy * dy) - cb[k] * dx * dy;
  }
};

template <typename F>
void forward_impl(const F* means2d, const F* conics, const F* opac, const F* features, int channels,
                  const int64_t* offsets, const int64_t* ids, Grid grid, int threads,
                  F* out_colour, F* out_t, int32_t* out_count) {
  const int64_t num_tiles = grid.num_tiles();
#pragma omp parallel num_threads(threads)
  {
    TileData<F> td;
    std::vector<F> acc(channels);
#pragma omp for schedule(dynamic, 1)
    for (int64_t tile = 0; tile < num_tiles; ++tile) {
      const int tx = int(tile % grid.tiles_x), ty = int(tile / grid.tiles_x);
      td.load(means2d, conics, opac, features, channels, ids, offsets[tile], offsets[tile + 1]);
      const int y_end = std::min(grid.height, (ty + 1) * grid.tile);
      const int x_end = std::min(grid.width, (tx + 1) * grid.tile);
      for (int y = ty * grid.tile; y < y_end; ++y) {
        for (int x = tx * grid.tile; x < x_end; ++x) {
          const F px = F(x) + F(0.5), py = F(y) + F(0.5);
          std::fill(acc.begin(), acc.end(), F(0));
          F T = F(1);
          int32_t count = 0;
          for (int64_t k = 0; k < td.n; ++k) {
            F dx, dy;
            const F pw = td.power(k, px, py, dx, dy);
            if (pw > F(0)) continue;
            const F alpha = std::min(F(kAlphaMax), td.op[k] * std::exp(pw));
            if (alpha < F(kAlphaMin)) continue;
            const F t_next = T * (F(1) - alpha);
            if (t_next < F(kTMin)) break;
            const F w = alpha * T;
            const F* f = &td.feat[size_t(k) * channels];
            for (int c = 0; c < channels; ++c) acc[c] += w * f[c];
            T = t_next;
            count = int32_t(k + 1);
          }
          const int64_t pix = int64_t(y) * grid.width + x;
          for (int c = 0; c < channels; ++c) out_colour[pix * channels + c] = acc[c];
          out_t[pix] = T;
          out_count[pix] = count;
        }
      }
    }
  }
}

// Gradient slots per pair: mean x, mean y, conic a, b, c, opacity, then C feature channels.
constexpr int kPairFixed = 6;

template <typename F>
void backward_impl(const F* means2d, const F* conics, const F* opac, const F* features, int channels,
                   const int64_t* offsets, const int64_t* ids, Grid grid, int threads,
                   const F* final_t, const int32_t* counts, const F* grad_colour, const F* grad_t,
                   int64_t num_gaussians, F* grad_means2d, F* grad_conics, F* grad_opac, F* grad_features) {
  const int64_t num_tiles = grid.num_tiles();
  const int stride = kPairFixed + channels;
  const int64_t num_pairs = offsets[num_tiles];
  std::vector<F> pair_grad(size_t(num_pairs) * stride, F(0));
#pragma omp parallel num_threads(threads)
  {
    TileData<F> td;
    std::vector<F> behind(channels), g(channels);
#pragma omp for schedule(dynamic, 1)
    for (int64_t tile = 0; tile < num_tiles; ++tile) {
      const int tx = int(tile % grid.tiles_x), ty = int(tile / grid.tiles_x);
      const int64_t start = offsets[tile];
      td.load(means2d, conics, opac, features, channels, ids, start, offsets[tile + 1]);
      F* tile_grad = pair_grad.data() + size_t(start) * stride;
      const int y_end = std::min(grid.height, (ty + 1) * grid.tile);
      const int x_end = std::min(grid.width, (tx + 1) * grid.tile);
      for (int y = ty * grid.tile; y < y_end; ++y) {
        for (int x = tx * grid.tile; x < x_end; ++x) {
          const int64_t pix = int64_t(y) * grid.width + x;
          const F px = F(x) + F(0.5), py = F(y) + F(0.5);
          const F t_final = final_t[pix];
          const F g_t = grad_t[pix];
          for (int c = 0; c < channels; ++c) g[c] = grad_colour[pix * channels + c];
          std::fill(behind.begin(), behind.end(), F(0));
          F T = t_final;  // transmittance behind the current Gaussian, recovered back to front
          for (int64_t k = int64_t(counts[pix]) - 1; k >= 0; --k) {
            F dx, dy;
            const F pw = td.power(k, px, py, dx, dy);
            if (pw > F(0)) continue;
            const F gauss = std::exp(pw);
            const F raw = td.op[k] * gauss;
            const F alpha = std::min(F(kAlphaMax), raw);
            if (alpha < F(kAlphaMin)) continue;
            const F one_minus = F(1) - alpha;
            T = T / one_minus;  // now the transmittance in front of Gaussian k
            const F w = alpha * T;
            const F* f = &td.feat[size_t(k) * channels];
            F* pg = tile_grad + size_t(k) * stride;
            F d_alpha = -g_t * t_final / one_minus;
            for (int c = 0; c < channels; ++c) {
              pg[kPairFixed + c] += w * g[c];
              d_alpha += g[c] * (T * f[c] - behind[c] / one_minus);
              behind[c] += w * f[c];
            }
            if (raw > F(kAlphaMax)) continue;  // clamped: alpha does not depend on opacity or position
            pg[5] += gauss * d_alpha;
            const F d_power = raw * d_alpha;
            pg[0] += -d_power * (td.ca[k] * dx + td.cb[k] * dy);
            pg[1] += -d_power * (td.cb[k] * dx + td.cc[k] * dy);
            pg[2] += F(-0.5) * dx * dx * d_power;
            pg[3] += -dx * dy * d_power;
            pg[4] += F(-0.5) * dy * dy * d_power;
          }
        }
      }
    }
  }
  // Deterministic reduction in pair order.
  for (int64_t i = 0; i < num_gaussians * 2; ++i) grad_means2d[i] = F(0);
  for (int64_t i = 0; i < num_gaussians * 3; ++i) grad_conics[i] = F(0);
  for (int64_t i = 0; i < num_gaussians; ++i) grad_opac[i] = F(0);
  for (int64_t i = 0; i < num_gaussians * channels; ++i) grad_features[i] = F(0);
  for (int64_t m = 0; m < num_pairs; ++m) {
    const int64_t gid = ids[m];
    const F* pg = pair_grad.data() + size_t(m) * stride;
    grad_means2d[2 * gid] += pg[0];
    grad_means2d[2 * gid + 1] += pg[1];
    grad_conics[3 * gid] += pg[2];
    grad_conics[3 * gid + 1] += pg[3];
    grad_conics[3 * gid + 2] += pg[4];
    grad_opac[gid] += pg[5];
    for (int c = 0; c < channels; ++c) grad_features[gid * channels + c] += pg[kPairFixed + c];
  }
}

// Light-view pass. Per Gaussian g: vis_sum[g] = sum of the transmittance in front of g over the pixels whose
// centre lies within `radius_px` of g's 2D mean (count[g] of them), and weight[g] = sum over all pixels of
// g's blending weight T*alpha. Compositing rules are the forward's; once a pixel terminates (T would drop
// below 1e-4) the Gaussians behind it see transmittance 0 there.
template <typename F>
void shadow_gather_impl(const F* means2d, const F* conics, const F* opac, const int64_t* offsets,
                        const int64_t* ids, Grid grid, F radius_px, int threads, int64_t num_gaussians,
                        F* vis_sum, int32_t* count, F* weight) {
  const int64_t num_tiles = grid.num_tiles();
  const int64_t num_pairs = offsets[num_tiles];
  std::vector<F> pair_vis(num_pairs, F(0)), pair_weight(num_pairs, F(0));
  std::vector<int32_t> pair_count(num_pairs, 0);
  const F r2 = radius_px * radius_px;
#pragma omp parallel num_threads(threads)
  {
    TileData<F> td;
#pragma omp for schedule(dynamic, 1)
    for (int64_t tile = 0; tile < num_tiles; ++tile) {
      const int tx = int(tile % grid.tiles_x), ty = int(tile / grid.tiles_x);
      const int64_t start = offsets[tile];
      td.load(means2d, conics, opac, nullptr, 0, ids, start, offsets[tile + 1]);
      const int y_end = std::min(grid.height, (ty + 1) * grid.tile);
      const int x_end = std::min(grid.width, (tx + 1) * grid.tile);
      for (int y = ty * grid.tile; y < y_end; ++y) {
        for (int x = tx * grid.tile; x < x_end; ++x) {
          const F px = F(x) + F(0.5), py = F(y) + F(0.5);
          F T = F(1);
          bool done = false;
          for (int64_t k = 0; k < td.n; ++k) {
            F dx, dy;
            const F pw = td.power(k, px, py, dx, dy);
            if (dx * dx + dy * dy <= r2) {
              pair_vis[start + k] += done ? F(0) : T;
              pair_count[start + k] += 1;
            }
            if (done || pw > F(0)) continue;
            const F alpha = std::min(F(kAlphaMax), td.op[k] * std::exp(pw));
            if (alpha < F(kAlphaMin)) continue;
            const F t_next = T * (F(1) - alpha);
            if (t_next < F(kTMin)) { done = true; continue; }
            pair_weight[start + k] += alpha * T;
            T = t_next;
          }
        }
      }
    }
  }
  for (int64_t i = 0; i < num_gaussians; ++i) { vis_sum[i] = F(0); count[i] = 0; weight[i] = F(0); }
  for (int64_t m = 0; m < num_pairs; ++m) {
    const int64_t gid = ids[m];
    vis_sum[gid] += pair_vis[m];
    count[gid] += pair_count[m];
    weight[gid] += pair_weight[m];
  }
}

}  // namespace

#define OLATBENCH_EXPORT extern "C" __attribute__((visibility("default")))

#define OLATBENCH_DEFINE(F, SUFFIX)                                                                          \
  OLATBENCH_EXPORT void olatbench_forward_##SUFFIX(                                                         \
      const F* means2d, const F* conics, const F* opac, const F* features, int channels,                    \
      const int64_t* offsets, const int64_t* ids, int width, int height, int tile, int tiles_x, int tiles_y, \
      int threads, F* out_colour, F* out_t, int32_t* out_count) {                                           \
    forward_impl<F>(means2d, conics, opac, features, channels, offsets, ids,                                \
                    Grid{width, height, tile, tiles_x, tiles_y}, threads, out_colour, out_t, out_count);    \
  }                                                                                                         \
  OLATBENCH_EXPORT void olatbench_backward_##SUFFIX(                                                        \
      const F* means2d, const F* conics, const F* opac, const F* features, int channels,                    \
      const int64_t* offsets, const int64_t* ids, int width, int height, int tile, int tiles_x, int tiles_y, \
      int threads, const F* final_t, const int32_t* counts, const F* grad_colour, const F* grad_t,          \
      int64_t num_gaussians, F* grad_means2d, F* grad_conics, F* grad_opac, F* grad_features) {             \
    backward_impl<F>(means2d, conics, opac, features, channels, offsets, ids,                               \
                     Grid{width, height, tile, tiles_x, tiles_y}, threads, final_t, counts, grad_colour,    \
                     grad_t, num_gaussians, grad_means2d, grad_conics, grad_opac, grad_features);           \
  }                                                                                                         \
  OLATBENCH_EXPORT void olatbench_shadow_gather_##SUFFIX(                                                   \
      const F* means2d, const F* conics, const F* opac, const int64_t* offsets, const int64_t* ids,         \
      int width, int height, int tile, int tiles_x, int tiles_y, F radius_px, int threads,                  \
      int64_t num_gaussians, F* vis_sum, int32_t* count, F* weight) {                                       \
    shadow_gather_impl<F>(means2d, conics, opac, offsets, ids, Grid{width, height, tile, tiles_x, tiles_y}, \
                          radius_px, threads, num_gaussians, vis_sum, count, weight);                       \
  }

OLATBENCH_DEFINE(float, f32)
OLATBENCH_DEFINE(double, f64)

OLATBENCH_EXPORT int olatbench_abi_version() { return 1; }
