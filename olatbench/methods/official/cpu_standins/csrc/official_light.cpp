// The per-pixel loop of the authors' light-view splat (diff-gaussian-rasterization_light, cuda_rasterizer/
// forward.cu, renderCUDA) on the CPU, for olatbench.methods.official.cpu_standins.light.
//
// For each pixel (integer coordinates, as forward.cu's pixf) the Gaussians of its tile are walked front to back
// (sorted by squared distance to the light). A lagging pointer composites the list into the transmittance T
// (alpha = min(0.99, o·exp(power)) where power <= 0, alpha < 1/255 counts as 0; no early stop). For Gaussian j
// with depth d_j: while d_j - depthT > offset the pointer takes the next Gaussian p (depthT = d_p); when
// d_j - d_p <= offset, j records with the T in front of p and the pointer composites p. If no step was needed,
// j records with the current T. "Records" means, when the squared pixel distance to j's centre dd < thres:
// out_trans[j] += exp(power_j)·T and non_trans[j] += exp(power_j). With is_train, out_weight[j] += w for every
// pixel of its tiles, where w is alpha·T of the last pointer step at that pixel (1 before any step).
// clip_power != 0 clamps power_j to at most clip_value (SSD-GS 26e4251's CLIP_THRESHOLD = 10; GS³ 83c8daa has
// no clamp). Arithmetic in float as on the GPU; the atomic adds make sums independent of the tile order up to
// rounding, as the CUDA atomicAdds do.
//
// Not reproduced: forward.cu reloads the pointer's shared-memory batch (collected_*_pointT) inside divergent
// code, a data race between the threads of a 16x16 block once a tile's list passes 256 Gaussians; here every
// pixel reads its own pointer entries, which is what the code is written to do.

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "export.h"

OLATBENCH_DEFINE_ABI_VERSION()

namespace {

constexpr float kSkip = -5.6f;  // exp(-5.6) = 0.0037 < 1/255 = 0.0039

inline float power_at(const float* xy, const float* conic_opacity, int64_t g, float px, float py) {
  const float dx = xy[2 * g] - px, dy = xy[2 * g + 1] - py;
  const float* c = conic_opacity + 4 * g;
  return -0.5f * (c[0] * dx * dx + c[2] * dy * dy) - c[1] * dx * dy;
}

inline void atomic_add(float* target, float value) {
#pragma omp atomic
  *target += value;
}

}  // namespace

// xy (P,2), depths (P), conic_opacity (P,4), offsets (tiles+1), ids (pairs): tile lists sorted by depth.
// Accumulates into out_trans (P), non_trans (P), out_weight (P).
OLATBENCH_EXPORT void olatbench_official_light_f32(const float* xy, const float* depths, const float* conic_opacity,
                                                   const int64_t* offsets, const int64_t* ids, int width, int height,
                                                   int tile, int tiles_x, int tiles_y, float offset, float thres,
                                                   int is_train, int clip_power, float clip_value, int threads,
                                                   float* out_trans, float* non_trans, float* out_weight) {
  const int64_t tiles = static_cast<int64_t>(tiles_x) * tiles_y;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (int64_t t = 0; t < tiles; ++t) {
    const int64_t begin = offsets[t], end = offsets[t + 1];
    if (begin == end) continue;
    const int tx = static_cast<int>(t % tiles_x), ty = static_cast<int>(t / tiles_x);
    for (int py = ty * tile; py < std::min((ty + 1) * tile, height); ++py) {
      for (int px = tx * tile; px < std::min((tx + 1) * tile, width); ++px) {
        const float pxf = static_cast<float>(px), pyf = static_cast<float>(py);
        float T = 1.0f, w = 1.0f, depth_t = 0.0f;
        int64_t pointer = begin;
        for (int64_t k = begin; k < end; ++k) {
          const int64_t j = ids[k];
          const float dx = xy[2 * j] - pxf, dy = xy[2 * j + 1] - pyf;
          const float dd = dx * dx + dy * dy;
          float power_j = 0.0f;  // only read where dd < thres
          if (dd < thres) {
            power_j = power_at(xy, conic_opacity, j, pxf, pyf);
            if (clip_power && power_j > clip_value) power_j = std::fmin(power_j, clip_value);
          }
          const float d_j = depths[j];
          if (d_j - depth_t > offset) {
            while (pointer < end) {
              const int64_t p = ids[pointer++];
              const float power = power_at(xy, conic_opacity, p, pxf, pyf);
              depth_t = depths[p];
              float alpha = 0.0f;
              // power below kSkip: o·exp(power) < exp(kSkip) < 1/255 for any opacity o <= 1, so alpha is 0 as on the
              // GPU; skipping exp there saves most of the work (the far pixels of each tile).
              if (power <= 0.0f && (power >= kSkip || conic_opacity[4 * p + 3] > 1.0f)) {
                alpha = std::min(0.99f, conic_opacity[4 * p + 3] * std::exp(power));
                if (alpha < 1.0f / 255.0f) alpha = 0.0f;
              }
              w = alpha * T;
              const float next_t = T * (1 - alpha);
              const bool reached = d_j - depth_t <= offset;
              if (reached && dd < thres) {
                atomic_add(out_trans + j, std::exp(power_j) * T);
                atomic_add(non_trans + j, std::exp(power_j));
              }
              T = next_t;
              if (reached) break;
            }
          } else if (dd < thres) {
            atomic_add(out_trans + j, std::exp(power_j) * T);
            atomic_add(non_trans + j, std::exp(power_j));
          }
          if (is_train) atomic_add(out_weight + j, w);
        }
      }
    }
  }
}
