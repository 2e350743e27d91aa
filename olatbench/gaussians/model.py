"""The Gaussian parameter container shared by every method.

A :class:`GaussianModel` holds N anisotropic 3D Gaussians as raw (unconstrained) parameters:

- ``means`` (N, 3) world-space centres,
- ``log_scales`` (N, 3) natural logs of the per-axis standard deviations
  (``scales = exp(log_scales)``),
- ``quats`` (N, 4) rotations as ``wxyz`` quaternions, unnormalised (renderers normalise),
- ``opacity_logits`` (N,) with ``opacities = sigmoid(opacity_logits)``,
- ``attributes``: any named per-Gaussian tensors (N, ...) a method needs (albedo, latent material,
  …), stored raw; activations are the method's business.

Every parameter's first dimension is N; :mod:`olatbench.gaussians.optim` relies on that to keep
optimizer state aligned when Gaussians are added or removed. Initialisation follows 3DGS: opacity
0.1, identity rotation, isotropic scale = sqrt(mean squared distance to the 3 nearest neighbours)
(``distCUDA2``), computed with the exact grid search of :mod:`olatbench.gaussians.knn`, which needs
no CUDA extension.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from olatbench.atomic import atomic_path
from olatbench.gaussians.knn import mean_neighbour_sq_distance

CHECKPOINT_FORMAT = "olatbench.gaussians.GaussianModel/1"
CORE_PARAMETERS = ("means", "log_scales", "quats", "opacity_logits")
# Trailing shapes of the core parameters (after the leading N).
_CORE_SHAPES = {"means": (3,), "log_scales": (3,), "quats": (4,), "opacity_logits": ()}
# 3DGS clamps the squared neighbour distance from below so that duplicate points get a finite
# log-scale.
MIN_NEIGHBOUR_SQ_DISTANCE = 1e-7

AttributeSpec = tuple[int, ...] | torch.Tensor


def points_in_ball(
    n: int, radius: float, seed: int, center: tuple[float, float, float] = (0.0, 0.0, 0.0)
) -> torch.Tensor:
    """(n, 3) float32 CPU points uniform in the ball of ``radius`` around ``center`` (world units),
    drawn on the CPU from ``seed``: the same points on every device and machine."""
    generator = torch.Generator().manual_seed(seed)
    cpu64 = dict(generator=generator, dtype=torch.float64, device="cpu")
    direction = torch.randn(n, 3, **cpu64)
    direction /= direction.norm(dim=1, keepdim=True).clamp_min(1e-12)
    r = radius * torch.rand(n, 1, **cpu64) ** (1.0 / 3.0)
    return (direction * r + torch.tensor(center, dtype=torch.float64, device="cpu")).float()


class GaussianModel(nn.Module):
    """N 3D Gaussians as ``nn.Parameter`` tensors whose first dimension is N
    (see the module docstring)."""

    def __init__(
        self,
        means: torch.Tensor,
        log_scales: torch.Tensor,
        quats: torch.Tensor,
        opacity_logits: torch.Tensor,
        attributes: dict[str, torch.Tensor] | None = None,
    ) -> None:
        super().__init__()
        n = means.shape[0]
        values = {
            "means": means,
            "log_scales": log_scales,
            "quats": quats,
            "opacity_logits": opacity_logits,
        }
        for name, value in values.items():
            _check_rows(name, value, n, _CORE_SHAPES[name])
            setattr(self, name, nn.Parameter(value.detach().clone()))
        self.attributes = nn.ParameterDict()
        for name, value in (attributes or {}).items():
            _check_rows(f"attributes[{name!r}]", value, n, None)
            self.attributes[name] = nn.Parameter(value.detach().clone())

    # -----------------------------------------------------------------------------------------
    # activations
    @property
    def scales(self) -> torch.Tensor:
        """(N, 3) linear standard deviations ``exp(log_scales)``."""
        return torch.exp(self.log_scales)

    @property
    def opacities(self) -> torch.Tensor:
        """(N,) opacities in (0, 1): ``sigmoid(opacity_logits)``."""
        return torch.sigmoid(self.opacity_logits)

    @property
    def num_gaussians(self) -> int:
        return int(self.means.shape[0])

    def per_gaussian_parameters(self) -> dict[str, nn.Parameter]:
        """Every per-Gaussian parameter by name (``means`` …, ``attributes.<name>``), in a stable
        order."""
        params = {name: getattr(self, name) for name in CORE_PARAMETERS}
        params.update({f"attributes.{name}": value for name, value in self.attributes.items()})
        return params

    # --------------------------------------------------------------------------------------
    # constructors
    @classmethod
    def from_points(
        cls,
        points: torch.Tensor | np.ndarray,
        colours: torch.Tensor | np.ndarray | None = None,
        attributes: dict[str, AttributeSpec] | None = None,
        opacity: float = 0.1,
        device: torch.device | str | None = None,
        dtype: torch.dtype = torch.float32,
    ) -> GaussianModel:
        """Gaussians centred on ``points`` (N, 3), 3DGS-initialised (see the module docstring).

        ``colours`` (N, 3), if given, becomes the attribute ``"colour"``. ``attributes`` maps names
        to either a trailing shape (zeros of shape (N, *shape)) or a tensor (N, ...) used as is.
        """
        means = (
            torch.as_tensor(np.asarray(points), device="cpu")
            if isinstance(points, np.ndarray)
            else points
        )
        means = means.to(device=device, dtype=dtype)
        if means.ndim != 2 or means.shape[1] != 3 or means.shape[0] == 0:
            raise ValueError(
                f"points must be a non-empty (N, 3) array, got shape {tuple(means.shape)}"
            )
        if not bool(torch.isfinite(means).all()):
            raise ValueError("points contain NaN or infinite coordinates")
        n = means.shape[0]
        if n > 1:
            sq = mean_neighbour_sq_distance(means, k=min(3, n - 1))
        else:
            sq = torch.ones(1, device=means.device, dtype=dtype)
        log_scales = 0.5 * torch.log(sq.clamp_min(MIN_NEIGHBOUR_SQ_DISTANCE))[:, None].repeat(1, 3)
        quats = torch.zeros(n, 4, device=means.device, dtype=dtype)
        quats[:, 0] = 1.0
        if not 0.0 < opacity < 1.0:
            raise ValueError(f"initial opacity must be in (0, 1), got {opacity}")
        opacity_logits = torch.full(
            (n,), math.log(opacity / (1.0 - opacity)), device=means.device, dtype=dtype
        )
        values = _build_attributes(attributes, n, means.device, dtype)
        if colours is not None:
            rgb = (
                torch.as_tensor(np.asarray(colours), device="cpu")
                if isinstance(colours, np.ndarray)
                else colours
            )
            rgb = rgb.to(device=means.device, dtype=dtype)
            _check_rows("colours", rgb, n, (3,))
            values["colour"] = rgb
        return cls(means, log_scales, quats, opacity_logits, values)

    @classmethod
    def random_in_sphere(
        cls,
        n: int,
        radius: float = 1.0,
        attributes: dict[str, AttributeSpec] | None = None,
        seed: int = 0,
        device: torch.device | str | None = None,
        center: tuple[float, float, float] = (0.0, 0.0, 0.0),
        opacity: float = 0.1,
    ) -> GaussianModel:
        """``n`` Gaussians uniform in the ball of ``radius`` around ``center`` (SSD-GS: 10K in the
        unit ball)."""
        points = points_in_ball(n, radius, seed, center)
        return cls.from_points(points, attributes=attributes, opacity=opacity, device=device)

    @classmethod
    def random_in_box(
        cls,
        n: int,
        low: tuple[float, float, float] = (-0.5, -0.5, -0.5),
        high: tuple[float, float, float] = (0.5, 0.5, 0.5),
        attributes: dict[str, AttributeSpec] | None = None,
        seed: int = 0,
        device: torch.device | str | None = None,
        opacity: float = 0.1,
    ) -> GaussianModel:
        """``n`` Gaussians uniform in the axis-aligned box [low, high] (3DGS Blender / SSD-GS code:
        100K in ±0.5)."""
        generator = torch.Generator().manual_seed(seed)
        lo = torch.tensor(low, dtype=torch.float64, device="cpu")
        hi = torch.tensor(high, dtype=torch.float64, device="cpu")
        if not bool((hi > lo).all()):
            raise ValueError(f"random_in_box needs high > low per axis, got low={low}, high={high}")
        points = (
            lo
            + (hi - lo) * torch.rand(n, 3, generator=generator, dtype=torch.float64, device="cpu")
        ).float()
        return cls.from_points(points, attributes=attributes, opacity=opacity, device=device)

    @classmethod
    def from_ply(
        cls,
        path: str | Path,
        attributes: dict[str, AttributeSpec] | None = None,
        device: torch.device | str | None = None,
        opacity: float = 0.1,
    ) -> GaussianModel:
        """Gaussians on the vertices of a point PLY (x, y, z and optional red, green, blue ->
        ``"colour"``)."""
        from olatbench.gaussians.ply import read_ply_points

        points, colours = read_ply_points(path)
        if len(points) == 0:
            raise ValueError(f"{path}: the PLY file has no vertices")
        return cls.from_points(
            points, colours=colours, attributes=attributes, opacity=opacity, device=device
        )

    # --------------------------------------------------------------------------------------
    # persistence
    def to_dict(self) -> dict[str, Any]:
        """Plain dict of detached tensors and strings (what :meth:`save` writes)."""
        return {
            "format": CHECKPOINT_FORMAT,
            **{name: getattr(self, name).detach() for name in CORE_PARAMETERS},
            "attributes": {name: value.detach() for name, value in self.attributes.items()},
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "checkpoint") -> GaussianModel:
        """Inverse of :meth:`to_dict`; ``source`` names the origin in error messages."""
        if not isinstance(data, dict) or data.get("format") != CHECKPOINT_FORMAT:
            found = data.get("format") if isinstance(data, dict) else type(data).__name__
            raise ValueError(
                f"{source}: not a GaussianModel checkpoint (format {found!r}, need "
                f"{CHECKPOINT_FORMAT!r})"
            )
        missing = [name for name in (*CORE_PARAMETERS, "attributes") if name not in data]
        if missing:
            raise ValueError(f"{source}: missing fields {missing}")
        for name in CORE_PARAMETERS:
            if not isinstance(data[name], torch.Tensor):
                raise ValueError(f"{source}: field {name!r} is not a tensor")
        if not isinstance(data["attributes"], dict):
            raise ValueError(f"{source}: field 'attributes' is not a dict")
        try:
            return cls(*(data[name] for name in CORE_PARAMETERS), attributes=data["attributes"])
        except ValueError as error:
            raise ValueError(f"{source}: {error}") from error

    def save(self, path: str | Path) -> Path:
        """Write the Gaussians to ``path`` atomically (``torch.save`` of tensors and strings
        only)."""
        path = Path(path)
        data = self.to_dict()
        data = {k: (v.cpu() if isinstance(v, torch.Tensor) else v) for k, v in data.items()}
        data["attributes"] = {k: v.cpu() for k, v in data["attributes"].items()}
        with atomic_path(path) as temporary:
            torch.save(data, temporary)
        return path

    @classmethod
    def load(cls, path: str | Path, device: torch.device | str | None = None) -> GaussianModel:
        """Read a file written by :meth:`save` (``torch.load(weights_only=True)``) onto
        ``device``."""
        path = Path(path)
        try:
            data = torch.load(path, map_location=device or "cpu", weights_only=True)
        except FileNotFoundError as error:
            raise FileNotFoundError(f"{path}: no such Gaussian checkpoint") from error
        except Exception as error:  # corrupt files raise many different unpickling errors
            raise ValueError(f"{path}: cannot read Gaussian checkpoint ({error})") from error
        return cls.from_dict(data, source=str(path))

    def _load_from_state_dict(
        self, state_dict, prefix, local_metadata, strict, missing_keys, unexpected_keys, error_msgs
    ):
        """Let ``load_state_dict`` change N and add attributes (a checkpoint usually has a different
        count).

        Parameters keep their identity (``.data`` is replaced), so an optimizer built on this model
        stays valid.
        """
        for name in CORE_PARAMETERS:
            key = prefix + name
            if key in state_dict and state_dict[key].shape != getattr(self, name).shape:
                param = getattr(self, name)
                param.data = torch.empty_like(
                    state_dict[key], device=param.device, dtype=param.dtype
                )
        attribute_prefix = prefix + "attributes."
        for key, value in state_dict.items():
            name = key[len(attribute_prefix) :]
            if not key.startswith(attribute_prefix) or "." in name:
                continue
            if name not in self.attributes:
                self.attributes[name] = nn.Parameter(
                    torch.empty_like(value, device=self.means.device)
                )
            elif self.attributes[name].shape != value.shape:
                param = self.attributes[name]
                param.data = torch.empty_like(value, device=param.device, dtype=param.dtype)
        super()._load_from_state_dict(
            state_dict, prefix, local_metadata, strict, missing_keys, unexpected_keys, error_msgs
        )


def _check_rows(name: str, value: torch.Tensor, n: int, trailing: tuple[int, ...] | None) -> None:
    if not isinstance(value, torch.Tensor):
        raise ValueError(f"{name} must be a tensor, got {type(value).__name__}")
    if value.ndim == 0 or value.shape[0] != n:
        raise ValueError(
            f"{name} must have {n} rows (one per Gaussian), got shape {tuple(value.shape)}"
        )
    if trailing is not None and tuple(value.shape[1:]) != trailing:
        raise ValueError(
            f"{name} must have shape (N, {', '.join(map(str, trailing))}), got {tuple(value.shape)}"
        )


def _build_attributes(
    specs: dict[str, AttributeSpec] | None, n: int, device: torch.device, dtype: torch.dtype
) -> dict[str, torch.Tensor]:
    values = {}
    for name, spec in (specs or {}).items():
        if isinstance(spec, torch.Tensor):
            _check_rows(f"attributes[{name!r}]", spec, n, None)
            values[name] = spec.to(device=device)
        else:
            values[name] = torch.zeros((n, *tuple(spec)), device=device, dtype=dtype)
    return values
