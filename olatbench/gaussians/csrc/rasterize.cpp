// olatbench CPU rasterizer: tile-based front-to-back Gaussian compositing (3DGS rules) with a hand-written,
// deterministic backward, plus the forward-only light-view "shadow gather" pass and the per-Gaussian largest
// blending weight (contribution culling).
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
#include <cstring>
#include <limits>
#include <vector>

#include "export.h"
#include "float_mode.h"
#include "rotation.h"
#include "simd.h"

namespace {

constexpr double kAlphaMax = 0.99;  // 3DGS's clamp (the light pass; the camera pass takes its Rules)
constexpr double kAlphaMin = 1.0 / 255.0;
constexpr double kTMin = 1e-4;
// Extra half-width (px) of the per-Gaussian pixel boxes, absorbing rounding in their computation.
constexpr double kBoxSlack = 1e-2;

// The camera pass's compositing rules: alpha = min(alpha_max, o exp(power)); a pixel stops before the Gaussian
// whose next transmittance is below kTMin (3DGS: alpha_max 0.99) or at or below it (gsplat: alpha_max 0.999).
template <typename F>
struct Rules {
  F alpha_max;
  bool stop_at_t_min;
  static Rules of(double alpha_max, int stop_at_t_min) { return Rules{F(alpha_max), stop_at_t_min != 0}; }
  static Rules three_dgs() { return Rules{F(kAlphaMax), false}; }
  bool stops(F t_next) const { return stop_at_t_min ? t_next <= F(kTMin) : t_next < F(kTMin); }
};

struct Grid {
  int width, height, tile, tiles_x, tiles_y;
  int64_t num_tiles() const { return int64_t(tiles_x) * tiles_y; }
};

// Pixel rectangle [x0, x1) x [y0, y1) inside one tile, with pixel indices local to the tile.
struct Box {
  int x0, x1, y0, y1;
};

// One tile: its pixel extent and its Gaussians gathered into contiguous arrays (better locality than
// indexing through ids), with for each Gaussian the half-widths of the box outside which it surely
// contributes nothing (alpha < 1/255).
template <typename F>
struct TileData {
  std::vector<F> mx, my, ca, cb, cc, op, cutoff, feat;
  std::vector<double> hx, hy;
  int64_t n = 0;
  int origin_x = 0, origin_y = 0, size_x = 0, size_y = 0;

  void load(const F* means2d, const F* conics, const F* opac, const F* features, int channels,
            const int64_t* ids, int64_t start, int64_t end, const Grid& grid, int64_t tile) {
    origin_x = int(tile % grid.tiles_x) * grid.tile;
    origin_y = int(tile / grid.tiles_x) * grid.tile;
    size_x = std::min(grid.width, origin_x + grid.tile) - origin_x;
    size_y = std::min(grid.height, origin_y + grid.tile) - origin_y;
    n = end - start;
    for (auto* v : {&mx, &my, &ca, &cb, &cc, &op, &cutoff}) v->resize(n);
    hx.resize(n); hy.resize(n);
    feat.resize(size_t(n) * channels);
    for (int64_t k = 0; k < n; ++k) {
      const int64_t g = ids[start + k];
      mx[k] = means2d[2 * g]; my[k] = means2d[2 * g + 1];
      ca[k] = conics[3 * g]; cb[k] = conics[3 * g + 1]; cc[k] = conics[3 * g + 2];
      op[k] = opac[g];
      if (features) for (int c = 0; c < channels; ++c) feat[size_t(k) * channels + c] = features[g * channels + c];
      // alpha <= o, so o < 1/255 never contributes. Otherwise, below `cutoff` o * exp(power) < 1/255 for sure
      // (the margin absorbs rounding); near the cut-off the exact test on alpha still decides, so results do
      // not depend on this shortcut. The set {power >= cutoff} is an ellipse with the box below.
      const double o = double(op[k]);
      const double det = double(ca[k]) * double(cc[k]) - double(cb[k]) * double(cb[k]);
      if (!(o >= kAlphaMin)) {
        cutoff[k] = F(0); hx[k] = hy[k] = -1.0;  // never contributes
      } else {
        const double cut = -std::log(255.0 * o) - 1e-3;
        cutoff[k] = F(cut);
        if (det > 0.0 && ca[k] > F(0) && cc[k] > F(0)) {
          hx[k] = std::sqrt(-2.0 * cut * double(cc[k]) / det) + kBoxSlack;
          hy[k] = std::sqrt(-2.0 * cut * double(ca[k]) / det) + kBoxSlack;
        } else {
          hx[k] = hy[k] = 1e30;  // not positive definite: evaluate the whole tile
        }
      }
    }
  }
  // Tile pixels whose centres may lie within Gaussian k's box widened to at least `min_half` px; false if none.
  // With `exact`, the half-width is `min_half` itself (a square around the mean, whatever Gaussian k's extent).
  bool box(int64_t k, double min_half, Box& b, bool exact = false) const {
    const double wx = exact ? min_half : std::max(hx[k], min_half), wy = exact ? min_half : std::max(hy[k], min_half);
    if (wx < 0.0) return false;
    const double cx = double(mx[k]) - origin_x - 0.5, cy = double(my[k]) - origin_y - 0.5;
    b.x0 = int(std::max(0.0, std::ceil(std::max(cx - wx, -1.0))));
    b.x1 = int(std::min(double(size_x), std::floor(std::min(cx + wx, double(size_x))) + 1.0));
    b.y0 = int(std::max(0.0, std::ceil(std::max(cy - wy, -1.0))));
    b.y1 = int(std::min(double(size_y), std::floor(std::min(cy + wy, double(size_y))) + 1.0));
    return b.x0 < b.x1 && b.y0 < b.y1;
  }
  // power = -1/2 d^T conic d with d = mean - pixel centre (same expression in forward and backward).
  inline F power(int64_t k, int lx, int ly, F& dx, F& dy) const {
    dx = mx[k] - (F(origin_x + lx) + F(0.5));
    dy = my[k] - (F(origin_y + ly) + F(0.5));
    return F(-0.5) * (ca[k] * dx * dx + cc[k] * dy * dy) - cb[k] * dx * dy;
  }
  // True when Gaussian k surely contributes nothing at this power (power > 0 or alpha < 1/255).
  inline bool negligible(int64_t k, F pw) const { return pw > F(0) || pw < cutoff[k]; }
};

// Forward. Per tile, Gaussians front to back (outer) and the pixels of their box (inner): each pixel still
// sees its Gaussians in list order, with per-pixel state kept in tile-sized arrays. pair_max (or null): per
// (tile, Gaussian) pair, the largest blending weight T*alpha it composited with (0 where it composited nothing).
template <typename F>
void forward_impl(const F* means2d, const F* conics, const F* opac, const F* features, int channels,
                  const int64_t* offsets, const int64_t* ids, Grid grid, int threads, Rules<F> rules,
                  F* out_colour, F* out_t, int32_t* out_count, F* pair_max = nullptr) {
  const int64_t num_tiles = grid.num_tiles();
  const int area = grid.tile * grid.tile;
  const FloatMode mode = FloatMode::of_this_thread();
#pragma omp parallel num_threads(threads)
  {
    const FloatModeScope scope(mode);
    TileData<F> td;
    std::vector<F> acc(size_t(area) * channels), T(area);
    std::vector<int32_t> count(area);
    std::vector<char> done(area);
#pragma omp for schedule(dynamic, 1)
    for (int64_t tile = 0; tile < num_tiles; ++tile) {
      td.load(means2d, conics, opac, features, channels, ids, offsets[tile], offsets[tile + 1], grid, tile);
      const int sx = td.size_x;
      std::fill(acc.begin(), acc.end(), F(0));
      std::fill(T.begin(), T.end(), F(1));
      std::fill(count.begin(), count.end(), 0);
      std::fill(done.begin(), done.end(), 0);
      int active = sx * td.size_y;
      Box b;
      F* tile_max = pair_max ? pair_max + offsets[tile] : nullptr;
      if (tile_max) std::fill(tile_max, tile_max + td.n, F(0));
      for (int64_t k = 0; k < td.n && active > 0; ++k) {
        if (!td.box(k, -1.0, b)) continue;
        const F* f = &td.feat[size_t(k) * channels];
        for (int ly = b.y0; ly < b.y1; ++ly) {
          for (int lx = b.x0; lx < b.x1; ++lx) {
            const int p = ly * sx + lx;
            if (done[p]) continue;
            F dx, dy;
            const F pw = td.power(k, lx, ly, dx, dy);
            if (td.negligible(k, pw)) continue;
            const F alpha = std::min(rules.alpha_max, td.op[k] * std::exp(pw));
            if (alpha < F(kAlphaMin)) continue;
            const F t_next = T[p] * (F(1) - alpha);
            if (rules.stops(t_next)) { done[p] = 1; --active; continue; }
            const F w = alpha * T[p];
            F* a = &acc[size_t(p) * channels];
            for (int c = 0; c < channels; ++c) a[c] += w * f[c];
            if (tile_max) tile_max[k] = std::max(tile_max[k], w);
            T[p] = t_next;
            count[p] = int32_t(k + 1);
          }
        }
      }
      for (int ly = 0; ly < td.size_y; ++ly) {
        for (int lx = 0; lx < sx; ++lx) {
          const int p = ly * sx + lx;
          const int64_t pix = int64_t(td.origin_y + ly) * grid.width + td.origin_x + lx;
          for (int c = 0; c < channels; ++c) out_colour[pix * channels + c] = acc[size_t(p) * channels + c];
          out_t[pix] = T[p];
          out_count[pix] = count[p];
        }
      }
    }
  }
}

// Contribution pass: each Gaussian's largest blending weight T*alpha over the image (max_weight (N,), 0 for those
// that composite nothing), from the forward itself run without feature channels, so the weights and every skip
// and stop decision are the camera pass's. A maximum does not depend on the order of the reduction.
template <typename F>
void max_weight_impl(const F* means2d, const F* conics, const F* opac, const int64_t* offsets, const int64_t* ids,
                     Grid grid, int threads, int64_t num_gaussians, F* max_weight) {
  const int64_t num_pairs = offsets[grid.num_tiles()];
  const size_t pixels = size_t(grid.width) * size_t(grid.height);
  std::vector<F> pair_max(num_pairs), final_t(pixels);
  std::vector<int32_t> counts(pixels);
  forward_impl<F>(means2d, conics, opac, nullptr, 0, offsets, ids, grid, threads, Rules<F>::three_dgs(), nullptr,
                  final_t.data(), counts.data(), pair_max.data());
  std::fill(max_weight, max_weight + num_gaussians, F(0));
  for (int64_t m = 0; m < num_pairs; ++m) max_weight[ids[m]] = std::max(max_weight[ids[m]], pair_max[m]);
}

// Gradient slots per pair: mean x, mean y, conic a, b, c, opacity, then C feature channels.
constexpr int kPairFixed = 6;

// Backward (3DGS): per pixel, Gaussians back to front from its last composited one, recovering the
// transmittance in front of each from the final one (T_k = T_{k+1} / (1 - alpha_k)).
template <typename F>
void backward_impl(const F* means2d, const F* conics, const F* opac, const F* features, int channels,
                   const int64_t* offsets, const int64_t* ids, Grid grid, int threads, Rules<F> rules,
                   const F* final_t, const int32_t* counts, const F* grad_colour, const F* grad_t,
                   int64_t num_gaussians, F* grad_means2d, F* grad_conics, F* grad_opac, F* grad_features) {
  const int64_t num_tiles = grid.num_tiles();
  const int area = grid.tile * grid.tile;
  const int stride = kPairFixed + channels;
  const int64_t num_pairs = offsets[num_tiles];
  std::vector<F> pair_grad(size_t(num_pairs) * stride, F(0));
  const FloatMode mode = FloatMode::of_this_thread();
#pragma omp parallel num_threads(threads)
  {
    const FloatModeScope scope(mode);
    TileData<F> td;
    std::vector<F> behind(size_t(area) * channels), g(size_t(area) * channels), T(area), tf(area), gt(area);
    std::vector<int32_t> count(area);
#pragma omp for schedule(dynamic, 1)
    for (int64_t tile = 0; tile < num_tiles; ++tile) {
      const int64_t start = offsets[tile];
      td.load(means2d, conics, opac, features, channels, ids, start, offsets[tile + 1], grid, tile);
      const int sx = td.size_x;
      for (int ly = 0; ly < td.size_y; ++ly) {
        for (int lx = 0; lx < sx; ++lx) {
          const int p = ly * sx + lx;
          const int64_t pix = int64_t(td.origin_y + ly) * grid.width + td.origin_x + lx;
          T[p] = tf[p] = final_t[pix];
          gt[p] = grad_t[pix];
          count[p] = counts[pix];
          for (int c = 0; c < channels; ++c) {
            g[size_t(p) * channels + c] = grad_colour[pix * channels + c];
            behind[size_t(p) * channels + c] = F(0);
          }
        }
      }
      F* tile_grad = pair_grad.data() + size_t(start) * stride;
      Box b;
      for (int64_t k = td.n - 1; k >= 0; --k) {
        if (!td.box(k, -1.0, b)) continue;
        const F* f = &td.feat[size_t(k) * channels];
        F* pg = tile_grad + size_t(k) * stride;
        for (int ly = b.y0; ly < b.y1; ++ly) {
          for (int lx = b.x0; lx < b.x1; ++lx) {
            const int p = ly * sx + lx;
            if (k >= count[p]) continue;
            F dx, dy;
            const F pw = td.power(k, lx, ly, dx, dy);
            if (td.negligible(k, pw)) continue;
            const F gauss = std::exp(pw);
            const F raw = td.op[k] * gauss;
            const F alpha = std::min(rules.alpha_max, raw);
            if (alpha < F(kAlphaMin)) continue;
            const F one_minus = F(1) - alpha;
            T[p] = T[p] / one_minus;  // now the transmittance in front of Gaussian k
            const F w = alpha * T[p];
            const F* gp = &g[size_t(p) * channels];
            F* bp = &behind[size_t(p) * channels];
            // dL/dalpha = sum_c g_c (T f_c - behind_c / (1 - alpha)) - gT T_final / (1 - alpha)
            F g_f = F(0), g_behind = F(0);
            for (int c = 0; c < channels; ++c) {
              pg[kPairFixed + c] += w * gp[c];
              g_f += gp[c] * f[c];
              g_behind += gp[c] * bp[c];
              bp[c] += w * f[c];
            }
            const F d_alpha = T[p] * g_f - (g_behind + gt[p] * tf[p]) / one_minus;
            if (raw > rules.alpha_max) continue;  // clamped: alpha does not depend on opacity or position
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
  std::fill(grad_means2d, grad_means2d + num_gaussians * 2, F(0));
  std::fill(grad_conics, grad_conics + num_gaussians * 3, F(0));
  std::fill(grad_opac, grad_opac + num_gaussians, F(0));
  std::fill(grad_features, grad_features + num_gaussians * channels, F(0));
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

// One box row of the light pass: composite Gaussian (mx, my, conic ca cb cc, opacity o) into the row's
// transmittance t_row and stop flags d_row (0 or 1) over local x in [x0, x1), W / sizeof(F) pixels at a time
// (the rows are padded so whole vectors can be read and written back; lanes past x1 keep their values). Each
// pixel's weight alpha T (0 where nothing was composited) is added to partial[(lx - x0) % kWeightLanes]: the
// same kWeightLanes running sums, in the same order, whatever the vector width (which divides kWeightLanes), so
// the total is width-independent without a serial chain of additions. rec (the lagged pass's record, or null)
// gets the factor the pixel's T was multiplied by: 1 - alpha, 0 where the pixel stopped, 1 where it was left
// alone.
constexpr int kWeightLanes = 8;

template <typename F, int W>
OLATBENCH_SIMD void composite_row(F* t_row, F* d_row, int x0, int x1, int origin_x, F mx, F dy, F ca, F cb, F cc,
                                  F o, F* partial, F* rec) {
  using S = Simd<F, W>;
  static_assert(kWeightLanes % S::kLanes == 0, "the vector width must divide kWeightLanes");
  using V = typename S::V;
  using I = typename S::I;
  V lane;
  for (int i = 0; i < S::kLanes; ++i) lane[i] = F(i);
  const V zero = splat<F, W>(F(0)), one = splat<F, W>(F(1));
  for (int lx = x0; lx < x1; lx += S::kLanes) {
    V t, d;
    std::memcpy(&t, t_row + lx, sizeof(V));
    std::memcpy(&d, d_row + lx, sizeof(V));
    const I open = ((lane + F(lx)) < F(x1)) & (d == zero);  // inside the box and not stopped yet
    const V px = splat<F, W>(F(origin_x + lx)) + lane;  // exact integers, as F(origin_x + lx) per pixel
    const V dx = mx - (px + F(0.5));
    const V pw = F(-0.5) * (ca * dx * dx + cc * dy * dy) - cb * dx * dy;  // as TileData::power
    const I positive = pw > zero;
    const V g = exp_nonpositive<F, W>(select<F, W>(positive, zero, pw));
    const V scaled = o * g;
    const V alpha = select<F, W>(scaled > splat<F, W>(F(kAlphaMax)), splat<F, W>(F(kAlphaMax)), scaled);
    const V keep = one - alpha;
    const V t_next = t * keep;
    const I live = open & ~positive & (alpha >= splat<F, W>(F(kAlphaMin)));
    const I stop = live & (t_next < splat<F, W>(F(kTMin)));
    const I update = live & ~stop;
    const V w = select<F, W>(update, alpha * t, zero);
    t = select<F, W>(update, t_next, t);
    d = select<F, W>(stop, one, d);
    std::memcpy(t_row + lx, &t, sizeof(V));
    std::memcpy(d_row + lx, &d, sizeof(V));
    F* sums = partial + (lx - x0) % kWeightLanes;
    V running;
    std::memcpy(&running, sums, sizeof(V));
    running += w;
    std::memcpy(sums, &running, sizeof(V));
    if (rec) store<F, W>(rec + (lx - x0), x1 - lx, select<F, W>(update, keep, select<F, W>(stop, zero, one)));
  }
}

template <typename F>
void composite_row_sse(F* t_row, F* d_row, int x0, int x1, int origin_x, F mx, F dy, F ca, F cb, F cc, F o,
                       F* partial, F* rec) {
  composite_row<F, 16>(t_row, d_row, x0, x1, origin_x, mx, dy, ca, cb, cc, o, partial, rec);
}
#ifdef OLATBENCH_SIMD_AVX2
template <typename F>
__attribute__((target("avx2"))) void composite_row_avx2(F* t_row, F* d_row, int x0, int x1, int origin_x, F mx,
                                                        F dy, F ca, F cb, F cc, F o, F* partial, F* rec) {
  composite_row<F, 32>(t_row, d_row, x0, x1, origin_x, mx, dy, ca, cb, cc, o, partial, rec);
}
#endif
// Vector lanes of padding after the per-pixel rows (the widest vector: 32 bytes).
constexpr int kRowPad = 32;

// Light-view pass over all tiles, writing per (tile, Gaussian) pair sums. kLagged, kDensity: see
// shadow_gather_impl. Per Gaussian k of a tile (front to back): first its sampling disc reads the transmittance
// in front of it, then it is composited over its box. The compositing loop is branch-free over each box row
// (pixels are independent), so it vectorises; per-pixel state is kept as F arrays (T, and done = 0 or 1).
// Disc sums go to pair_vis (F; uniform) or to pair_vis64 and pair_norm64 (double; kDensity).
template <typename F, bool kLagged, bool kDensity>
void shadow_gather_tiles(const F* means2d, const F* conics, const F* opac, const F* keys, double depth_offset,
                         const int64_t* offsets, const int64_t* ids, Grid grid, F radius_px, int threads,
                         F* pair_vis, double* pair_vis64, double* pair_norm64, int32_t* pair_count,
                         F* pair_weight) {
  const int64_t num_tiles = grid.num_tiles();
  const int area = grid.tile * grid.tile;
  const F r2 = radius_px * radius_px;
  auto composite = composite_row_sse<F>;
#ifdef OLATBENCH_SIMD_AVX2
  if (have_avx2()) composite = composite_row_avx2<F>;
#endif
  const FloatMode mode = FloatMode::of_this_thread();
#pragma omp parallel num_threads(threads)
  {
    const FloatModeScope scope(mode);
    TileData<F> td;
    // Rows padded by kRowPad so composite_row may read and write back whole vectors past a row's end.
    std::vector<F> T(area + kRowPad), done(area + kRowPad);
    std::vector<F> T_lag(kLagged ? area : 0), done_lag(kLagged ? area : 0);
    // kLagged: what the main pass did to each pixel of each Gaussian's box, row-major from record_start[k]:
    // the factor 1 - alpha it multiplied T by, 0 where it stopped the pixel, 1 where it left it alone.
    std::vector<float> key32, threshold32;
    std::vector<Box> boxes;
    std::vector<int64_t> record_start;
    std::vector<F> record;
#pragma omp for schedule(dynamic, 1)
    for (int64_t tile = 0; tile < num_tiles; ++tile) {
      const int64_t start = offsets[tile];
      td.load(means2d, conics, opac, nullptr, 0, ids, start, offsets[tile + 1], grid, tile);
      const int sx = td.size_x;
      std::fill(T.begin(), T.end(), F(1));
      std::fill(done.begin(), done.end(), F(0));
      int64_t lag = 0;  // Gaussians [0, lag) of the tile are composited into T_lag
      if constexpr (kLagged) {
        std::fill(T_lag.begin(), T_lag.end(), F(1));
        std::fill(done_lag.begin(), done_lag.end(), F(0));
        key32.resize(td.n);
        threshold32.resize(td.n);
        boxes.assign(td.n, Box{0, 0, 0, 0});
        record_start.resize(td.n + 1);
        record.clear();
        for (int64_t k = 0; k < td.n; ++k) {
          const int64_t g = ids[start + k];
          key32[k] = float(keys[g]);
          threshold32[k] = float(double(keys[g]) - depth_offset);
        }
      }
      const F* T_front = kLagged ? T_lag.data() : T.data();
      const F* done_front = kLagged ? done_lag.data() : done.data();
      for (int64_t k = 0; k < td.n; ++k) {
        if constexpr (kLagged) {
          record_start[k] = int64_t(record.size());
          const float threshold = threshold32[k];
          if (lag > 0 && !(key32[lag - 1] < threshold)) {  // the prefix shrank: replay from the tile start
            std::fill(T_lag.begin(), T_lag.end(), F(1));
            std::fill(done_lag.begin(), done_lag.end(), F(0));
            lag = 0;
          }
          // Replaying the recorded factors reproduces T bit for bit (same products in the same order; x * 1 = x).
          for (; lag < k && key32[lag] < threshold; ++lag) {
            const Box& lb = boxes[lag];
            const F* f = record.data() + record_start[lag];
            for (int ly = lb.y0; ly < lb.y1; ++ly) {
              F* t_row = T_lag.data() + ly * sx;
              F* d_row = done_lag.data() + ly * sx;
              for (int lx = lb.x0; lx < lb.x1; ++lx, ++f) {
                const bool stop = *f == F(0);
                d_row[lx] = stop ? F(1) : d_row[lx];
                t_row[lx] = stop ? t_row[lx] : t_row[lx] * *f;
              }
            }
          }
        }
        if constexpr (kDensity) {
          pair_vis64[start + k] = 0.0;
          pair_norm64[start + k] = 0.0;
        } else {
          pair_vis[start + k] = F(0);
        }
        pair_count[start + k] = 0;
        pair_weight[start + k] = F(0);
        Box b;
        // The sampling disc: pixel centres within radius_px of the mean, reading T before k is composited.
        const bool disc = td.box(k, double(radius_px) + kBoxSlack, b, true);
        if (!disc) {  // no pixel centre near the mean: nothing to sample
        } else if constexpr (kDensity) {
          // Weighted by k's own density rho = exp(power) (no opacity), evaluated and summed in double like the
          // torch reference; only inside the disc (a branch: exp is the costly part).
          double vis = 0.0, norm = 0.0;
          int32_t cnt = 0;
          for (int ly = b.y0; ly < b.y1; ++ly) {
            const F* t_row = T_front + ly * sx;
            const F* d_row = done_front + ly * sx;
            for (int lx = b.x0; lx < b.x1; ++lx) {
              F dx, dy;
              const F pw = td.power(k, lx, ly, dx, dy);
              if (!(dx * dx + dy * dy <= r2)) continue;
              const double rho = std::exp(double(pw));
              norm += rho;
              vis += d_row[lx] == F(0) ? rho * double(t_row[lx]) : 0.0;  // + 0 past a stop
              ++cnt;
            }
          }
          pair_vis64[start + k] = vis;
          pair_norm64[start + k] = norm;
          pair_count[start + k] = cnt;
        } else {
          F vis = F(0);
          int32_t cnt = 0;
          for (int ly = b.y0; ly < b.y1; ++ly) {  // branch-free: which pixels fall inside varies unpredictably
            const F dy = td.my[k] - (F(td.origin_y + ly) + F(0.5)), dy2 = dy * dy;
            const F* t_row = T_front + ly * sx;
            const F* d_row = done_front + ly * sx;
            for (int lx = b.x0; lx < b.x1; ++lx) {
              const F dx = td.mx[k] - (F(td.origin_x + lx) + F(0.5));  // as TileData::power
              const bool inside = dx * dx + dy2 <= r2;
              vis += t_row[lx] * F(inside & (d_row[lx] == F(0)));  // + 0 outside the disc or past a stop
              cnt += int32_t(inside);
            }
          }
          pair_vis[start + k] = vis;
          pair_count[start + k] = cnt;
        }
        if (td.hx[k] < 0.0 || !td.box(k, 0.0, b)) continue;  // opacity below 1/255: never composited
        if constexpr (kLagged) {
          boxes[k] = b;
          record.resize(record.size() + size_t(b.x1 - b.x0) * size_t(b.y1 - b.y0));
        }
        F* rec = kLagged ? record.data() + record_start[k] : nullptr;
        const F mx = td.mx[k], my = td.my[k], ca = td.ca[k], cb = td.cb[k], cc = td.cc[k], o = td.op[k];
        const int row_width = b.x1 - b.x0;
        F partial[kWeightLanes] = {};
        for (int ly = b.y0; ly < b.y1; ++ly) {
          const F dy = my - (F(td.origin_y + ly) + F(0.5));
          F* row_rec = kLagged ? rec + (ly - b.y0) * row_width : nullptr;
          composite(T.data() + ly * sx, done.data() + ly * sx, b.x0, b.x1, td.origin_x, mx, dy, ca, cb, cc, o,
                    partial, row_rec);
        }
        pair_weight[start + k] = ((partial[0] + partial[1]) + (partial[2] + partial[3])) +
                                 ((partial[4] + partial[5]) + (partial[6] + partial[7]));
      }
      if constexpr (kLagged) record_start[td.n] = int64_t(record.size());
    }
  }
}

// Light-view pass. Per Gaussian g: vis_sum[g] = sum of the transmittance in front of g over the pixels whose
// centre lies within `radius_px` of g's 2D mean (count[g] of them), and weight[g] = sum over all pixels of
// g's blending weight T*alpha. Compositing rules are the forward's; once a pixel terminates (T would drop
// below 1e-4) the Gaussians behind it see transmittance 0 there.
// depth_offset > 0 (needs keys, the per-Gaussian sort keys): "in front of g" keeps only the Gaussians L with
// float(key[L]) < float(double(key[g]) - depth_offset), compared in float32 like the tile sort
// (tiles.float_order_key), so they form a prefix of g's tile list. A second per-pixel state (T_lag, done_lag),
// advanced by a lagging pointer, replays the main pass's recorded per-pixel factors up to that prefix; vis_sum
// reads it instead of T (weight still uses T). The threshold is non-decreasing along the list except among
// Gaussians with equal float32 keys (the list is sorted by float32 key, the threshold computed from the full
// key); when the prefix shrinks, T_lag is replayed from the tile start (exact, and rare).
// depth_offset == 0 runs the plain loop without any of this (keys may be null).
// density == 0: every disc pixel counts 1 (norm[g] = count[g]); the sums are in F. density != 0: each disc pixel
// is weighted by g's density rho = exp(-1/2 d^T conic d) (no opacity): vis_sum[g] = sum rho T, norm[g] = sum rho,
// summed in double and rounded to F at the end (the official kernel's out_trans and non_trans).
template <typename F, bool kLagged>
void shadow_gather_dispatch(bool density, const F* means2d, const F* conics, const F* opac, const F* keys,
                            double depth_offset, const int64_t* offsets, const int64_t* ids, Grid grid, F radius_px,
                            int threads, F* pair_vis, double* pair_vis64, double* pair_norm64, int32_t* pair_count,
                            F* pair_weight) {
  if (density) {
    shadow_gather_tiles<F, kLagged, true>(means2d, conics, opac, keys, depth_offset, offsets, ids, grid, radius_px,
                                          threads, pair_vis, pair_vis64, pair_norm64, pair_count, pair_weight);
  } else {
    shadow_gather_tiles<F, kLagged, false>(means2d, conics, opac, keys, depth_offset, offsets, ids, grid,
                                           radius_px, threads, pair_vis, pair_vis64, pair_norm64, pair_count,
                                           pair_weight);
  }
}

template <typename F>
void shadow_gather_impl(const F* means2d, const F* conics, const F* opac, const F* keys, double depth_offset,
                        int density, const int64_t* offsets, const int64_t* ids, Grid grid, F radius_px,
                        int threads, int64_t num_gaussians, F* vis_sum, int32_t* count, F* norm, F* weight) {
  const int64_t num_pairs = offsets[grid.num_tiles()];
  std::vector<F> pair_vis(density ? 0 : num_pairs, F(0)), pair_weight(num_pairs, F(0));
  std::vector<double> pair_vis64(density ? num_pairs : 0, 0.0), pair_norm64(density ? num_pairs : 0, 0.0);
  std::vector<int32_t> pair_count(num_pairs, 0);
  if (depth_offset > 0.0) {
    shadow_gather_dispatch<F, true>(density != 0, means2d, conics, opac, keys, depth_offset, offsets, ids, grid,
                                    radius_px, threads, pair_vis.data(), pair_vis64.data(), pair_norm64.data(),
                                    pair_count.data(), pair_weight.data());
  } else {
    shadow_gather_dispatch<F, false>(density != 0, means2d, conics, opac, keys, depth_offset, offsets, ids, grid,
                                     radius_px, threads, pair_vis.data(), pair_vis64.data(), pair_norm64.data(),
                                     pair_count.data(), pair_weight.data());
  }
  std::fill(vis_sum, vis_sum + num_gaussians, F(0));
  std::fill(count, count + num_gaussians, 0);
  std::fill(weight, weight + num_gaussians, F(0));
  for (int64_t m = 0; m < num_pairs; ++m) {
    const int64_t gid = ids[m];
    if (!density) vis_sum[gid] += pair_vis[m];
    count[gid] += pair_count[m];
    weight[gid] += pair_weight[m];
  }
  if (density) {
    std::vector<double> vis64(num_gaussians, 0.0), norm64(num_gaussians, 0.0);
    for (int64_t m = 0; m < num_pairs; ++m) {
      vis64[ids[m]] += pair_vis64[m];
      norm64[ids[m]] += pair_norm64[m];
    }
    for (int64_t g = 0; g < num_gaussians; ++g) {
      vis_sum[g] = F(vis64[g]);
      norm[g] = F(norm64[g]);
    }
  } else {
    for (int64_t g = 0; g < num_gaussians; ++g) norm[g] = F(count[g]);
  }
}

// Tile binning (tiles.bin_gaussians, bit for bit). Gaussian g covers the pixels whose centres lie in
// [m - r, m + r]: x0 = ceil(m - r - 0.5), x1 = floor(m + r - 0.5) in F arithmetic, as the torch code.
struct TileRange {
  int64_t tx0, tx1, ty0, ty1;  // [tx0, tx1) x [ty0, ty1); empty when the Gaussian is culled or off-image
};

// std::floor / std::ceil without a libm call (baseline x86-64 has no rounding instruction): exact for every
// finite value, since floats at or above 2^(mantissa bits) are integers already; NaN passes through.
template <typename F>
inline F floor_exact(F v) {
  if (!(std::fabs(v) < F(int64_t(1) << std::numeric_limits<F>::digits))) return v;
  const F i = F(int64_t(v));
  return i > v ? i - F(1) : i;
}
template <typename F>
inline F ceil_exact(F v) {
  if (!(std::fabs(v) < F(int64_t(1) << std::numeric_limits<F>::digits))) return v;
  const F i = F(int64_t(v));
  return i < v ? i + F(1) : i;
}

template <typename F>
TileRange tile_range(const F* means2d, const int64_t* radii, int64_t g, const Grid& grid) {
  const F mx = means2d[2 * g], my = means2d[2 * g + 1], r = F(radii[g]);
  const F x0 = ceil_exact(mx - r - F(0.5)), x1 = floor_exact(mx + r - F(0.5));
  const F y0 = ceil_exact(my - r - F(0.5)), y1 = floor_exact(my + r - F(0.5));
  const bool inside = radii[g] > 0 && x0 <= x1 && y0 <= y1 && x1 >= F(0) && x0 <= F(grid.width - 1) &&
                      y1 >= F(0) && y0 <= F(grid.height - 1) && std::isfinite(mx) && std::isfinite(my);
  if (!inside) return {0, 0, 0, 0};
  auto clip = [](F v, int hi) { return int64_t(std::min(std::max(v, F(0)), F(hi))); };
  return {clip(x0, grid.width - 1) / grid.tile, clip(x1, grid.width - 1) / grid.tile + 1,
          clip(y0, grid.height - 1) / grid.tile, clip(y1, grid.height - 1) / grid.tile + 1};
}

// tiles.float_order_key: float32 -> uint32 with the same order.
inline uint32_t float_order(float v) {
  int32_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  if (bits < 0) bits ^= 0x7FFFFFFF;
  return uint32_t(int64_t(bits) + (int64_t(1) << 31));
}

// Pass 1: each Gaussian's tile range into `ranges` (N, 4) int64 (tx0, tx1, ty0, ty1) and offsets (T + 1,) =
// exclusive prefix sum of the pairs per tile; returns the number of pairs.
template <typename F>
int64_t bin_count_impl(const F* means2d, const int64_t* radii, int64_t n, Grid grid, int64_t* ranges,
                       int64_t* offsets) {
  const int64_t num_tiles = grid.num_tiles();
  std::fill(offsets, offsets + num_tiles + 1, int64_t(0));
  for (int64_t g = 0; g < n; ++g) {
    const TileRange t = tile_range(means2d, radii, g, grid);
    int64_t* r = ranges + 4 * g;
    r[0] = t.tx0; r[1] = t.tx1; r[2] = t.ty0; r[3] = t.ty1;
    for (int64_t ty = t.ty0; ty < t.ty1; ++ty)
      for (int64_t tx = t.tx0; tx < t.tx1; ++tx) ++offsets[ty * grid.tiles_x + tx + 1];
  }
  for (int64_t t = 0; t < num_tiles; ++t) offsets[t + 1] += offsets[t];
  return offsets[num_tiles];
}

// Pass 2: each tile's list in (float_order(float(key)), Gaussian index) order, the torch version's stable sort.
// The Gaussians that cover a tile are ordered once by a stable radix sort of their 32-bit keys (four 8-bit
// passes over the indices in ascending order, so equal keys keep index order) and then dealt out to their tiles
// in that order, which leaves every tile's list sorted: O(N) instead of sorting each tile's pairs. Needs N < 2^32.
template <typename F>
void bin_fill_impl(const int64_t* ranges, const F* keys, int64_t n, Grid grid, const int64_t* offsets,
                   int64_t* ids) {
  std::vector<uint32_t> key, index;
  for (int64_t g = 0; g < n; ++g) {
    if (ranges[4 * g] == ranges[4 * g + 1]) continue;
    key.push_back(float_order(float(keys[g])));
    index.push_back(uint32_t(g));
  }
  std::vector<uint32_t> key_out(key.size()), index_out(index.size());
  for (int shift = 0; shift < 32; shift += 8) {
    size_t start[257] = {};
    for (uint32_t k : key) ++start[((k >> shift) & 0xFFu) + 1];
    for (int d = 0; d < 256; ++d) start[d + 1] += start[d];
    for (size_t i = 0; i < key.size(); ++i) {
      const size_t to = start[(key[i] >> shift) & 0xFFu]++;
      key_out[to] = key[i];
      index_out[to] = index[i];
    }
    key.swap(key_out);
    index.swap(index_out);
  }
  std::vector<int64_t> cursor(offsets, offsets + grid.num_tiles());
  for (uint32_t g : index) {
    const int64_t* r = ranges + 4 * int64_t(g);
    for (int64_t ty = r[2]; ty < r[3]; ++ty)
      for (int64_t tx = r[0]; tx < r[1]; ++tx) ids[cursor[ty * grid.tiles_x + tx]++] = int64_t(g);
  }
}

// ---------------------------------------------------------------------------------------------------------
// Projection (projection.project, same formulas, evaluated in double whatever F is). `camera` holds the w2c
// matrix (16, row-major), then fx, fy, cx, cy, the clamp bounds of x/z and y/z (u_lo, u_hi, v_lo, v_hi),
// near, far, the low-pass term and the radius in sigmas: 28 doubles.
struct ProjectCamera {
  double R[3][3], t[3], fx, fy, cx, cy, u_lo, u_hi, v_lo, v_hi, near, far, low_pass, sigmas;
  explicit ProjectCamera(const double* c) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) R[i][j] = c[4 * i + j];
      t[i] = c[4 * i + 3];
    }
    fx = c[16]; fy = c[17]; cx = c[18]; cy = c[19];
    u_lo = c[20]; u_hi = c[21]; v_lo = c[22]; v_hi = c[23];
    near = c[24]; far = c[25]; low_pass = c[26]; sigmas = c[27];
  }
};

// Everything the backward needs of one Gaussian's forward.
struct ProjectState {
  double m[3], c[3], zs, u, v, uc, vc, J00, J02, J11, J12;
  Rotation<double> rot;  // of the Gaussian's quaternion
  double s[3], Sigma[3][3], SigmaC[3][3], a, b, cc, det, ds;
  bool in_range, ok;
};

template <typename F>
void project_state(const F* means, const F* quats, const F* scales, int64_t g, const ProjectCamera& cam,
                   ProjectState& st) {
  for (int i = 0; i < 3; ++i) { st.m[i] = double(means[3 * g + i]); st.s[i] = double(scales[3 * g + i]); }
  for (int i = 0; i < 3; ++i)
    st.c[i] = cam.R[i][0] * st.m[0] + cam.R[i][1] * st.m[1] + cam.R[i][2] * st.m[2] + cam.t[i];
  const double z = st.c[2];
  st.in_range = z > cam.near && z < cam.far;
  st.zs = st.in_range ? z : 1.0;
  st.u = st.c[0] / st.zs;
  st.v = st.c[1] / st.zs;
  st.uc = std::min(std::max(st.u, cam.u_lo), cam.u_hi);
  st.vc = std::min(std::max(st.v, cam.v_lo), cam.v_hi);
  st.J00 = cam.fx / st.zs; st.J02 = -cam.fx * st.uc / st.zs;
  st.J11 = cam.fy / st.zs; st.J12 = -cam.fy * st.vc / st.zs;
  double q[4];
  for (int i = 0; i < 4; ++i) q[i] = double(quats[4 * g + i]);
  rotation_eval<double>(q, st.rot);
  double M[3][3];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) M[i][j] = st.rot.R[i][j] * st.s[j];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) st.Sigma[i][j] = M[i][0] * M[j][0] + M[i][1] * M[j][1] + M[i][2] * M[j][2];
  double RS[3][3];  // R Sigma
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      RS[i][j] = cam.R[i][0] * st.Sigma[0][j] + cam.R[i][1] * st.Sigma[1][j] + cam.R[i][2] * st.Sigma[2][j];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      st.SigmaC[i][j] = RS[i][0] * cam.R[j][0] + RS[i][1] * cam.R[j][1] + RS[i][2] * cam.R[j][2];
  const double (*C)[3] = st.SigmaC;
  // cov2d = J SigmaC J^T with J = [[J00, 0, J02], [0, J11, J12]]
  st.a = st.J00 * (st.J00 * C[0][0] + st.J02 * C[2][0]) + st.J02 * (st.J00 * C[0][2] + st.J02 * C[2][2]) +
         cam.low_pass;
  st.b = st.J00 * (st.J11 * C[0][1] + st.J12 * C[0][2]) + st.J02 * (st.J11 * C[2][1] + st.J12 * C[2][2]);
  st.cc = st.J11 * (st.J11 * C[1][1] + st.J12 * C[2][1]) + st.J12 * (st.J11 * C[1][2] + st.J12 * C[2][2]) +
          cam.low_pass;
  st.det = st.a * st.cc - st.b * st.b;
  st.ok = st.in_range && st.det > 0.0;
  st.ds = st.ok ? st.det : 1.0;
}

template <typename F>
void project_forward_impl(const F* means, const F* quats, const F* scales, const double* camera, int64_t n,
                          int width, int height, int threads, F* means2d, F* conics, int64_t* radii, F* depths) {
  const ProjectCamera cam(camera);
  parallel_for_static(n, threads, [&](int64_t g) {
    ProjectState st;
    project_state(means, quats, scales, g, cam, st);
    const double mx = cam.fx * st.u + cam.cx, my = cam.fy * st.v + cam.cy;
    means2d[2 * g] = F(mx);
    means2d[2 * g + 1] = F(my);
    conics[3 * g] = F(st.cc / st.ds);
    conics[3 * g + 1] = F(-st.b / st.ds);
    conics[3 * g + 2] = F(st.a / st.ds);
    depths[g] = F(st.c[2]);
    const double mid = 0.5 * (st.a + st.cc);
    const double lam = mid + std::sqrt(std::max(mid * mid - st.det, 0.0));
    const double radius = std::ceil(cam.sigmas * std::sqrt(std::max(lam, 0.0)));
    const bool on_screen = mx + radius > 0 && mx - radius < width && my + radius > 0 && my - radius < height;
    radii[g] = (st.ok && on_screen && std::isfinite(radius)) ? int64_t(radius) : 0;
  });
}

// Backward: gradients of means (N,3), quats (N,4), scales (N,3) and, if grad_w2c is not null, of the w2c
// matrix (4x4, row-major; row 3 stays 0), summed over Gaussians in index order (deterministic).
template <typename F>
void project_backward_impl(const F* means, const F* quats, const F* scales, const double* camera, int64_t n,
                           int threads, const F* grad_means2d, const F* grad_conics, const F* grad_depths,
                           F* grad_means, F* grad_quats, F* grad_scales, F* grad_w2c) {
  const ProjectCamera cam(camera);
  std::vector<double> pose(grad_w2c ? size_t(n) * 12 : 0);
  parallel_for_static(n, threads, [&](int64_t g) {
    ProjectState st;
    project_state(means, quats, scales, g, cam, st);
    const double gc0 = double(grad_conics[3 * g]), gc1 = double(grad_conics[3 * g + 1]);
    const double gc2 = double(grad_conics[3 * g + 2]);
    // conics = (c, -b, a) / ds, ds = det where ok
    const double inv = 1.0 / st.ds;
    const double d_ds = st.ok ? -(gc0 * st.cc - gc1 * st.b + gc2 * st.a) * inv * inv : 0.0;
    const double ga = gc2 * inv + d_ds * st.cc, gb = -gc1 * inv - 2.0 * d_ds * st.b;
    const double gcc = gc0 * inv + d_ds * st.a;
    // cov2d = J SigmaC J^T, gradient E on its (0,0), (0,1), (1,1) entries.
    const double J[2][3] = {{st.J00, 0.0, st.J02}, {0.0, st.J11, st.J12}};
    const double E[2][2] = {{ga, gb}, {0.0, gcc}};
    double JC[2][3];  // J SigmaC
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 3; ++j)
        JC[i][j] = J[i][0] * st.SigmaC[0][j] + J[i][1] * st.SigmaC[1][j] + J[i][2] * st.SigmaC[2][j];
    // dJ = (E + E^T) J SigmaC
    const double S[2][2] = {{2.0 * ga, gb}, {gb, 2.0 * gcc}};
    double dJ[2][3];
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 3; ++j) dJ[i][j] = S[i][0] * JC[0][j] + S[i][1] * JC[1][j];
    // dSigmaC = J^T E J
    double EJ[2][3];
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 3; ++j) EJ[i][j] = E[i][0] * J[0][j] + E[i][1] * J[1][j];
    double G[3][3];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) G[i][j] = J[0][i] * EJ[0][j] + J[1][i] * EJ[1][j];
    // SigmaC = R Sigma R^T: dSigma = R^T G R, dR = (G + G^T) R Sigma
    double GR[3][3], dSigma[3][3], dR[3][3] = {};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) GR[i][j] = G[i][0] * cam.R[0][j] + G[i][1] * cam.R[1][j] + G[i][2] * cam.R[2][j];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        dSigma[i][j] = cam.R[0][i] * GR[0][j] + cam.R[1][i] * GR[1][j] + cam.R[2][i] * GR[2][j];
    if (grad_w2c) {
      double RSig[3][3];
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          RSig[i][j] = cam.R[i][0] * st.Sigma[0][j] + cam.R[i][1] * st.Sigma[1][j] + cam.R[i][2] * st.Sigma[2][j];
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          double acc = 0.0;
          for (int k = 0; k < 3; ++k) acc += (G[i][k] + G[k][i]) * RSig[k][j];
          dR[i][j] = acc;
        }
    }
    // Sigma = M M^T, M = Rq diag(s): dM = (dSigma + dSigma^T) M
    double dRq[3][3];
    for (int j = 0; j < 3; ++j) {
      double ds_j = 0.0;
      for (int i = 0; i < 3; ++i) {
        double dM = 0.0;
        for (int k = 0; k < 3; ++k) dM += (dSigma[i][k] + dSigma[k][i]) * st.rot.R[k][j] * st.s[j];
        dRq[i][j] = dM * st.s[j];
        ds_j += dM * st.rot.R[i][j];
      }
      grad_scales[3 * g + j] = F(ds_j);
    }
    double gq[4];
    rotation_backward<double>(st.rot, dRq, gq);
    for (int i = 0; i < 4; ++i) grad_quats[4 * g + i] = F(gq[i]);
    // J entries -> zs and the clamped u, v; means2d -> u, v; u = x / zs, v = y / zs
    const double zs2 = st.zs * st.zs;
    double d_zs = -dJ[0][0] * cam.fx / zs2 + dJ[0][2] * cam.fx * st.uc / zs2 - dJ[1][1] * cam.fy / zs2 +
                  dJ[1][2] * cam.fy * st.vc / zs2;
    double du = double(grad_means2d[2 * g]) * cam.fx, dv = double(grad_means2d[2 * g + 1]) * cam.fy;
    if (st.u >= cam.u_lo && st.u <= cam.u_hi) du += -dJ[0][2] * cam.fx / st.zs;
    if (st.v >= cam.v_lo && st.v <= cam.v_hi) dv += -dJ[1][2] * cam.fy / st.zs;
    const double dcx = du / st.zs, dcy = dv / st.zs;
    d_zs += -du * st.c[0] / zs2 - dv * st.c[1] / zs2;
    const double dcz = (st.in_range ? d_zs : 0.0) + double(grad_depths[g]);
    const double dc[3] = {dcx, dcy, dcz};
    for (int i = 0; i < 3; ++i)
      grad_means[3 * g + i] = F(cam.R[0][i] * dc[0] + cam.R[1][i] * dc[1] + cam.R[2][i] * dc[2]);
    if (grad_w2c) {
      double* p = &pose[size_t(g) * 12];
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) p[4 * i + j] = dR[i][j] + dc[i] * st.m[j];
        p[4 * i + 3] = dc[i];
      }
    }
  });
  if (grad_w2c) {
    double total[12] = {0.0};
    for (int64_t g = 0; g < n; ++g)
      for (int k = 0; k < 12; ++k) total[k] += pose[size_t(g) * 12 + k];
    for (int k = 0; k < 12; ++k) grad_w2c[k] = F(total[k]);
    for (int k = 12; k < 16; ++k) grad_w2c[k] = F(0);
  }
}

}  // namespace

#define OLATBENCH_DEFINE(F, SUFFIX)                                                                          \
  OLATBENCH_EXPORT void olatbench_forward_##SUFFIX(                                                         \
      const F* means2d, const F* conics, const F* opac, const F* features, int channels,                    \
      const int64_t* offsets, const int64_t* ids, int width, int height, int tile, int tiles_x, int tiles_y, \
      int threads, double alpha_max, int stop_at_t_min, F* out_colour, F* out_t, int32_t* out_count) {     \
    forward_impl<F>(means2d, conics, opac, features, channels, offsets, ids,                                \
                    Grid{width, height, tile, tiles_x, tiles_y}, threads,                                   \
                    Rules<F>::of(alpha_max, stop_at_t_min), out_colour, out_t, out_count);                  \
  }                                                                                                         \
  OLATBENCH_EXPORT void olatbench_backward_##SUFFIX(                                                        \
      const F* means2d, const F* conics, const F* opac, const F* features, int channels,                    \
      const int64_t* offsets, const int64_t* ids, int width, int height, int tile, int tiles_x, int tiles_y, \
      int threads, double alpha_max, int stop_at_t_min, const F* final_t, const int32_t* counts,            \
      const F* grad_colour, const F* grad_t, int64_t num_gaussians, F* grad_means2d, F* grad_conics,        \
      F* grad_opac, F* grad_features) {                                                                     \
    backward_impl<F>(means2d, conics, opac, features, channels, offsets, ids,                               \
                     Grid{width, height, tile, tiles_x, tiles_y}, threads,                                  \
                     Rules<F>::of(alpha_max, stop_at_t_min), final_t, counts, grad_colour,                  \
                     grad_t, num_gaussians, grad_means2d, grad_conics, grad_opac, grad_features);           \
  }                                                                                                         \
  OLATBENCH_EXPORT void olatbench_max_weight_##SUFFIX(                                                      \
      const F* means2d, const F* conics, const F* opac, const int64_t* offsets, const int64_t* ids,         \
      int width, int height, int tile, int tiles_x, int tiles_y, int threads, int64_t num_gaussians,        \
      F* max_weight) {                                                                                      \
    max_weight_impl<F>(means2d, conics, opac, offsets, ids, Grid{width, height, tile, tiles_x, tiles_y},    \
                       threads, num_gaussians, max_weight);                                                 \
  }                                                                                                         \
  OLATBENCH_EXPORT void olatbench_shadow_gather_##SUFFIX(                                                   \
      const F* means2d, const F* conics, const F* opac, const F* keys, double depth_offset, int density,    \
      const int64_t* offsets, const int64_t* ids, int width, int height, int tile, int tiles_x,             \
      int tiles_y, F radius_px, int threads, int64_t num_gaussians, F* vis_sum, int32_t* count, F* norm,    \
      F* weight) {                                                                                          \
    shadow_gather_impl<F>(means2d, conics, opac, keys, depth_offset, density, offsets, ids,                 \
                          Grid{width, height, tile, tiles_x, tiles_y}, radius_px, threads, num_gaussians,   \
                          vis_sum, count, norm, weight);                                                    \
  }                                                                                                         \
  OLATBENCH_EXPORT int64_t olatbench_bin_count_##SUFFIX(                                                   \
      const F* means2d, const int64_t* radii, int64_t n, int width, int height, int tile, int tiles_x,       \
      int tiles_y, int64_t* ranges, int64_t* offsets) {                                                     \
    return bin_count_impl<F>(means2d, radii, n, Grid{width, height, tile, tiles_x, tiles_y}, ranges,       \
                             offsets);                                                                      \
  }                                                                                                         \
  OLATBENCH_EXPORT void olatbench_bin_fill_##SUFFIX(                                                        \
      const int64_t* ranges, const F* keys, int64_t n, int width, int height, int tile, int tiles_x,         \
      int tiles_y, const int64_t* offsets, int64_t* ids) {                                                  \
    bin_fill_impl<F>(ranges, keys, n, Grid{width, height, tile, tiles_x, tiles_y}, offsets, ids);           \
  }                                                                                                         \
  OLATBENCH_EXPORT void olatbench_project_forward_##SUFFIX(                                                 \
      const F* means, const F* quats, const F* scales, const double* camera, int64_t n, int width,          \
      int height, int threads, F* means2d, F* conics, int64_t* radii, F* depths) {                          \
    project_forward_impl<F>(means, quats, scales, camera, n, width, height, threads, means2d, conics, radii, \
                            depths);                                                                        \
  }                                                                                                         \
  OLATBENCH_EXPORT void olatbench_project_backward_##SUFFIX(                                                \
      const F* means, const F* quats, const F* scales, const double* camera, int64_t n, int threads,        \
      const F* grad_means2d, const F* grad_conics, const F* grad_depths, F* grad_means, F* grad_quats,      \
      F* grad_scales, F* grad_w2c) {                                                                        \
    project_backward_impl<F>(means, quats, scales, camera, n, threads, grad_means2d, grad_conics,           \
                             grad_depths, grad_means, grad_quats, grad_scales, grad_w2c);                   \
  }

OLATBENCH_DEFINE(float, f32)
OLATBENCH_DEFINE(double, f64)

OLATBENCH_DEFINE_ABI_VERSION()
