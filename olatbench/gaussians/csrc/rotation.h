// Quaternion -> rotation matrix and its backward, shared by the projection (rasterize.cpp, T = double) and the
// SSD-GS shading kernels (shading.cpp: T = F for the ASG lobe frames, T = Simd<F>::V for lanes of Gaussians).
// The same conversion as the torch code's projection.quat_to_rotmat: wxyz, normalised without an epsilon.
#pragma once

#include <cstring>

#include "simd.h"

namespace {

// R (row-major [i][j]) of the normalised quaternion q = quat / |quat|, with |quat| and q kept for the backward.
template <typename T>
struct Rotation {
  T norm, q[4], R[3][3];
};

template <typename F, typename T>
void rotation_eval(const T* quat, Rotation<T>& r) {
  r.norm = root((quat[0] * quat[0] + quat[1] * quat[1]) + (quat[2] * quat[2] + quat[3] * quat[3]));
  for (int i = 0; i < 4; ++i) r.q[i] = quat[i] / r.norm;
  const T w = r.q[0], x = r.q[1], y = r.q[2], z = r.q[3];
  const T R[3][3] = {
      {F(1) - F(2) * (y * y + z * z), F(2) * (x * y - w * z), F(2) * (x * z + w * y)},
      {F(2) * (x * y + w * z), F(1) - F(2) * (x * x + z * z), F(2) * (y * z - w * x)},
      {F(2) * (x * z - w * y), F(2) * (y * z + w * x), F(1) - F(2) * (x * x + y * y)},
  };
  std::memcpy(r.R, R, sizeof(R));
}

// dL/dquat from dL/dR: the derivatives of R's nine entries w.r.t. q, then through q = quat / |quat|:
// dL/dquat = (g - q (q . g)) / |quat| with g = dL/dq.
template <typename F, typename T>
void rotation_backward(const Rotation<T>& r, const T (&gR)[3][3], T* grad_quat) {
  const T w = r.q[0], x = r.q[1], y = r.q[2], z = r.q[3];
  T gq[4];
  gq[0] = F(2) * (-z * gR[0][1] + y * gR[0][2] + z * gR[1][0] - x * gR[1][2] - y * gR[2][0] + x * gR[2][1]);
  gq[1] = F(2) * (y * gR[0][1] + z * gR[0][2] + y * gR[1][0] - F(2) * x * gR[1][1] - w * gR[1][2] +
                  z * gR[2][0] + w * gR[2][1] - F(2) * x * gR[2][2]);
  gq[2] = F(2) * (-F(2) * y * gR[0][0] + x * gR[0][1] + w * gR[0][2] + x * gR[1][0] + z * gR[1][2] -
                  w * gR[2][0] + z * gR[2][1] - F(2) * y * gR[2][2]);
  gq[3] = F(2) * (-F(2) * z * gR[0][0] - w * gR[0][1] + x * gR[0][2] + w * gR[1][0] - F(2) * z * gR[1][1] +
                  y * gR[1][2] + x * gR[2][0] + y * gR[2][1]);
  const T qg = (r.q[0] * gq[0] + r.q[1] * gq[1]) + (r.q[2] * gq[2] + r.q[3] * gq[3]);
  for (int i = 0; i < 4; ++i) grad_quat[i] = (gq[i] - r.q[i] * qg) / r.norm;
}

}  // namespace
