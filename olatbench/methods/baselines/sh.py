"""Real spherical harmonics up to degree 3 in the convention of 3D Gaussian Splatting
(``utils/sh_utils.py``).

Coefficients are ordered by degree l then order m = -l … l, so degree d uses ``(d + 1)²`` of them.
With a unit direction (x, y, z) the basis functions are (3DGS / PlenOctrees sign convention)::

    l = 0:  C0
    l = 1:  -C1 y,  C1 z,  -C1 x
    l = 2:  C2[0] xy,  C2[1] yz,  C2[2] (2z² - x² - y²),  C2[3] xz,  C2[4] (x² - y²)
    l = 3:  C3[0] y(3x² - y²),  C3[1] xyz,  C3[2] y(4z² - x² - y²),  C3[3] z(2z² - 3x² - 3y²),
            C3[4] x(4z² - x² - y²),  C3[5] z(x² - y²),  C3[6] x(x² - 3y²)

with the orthonormal constants written out below in closed form (3DGS's ``C0 … C3`` values, signs
included: C0 = 1/(2√π), C1 = √3/(2√π), |C2| = √15/(2√π), √15/(2√π), √5/(4√π), √15/(2√π), √15/(4√π),
…). A colour is ``eval_sh(...) + 0.5`` (3DGS stores the DC term of ``colour - 0.5``).
"""

from __future__ import annotations

import math

import torch

from olatbench.methods.baselines.gs3dgs_config import MAX_SH_DEGREE

C0 = 0.5 / math.sqrt(math.pi)
C1 = math.sqrt(3.0) / (2.0 * math.sqrt(math.pi))
C2 = (
    math.sqrt(15.0) / (2.0 * math.sqrt(math.pi)),
    -math.sqrt(15.0) / (2.0 * math.sqrt(math.pi)),
    math.sqrt(5.0) / (4.0 * math.sqrt(math.pi)),
    -math.sqrt(15.0) / (2.0 * math.sqrt(math.pi)),
    math.sqrt(15.0) / (4.0 * math.sqrt(math.pi)),
)
C3 = (
    -math.sqrt(70.0) / (8.0 * math.sqrt(math.pi)),
    math.sqrt(105.0) / (2.0 * math.sqrt(math.pi)),
    -math.sqrt(42.0) / (8.0 * math.sqrt(math.pi)),
    math.sqrt(7.0) / (4.0 * math.sqrt(math.pi)),
    -math.sqrt(42.0) / (8.0 * math.sqrt(math.pi)),
    math.sqrt(105.0) / (4.0 * math.sqrt(math.pi)),
    -math.sqrt(70.0) / (8.0 * math.sqrt(math.pi)),
)
MAX_DEGREE = MAX_SH_DEGREE


def num_coefficients(degree: int) -> int:
    """``(degree + 1)²`` coefficients per colour channel."""
    return (degree + 1) ** 2


def sh_basis(degree: int, dirs: torch.Tensor) -> torch.Tensor:
    """The real SH basis (…, (degree+1)²) at unit directions ``dirs`` (…, 3)."""
    if not 0 <= degree <= MAX_DEGREE:
        raise ValueError(f"SH degree must be in 0..{MAX_DEGREE}, got {degree}")
    x, y, z = dirs.unbind(-1)
    values = [torch.full_like(x, C0)]
    if degree >= 1:
        values += [-C1 * y, C1 * z, -C1 * x]
    if degree >= 2:
        xx, yy, zz, xy, yz, xz = x * x, y * y, z * z, x * y, y * z, x * z
        values += [
            C2[0] * xy,
            C2[1] * yz,
            C2[2] * (2.0 * zz - xx - yy),
            C2[3] * xz,
            C2[4] * (xx - yy),
        ]
    if degree >= 3:
        values += [
            C3[0] * y * (3.0 * xx - yy),
            C3[1] * xy * z,
            C3[2] * y * (4.0 * zz - xx - yy),
            C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy),
            C3[4] * x * (4.0 * zz - xx - yy),
            C3[5] * z * (xx - yy),
            C3[6] * x * (xx - 3.0 * yy),
        ]
    return torch.stack(values, dim=-1)


def eval_sh(degree: int, coefficients: torch.Tensor, dirs: torch.Tensor) -> torch.Tensor:
    """Σ_k coefficients[..., k, :] · Y_k(dirs): ``coefficients`` (…, K ≥ (degree+1)², C), ``dirs``
    (…, 3) unit -> (…, C). Coefficients beyond ``degree`` are ignored (the progressive degree
    schedule of 3DGS)."""
    k = num_coefficients(degree)
    if coefficients.shape[-2] < k:
        raise ValueError(f"degree {degree} needs {k} coefficients, got {coefficients.shape[-2]}")
    basis = sh_basis(degree, dirs)
    return (basis[..., :, None] * coefficients[..., :k, :]).sum(-2)


def rgb_to_sh_dc(rgb: torch.Tensor) -> torch.Tensor:
    """The DC coefficient whose colour (``C0 · dc + 0.5``) is ``rgb``."""
    return (rgb - 0.5) / C0


class SHFit:
    """Least-squares SH coefficients per Gaussian for colours seen along several directions, one
    view at a time.

    For each of ``n`` Gaussians, the coefficients ``c`` (K = (degree+1)², 3) minimising Σ_views
    ‖Y(d_v) c + 0.5 − colour_v‖² (a 3DGS colour is ``eval_sh + 0.5``), from the normal equations Σ Y
    Yᵀ c = Σ Y (colour − 0.5) accumulated in float64 by `add` and solved by `solve`. Degree 0 gives
    the mean colour over the views. ``ridge`` (relative to the number of views) is added to the
    diagonal of the coefficients above degree 0 only, so that directions no view saw get small
    coefficients instead of arbitrary ones.
    """

    def __init__(
        self, n: int, degree: int, ridge: float = 1e-3, device: str | torch.device = "cpu"
    ) -> None:
        self.degree, self.ridge = degree, ridge
        k = num_coefficients(degree)
        self.normal = torch.zeros(n, k, k, dtype=torch.float64, device=device)
        self.target = torch.zeros(n, k, 3, dtype=torch.float64, device=device)
        self.views = 0

    def add(self, dirs: torch.Tensor, colours: torch.Tensor) -> None:
        """One view: unit directions (n, 3) from the camera to each Gaussian, and each Gaussian's
        colour (n, 3)."""
        basis = sh_basis(self.degree, dirs.to(self.normal))
        self.normal += basis[:, :, None] * basis[:, None, :]
        self.target += basis[:, :, None] * (colours.to(self.target) - 0.5)[:, None, :]
        self.views += 1

    def solve(self) -> torch.Tensor:
        """The coefficients (n, K, 3) in float32."""
        if self.views == 0:
            raise ValueError("an SH fit needs at least one view")
        k = self.normal.shape[-1]
        penalty = torch.full(
            (k,), self.ridge * self.views, dtype=torch.float64, device=self.normal.device
        )
        penalty[0] = 0.0
        return torch.linalg.solve(self.normal + torch.diag(penalty), self.target).float()


def rotate_sh(coefficients: torch.Tensor, rotation: torch.Tensor) -> torch.Tensor:
    """The coefficients (…, K, C) of degrees 1 … d (K = (d + 1)² − 1, the DC term excluded as 3DGS
    stores ``sh_rest``) of the function rotated by ``rotation`` (3, 3): ``f'(R u) = f(u)`` for every
    unit ``u``.

    Each degree l mixes only its own 2l + 1 coefficients: the matrix is solved, in float64, from the
    basis at 64 fixed directions (more than the 7 unknowns per row of degree 3),
    ``Y_l(Rᵀ u) = D_l Y_l(u)``, exact to rounding since the span of each degree is closed under
    rotation; then ``c'_l = D_lᵀ c_l``.
    """
    k = coefficients.shape[-2]
    degree = math.isqrt(k + 1) - 1
    if num_coefficients(degree) - 1 != k:
        raise ValueError(f"{k} SH coefficients above degree 0 is no whole degree")
    # a Fibonacci sphere
    index = torch.arange(64, dtype=torch.float64, device=coefficients.device) + 0.5
    z = 1.0 - 2.0 * index / 64
    azimuth = math.pi * (1.0 + 5.0**0.5) * index
    dirs = torch.stack(
        [torch.sqrt(1 - z * z) * torch.cos(azimuth), torch.sqrt(1 - z * z) * torch.sin(azimuth), z],
        -1,
    )
    rotation = torch.as_tensor(rotation, dtype=torch.float64, device=coefficients.device)
    # Y(u), Y(Rᵀ u)
    basis, rotated = sh_basis(degree, dirs)[:, 1:], sh_basis(degree, dirs @ rotation)[:, 1:]
    out = coefficients.to(torch.float64).clone()
    for band in range(1, degree + 1):
        rows = slice(band * band - 1, (band + 1) ** 2 - 1)
        mixing = torch.linalg.lstsq(basis[:, rows], rotated[:, rows]).solution  # D_lᵀ
        out[..., rows, :] = torch.einsum(
            "ji,...ic->...jc", mixing, coefficients[..., rows, :].to(torch.float64)
        )
    return out.to(coefficients.dtype)
