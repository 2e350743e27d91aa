"""Per-Gaussian colour of SSD-GS: ``C = (c_d f_d + c_s f_s) · S + c_sss f_sss``, times ``I / d²``.

`Shader` owns the global learnable parts (ASG bases, Θ_SSS, Θ_shad) and turns the raw per-Gaussian
attributes of the visible Gaussians into colour components; the method splats them as feature
channels. Per-Gaussian attributes (raw, activations applied here): ``diffuse`` (K, 3) and
``specular`` (K, 3) and ``sss`` (K, 3) colours through softplus, ``asg_weights`` (K, N) through
softplus, ``material`` (K, M) as is, optionally ``shading_quat`` (K, 4) for the official code's
learned shading frame.

Backends (`Shader.backend`): ``"torch"`` evaluates everything with torch ops (the reference);
``"cpu"`` runs the closed-form parts as the two fused C++ kernels of `shading_cpu` (hand-written
backwards; the two networks stay torch modules called between them) and raises ValueError when it
cannot take the inputs (tensors not on the CPU, not one float32/float64 dtype, ``asg_form``
"official" — the kernels implement the "xu" ASG only) and RuntimeError when its C++ library does not
build; ``"auto"`` (default) uses ``"cpu"`` when it can and ``"torch"`` otherwise, with one
RuntimeWarning when the reason is a failed build (``olatbench._native``'s ``choose_backend``); the
environment variable ``OLATBENCH_SHADING`` (``auto``, ``torch`` or ``cpu``) overrides ``"auto"``.
Both give the same components and gradients up to rounding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from olatbench._native import Unavailable, always, choose_backend
from olatbench.gaussians.projection import quat_to_rotmat
from olatbench.methods.shading.asg import ASGMixture
from olatbench.methods.shading.shadow_mlp import ShadowNetwork
from olatbench.methods.shading.terms import (
    inverse_square_irradiance,
    lambert_cosine,
    min_scale_frames,
    orient_frames,
    safe_normalize,
    schlick_fresnel,
)
from olatbench.methods.ssdgs.config import SSDGSConfig
from olatbench.methods.ssdgs.shading_cpu import (
    LIBRARY,
    rotations_cpu,
    shading_combine,
    shading_geometry,
)
from olatbench.methods.ssdgs.sss import SSSNetwork


@dataclass
class Components:
    """Per-Gaussian shading of K Gaussians: ``colour`` (K, 3) and its parts, all including
    ``I / d²``.

    ``diffuse``/``specular``/``sss`` (K, 3) are unshadowed; ``shadow`` (K, 1) is S
    (1 when the term is off) and ``shadow_coarse`` (K, 1) the light-view visibility v̂
    (1 when not computed)."""

    colour: torch.Tensor
    diffuse: torch.Tensor
    specular: torch.Tensor
    sss: torch.Tensor
    shadow: torch.Tensor
    shadow_coarse: torch.Tensor


BACKENDS = ("auto", "torch", "cpu")
SHADING_ENV = "OLATBENCH_SHADING"


class Shader(nn.Module):
    """The global networks of SSD-GS and the per-Gaussian shading function; ``backend`` as in the
    module doc."""

    def __init__(self, config: SSDGSConfig, backend: str = "auto") -> None:
        super().__init__()
        if backend not in BACKENDS:
            raise ValueError(f"Shader backend must be one of {BACKENDS}, not {backend!r}")
        self.config = config
        self.backend = backend
        self.asg = ASGMixture(config.num_asg, config.asg_form)
        self.sss_net = SSSNetwork(
            config.material_dim,
            config.sss_hidden,
            config.sss_layers,
            config.sss_freqs,
            config.dipole_eta,
            config.dipole_virtual_factor,
            config.network_precision,
            config.sss_last_hidden,
        )
        self.shadow_net = ShadowNetwork(
            config.material_dim,
            config.shadow_hidden,
            config.shadow_layers,
            config.shadow_freqs,
            config.network_precision,
            config.shadow_input_bias,
        )

    def frames(
        self,
        attributes: dict[str, torch.Tensor],
        quats: torch.Tensor,
        scales: torch.Tensor,
        wo: torch.Tensor,
    ) -> torch.Tensor:
        """(K, 3, 3) shading frames (columns x, y, z = normal)."""
        if self.config.shading_frame == "learned":
            frames = quat_to_rotmat(attributes["shading_quat"])
        else:
            frames = min_scale_frames(quat_to_rotmat(quats), scales)
        return orient_frames(frames, wo) if self.config.orient_normals else frames

    def forward(
        self,
        positions: torch.Tensor,
        quats: torch.Tensor,
        scales: torch.Tensor,
        attributes: dict[str, torch.Tensor],
        camera_position: torch.Tensor,
        light_position: torch.Tensor,
        intensity: torch.Tensor,
        terms: frozenset[str],
        coarse_visibility: torch.Tensor | None = None,
    ) -> Components:
        """Shade K Gaussians (``positions`` (K,3), ``quats`` (K,4), ``scales`` (K,3), attributes
        (K, ·)).

        ``terms`` ⊆ {"specular", "sss", "shadow"} are switched on (diffuse always is);
        ``coarse_visibility`` (K,) is required when "shadow" is on.
        """
        if self.backend != "torch":
            tensors = [
                positions,
                quats,
                scales,
                camera_position,
                light_position,
                intensity,
                *(attributes[name] for name in self._attribute_names(terms)),
            ]
            if "specular" in terms:
                tensors += list(self.asg.parameters())
            if self.choose(positions.device.type, tensors) == "cpu":
                return self._forward_cpu(
                    positions,
                    quats,
                    scales,
                    attributes,
                    camera_position,
                    light_position,
                    intensity,
                    terms,
                    coarse_visibility,
                )
        wi, incident = inverse_square_irradiance(positions, light_position, intensity)
        wo = safe_normalize(camera_position[None, :] - positions)
        frames = self.frames(attributes, quats, scales, wo)
        normals = frames[:, :, 2]
        ones = positions.new_ones(positions.shape[0], 1)
        zeros3 = positions.new_zeros(positions.shape[0], 3)

        diffuse = (
            F.softplus(attributes["diffuse"])
            / math.pi
            * lambert_cosine(normals, wi, self.config.diffuse_cosine)
        )
        specular = zeros3
        if "specular" in terms:
            half = safe_normalize(wi + wo)
            h_local = torch.einsum("ki,kij->kj", half, frames)
            lobes = self.asg(h_local, F.softplus(attributes["asg_weights"]))
            specular = (
                F.softplus(attributes["specular"])
                * schlick_fresnel(wi, half, self.config.fresnel_f0)
                * lobes
            )
        sss = zeros3
        if "sss" in terms:
            sss = F.softplus(attributes["sss"]) * self.sss_net(
                positions, wo, wi, normals, attributes["material"]
            )
        shadow, coarse = ones, ones
        if "shadow" in terms:
            if coarse_visibility is None:
                raise ValueError("the shadow term needs the coarse light-view visibility")
            coarse = coarse_visibility[:, None].to(positions.dtype)
            shadow = self.shadow_net(positions, wi, coarse, attributes["material"])

        diffuse, specular, sss = diffuse * incident, specular * incident, sss * incident
        if self.config.shadow_on_sss:
            colour = (diffuse + specular + sss) * shadow
        else:
            colour = (diffuse + specular) * shadow + sss
        return Components(colour, diffuse, specular, sss, shadow, coarse)

    def choose(self, device_type: str, tensors: list[torch.Tensor]) -> str:
        """The backend for input ``tensors`` on ``device_type``: "cpu" (the C++ kernels) or
        "torch"."""
        available = {"cpu": lambda: self.cpu_unsupported(tensors), "torch": always}
        return choose_backend(
            self.backend, device_type, available, kind="SSD-GS shading", env_var=SHADING_ENV
        )

    def backend_for(self, device: torch.device | str, dtype: torch.dtype = torch.float32) -> str:
        """The backend `forward` runs for ``dtype`` inputs on ``device``
        (for doctor and the run log)."""
        device = torch.device(device)
        return self.choose(device.type, [torch.zeros(1, device=device, dtype=dtype)])

    def _attribute_names(self, terms: frozenset[str]) -> list[str]:
        """The per-Gaussian attributes shading with ``terms`` reads."""
        names = ["diffuse"]
        if self.config.shading_frame == "learned":
            names.append("shading_quat")
        if "specular" in terms:
            names += ["specular", "asg_weights"]
        if "sss" in terms:
            names.append("sss")
        if "sss" in terms or "shadow" in terms:
            names.append("material")
        return names

    def cpu_unsupported(self, tensors: list[torch.Tensor]) -> Unavailable | None:
        """Why the fused C++ kernels cannot shade with these input ``tensors`` and this config
        (None: they can)."""
        if self.config.asg_form != "xu":
            return Unavailable(
                f"asg_form {self.config.asg_form!r} (the C++ kernels implement the 'xu' ASG form "
                "only)"
            )
        dtype = tensors[0].dtype
        if dtype not in (torch.float32, torch.float64):
            return Unavailable(f"dtype {dtype} (the C++ kernels support float32 and float64)")
        if any(t.device.type != "cpu" for t in tensors):
            return Unavailable("tensors not on the CPU")
        if any(t.dtype != dtype for t in tensors):
            return Unavailable("inputs of different dtypes")
        return LIBRARY.unavailable()

    def _forward_cpu(
        self,
        positions: torch.Tensor,
        quats: torch.Tensor,
        scales: torch.Tensor,
        attributes: dict[str, torch.Tensor],
        camera_position: torch.Tensor,
        light_position: torch.Tensor,
        intensity: torch.Tensor,
        terms: frozenset[str],
        coarse_visibility: torch.Tensor | None,
    ) -> Components:
        """`forward` with the fused C++ kernels: geometry, then the two networks (torch), then the
        combination."""
        if "shadow" in terms and coarse_visibility is None:
            raise ValueError("the shadow term needs the coarse light-view visibility")
        cfg = self.config
        learned = cfg.shading_frame == "learned"
        wi, wo, frames, inv_dist2 = shading_geometry(
            positions,
            attributes["shading_quat"] if learned else quats,
            None if learned else scales,
            camera_position,
            light_position,
            cfg.orient_normals,
        )
        ones = positions.new_ones(positions.shape[0], 1)
        inputs: dict[str, torch.Tensor] = {}
        if "specular" in terms:
            # The lobe frames are ASGMixture.frames() = quat_to_rotmat(rotation), here in C++ as one
            # autograd node (the reference's ~60 tiny ops on 8 quaternions cost more than all the
            # per-Gaussian shading).
            lam, mu = self.asg.log_sharpness.exp().unbind(-1)
            inputs.update(
                specular=attributes["specular"],
                asg_weights=attributes["asg_weights"],
                lobe_axes=rotations_cpu(self.asg.rotation),
                lam=lam,
                mu=mu,
            )
        if "sss" in terms:
            profile = self.sss_net(positions, wo, wi, frames[:, :, 2], attributes["material"])
            inputs.update(sss=attributes["sss"], profile=profile)
        shadow, coarse = ones, ones
        if "shadow" in terms:
            coarse = coarse_visibility[:, None].to(positions.dtype)
            shadow = self.shadow_net(positions, wi, coarse, attributes["material"])
            inputs["shadow"] = shadow
        colour, diffuse, specular, sss = shading_combine(
            wi,
            wo,
            frames,
            inv_dist2,
            intensity,
            attributes["diffuse"],
            **inputs,
            diffuse_cosine=cfg.diffuse_cosine,
            fresnel_f0=cfg.fresnel_f0,
            shadow_on_sss=cfg.shadow_on_sss,
        )
        return Components(colour, diffuse, specular, sss, shadow, coarse)
