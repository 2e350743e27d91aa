"""C++ kernels of SSD-GS's per-Gaussian shading (``methods/ssdgs/csrc/shading.cpp``), called through
ctypes.

`Shader.forward` (backend "auto" or "cpu") runs its closed-form parts as two fused kernels with
hand-written backwards; the two networks Θ_SSS and Θ_shad stay torch modules called between them:

* `shading_geometry`: positions, frame quaternions (and scales) and the camera / light positions ->
  ``wi``, ``wo``, the shading frames and ``1 / d²``;
* `shading_combine`: those, the intensity, the raw per-Gaussian colours and ASG weights, the ASG
  lobes, the SSS profile and the shadow -> colour, diffuse, specular and sss
  (all including ``I / d²``);
* `rotations_cpu`: ``quat_to_rotmat`` as one autograd node, for the ASG lobe frames.

They reproduce the torch code of `shader`, `shading` and `specular` (ASG form "xu" only) up to
rounding, including its gradient conventions at clamps, ties and normalisations, and give the same
results for any number of threads. CPU float32/float64 tensors of one dtype. The kernels are
SSD-GS's own native library, ``LIBRARY`` (built on first use by ``olatbench._native``). It includes
the Gaussian core's ``rotation.h`` but none of its sources: editing ``shading.cpp`` rebuilds this
library only, editing ``rotation.h`` both.
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import torch
from torch.autograd.function import once_differentiable

from olatbench._native import NativeLibrary, Signature, per_float
from olatbench._native.tensors import float_suffix, pointer, thread_count
from olatbench.gaussians.backends.cpu import CSRC as GAUSSIAN_CSRC

# a pointer (tensor data or NULL), int, int64_t
_P, _INT, _I64 = ctypes.c_void_p, ctypes.c_int, ctypes.c_int64
# OLATBENCH_SHADING_COMBINE_ARGS: wi, wo, frames, inv_dist2, intensity, diffuse, specular,
# asg_weights, lobe_axes, lam, mu, num_lobes, sss, profile, profile_channels, shadow, n,
# smooth_cosine, shadow_on_sss, f0, threads.
_COMBINE_ARGS = (*(_P,) * 11, _INT, _P, _P, _INT, _P, _I64, _INT, _INT, ctypes.c_double, _INT)


def _symbols(suffix: str, real: type) -> dict[str, Signature]:
    """The exported functions of ``csrc/shading.cpp`` for one float type
    (its ``OLATBENCH_SHADING_DEFINE``)."""
    return {
        # quats, n -> rotations; quats, n, grad rotations -> grad quats
        f"olatbench_shading_rotations_forward_{suffix}": Signature(None, (_P, _I64, _P)),
        f"olatbench_shading_rotations_backward_{suffix}": Signature(None, (_P, _I64, _P, _P)),
        # positions, quats, scales, camera, light, n, orient, threads -> wi, wo, frames, inv_dist2
        f"olatbench_shading_geometry_forward_{suffix}": Signature(
            None, (*(_P,) * 5, _I64, _INT, _INT, *(_P,) * 4)
        ),
        # ... as forward, grads of wi, wo, frames, inv_dist2 -> grads of positions, quats, camera,
        # light
        f"olatbench_shading_geometry_backward_{suffix}": Signature(
            None, (*(_P,) * 5, _I64, _INT, _INT, *(_P,) * 8)
        ),
        # combine args -> colour, diffuse, specular, sss, cache
        f"olatbench_shading_combine_forward_{suffix}": Signature(
            None, (*_COMBINE_ARGS, *(_P,) * 5)
        ),
        # combine args, cache, grads of colour, diffuse, specular, sss -> grads of the 14 tensor
        # inputs
        f"olatbench_shading_combine_backward_{suffix}": Signature(
            None, (*_COMBINE_ARGS, *(_P,) * 19)
        ),
    }


CSRC = Path(__file__).with_name("csrc")
LIBRARY = NativeLibrary(
    "olatbench_ssdgs_shading",
    [CSRC / "shading.cpp"],
    per_float(_symbols),
    # for rotation.h (quaternion -> rotation matrix)
    include_dirs=[GAUSSIAN_CSRC],
)


def _suffix(dtype: torch.dtype) -> str:
    return float_suffix(dtype, "the cpu shading kernels")


def _contiguous(t: torch.Tensor | None) -> torch.Tensor | None:
    """C-contiguous (device and dtype are checked by the public functions; output gradients share
    them)."""
    return None if t is None else t.contiguous()


class _GeometryCPU(torch.autograd.Function):
    """(positions (K,3), frame_quats (K,4), scales (K,3) | None, camera (3,), light (3,), orient,
    threads) -> (wi (K,3), wo (K,3), frames (K,3,3), inv_dist2 (K,1)); gradients for positions,
    frame_quats, camera, light."""

    @staticmethod
    def forward(
        ctx, positions, frame_quats, scales, camera_position, light_position, orient, threads
    ):
        dtype, n = positions.dtype, positions.shape[0]
        suffix = _suffix(dtype)
        inputs = [
            _contiguous(t)
            for t in (positions, frame_quats, scales, camera_position, light_position)
        ]
        wi, wo = torch.empty(n, 3, dtype=dtype), torch.empty(n, 3, dtype=dtype)
        frames, inv_dist2 = torch.empty(n, 3, 3, dtype=dtype), torch.empty(n, 1, dtype=dtype)
        LIBRARY.load()[f"olatbench_shading_geometry_forward_{suffix}"](
            *map(pointer, inputs), n, int(orient), threads,
            pointer(wi), pointer(wo), pointer(frames), pointer(inv_dist2),
        )  # fmt: skip
        ctx.save_for_backward(*inputs)
        ctx.orient, ctx.threads = orient, threads
        # unused outputs get None gradients (passed to the kernel as null)
        ctx.set_materialize_grads(False)
        return wi, wo, frames, inv_dist2

    @staticmethod
    @once_differentiable
    def backward(ctx, g_wi, g_wo, g_frames, g_inv):
        inputs = ctx.saved_tensors
        positions, frame_quats = inputs[0], inputs[1]
        dtype, n = positions.dtype, positions.shape[0]
        grads = [_contiguous(g) for g in (g_wi, g_wo, g_frames, g_inv)]
        out = [
            torch.empty_like(positions),
            torch.empty_like(frame_quats),
            torch.empty(3, dtype=dtype),
            torch.empty(3, dtype=dtype),
        ]
        LIBRARY.load()[f"olatbench_shading_geometry_backward_{_suffix(dtype)}"](
            *map(pointer, inputs), n, int(ctx.orient), ctx.threads,
            *map(pointer, grads), *map(pointer, out),
        )  # fmt: skip
        grad_positions, grad_quats, grad_camera, grad_light = out
        # No gradient (None, as autograd gives) where none can flow: the camera reaches the outputs
        # only through wo, the quaternions only through the frames, the light only through wi and
        # 1/d².
        return (
            grad_positions,
            None if g_frames is None else grad_quats,
            None,
            None if g_wo is None else grad_camera,
            None if g_wi is None and g_inv is None else grad_light,
            None,
            None,
        )


class _RotationsCPU(torch.autograd.Function):
    """quats (N,4) wxyz, any norm -> rotation matrices (N,3,3), as ``projection.quat_to_rotmat``."""

    @staticmethod
    def forward(ctx, quats):
        quats = quats.contiguous()
        out = torch.empty(quats.shape[0], 3, 3, dtype=quats.dtype)
        LIBRARY.load()[f"olatbench_shading_rotations_forward_{_suffix(quats.dtype)}"](
            pointer(quats), quats.shape[0], pointer(out)
        )
        ctx.save_for_backward(quats)
        return out

    @staticmethod
    @once_differentiable
    def backward(ctx, grad_out):
        (quats,) = ctx.saved_tensors
        grad = torch.empty_like(quats)
        LIBRARY.load()[f"olatbench_shading_rotations_backward_{_suffix(quats.dtype)}"](
            pointer(quats), quats.shape[0], pointer(grad_out.contiguous()), pointer(grad)
        )
        return grad


# The combine kernel's tensor inputs, in the order of the C functions' pointer arguments.
_COMBINE_TENSORS = (
    "wi",
    "wo",
    "frames",
    "inv_dist2",
    "intensity",
    "diffuse",
    "specular",
    "asg_weights",
    "lobe_axes",
    "lam",
    "mu",
    "sss",
    "profile",
    "shadow",
)


class _CombineCPU(torch.autograd.Function):
    """The 14 tensors of ``_COMBINE_TENSORS`` (None for the inputs of a term that is off), then
    smooth_cosine, fresnel_f0, shadow_on_sss, threads -> (colour, diffuse, specular, sss), each
    (K,3). All four outputs are differentiable; the gradient of every tensor input is returned, None
    for those of a term that is off and for wo without the specular term (it only enters the half
    vector)."""

    @staticmethod
    def forward(ctx, *args):
        tensors, (smooth_cosine, fresnel_f0, shadow_on_sss, threads) = args[:14], args[14:]
        dtype, n = tensors[0].dtype, tensors[0].shape[0]
        suffix = _suffix(dtype)
        tensors = [_contiguous(t) for t in tensors]
        out = [torch.empty(n, 3, dtype=dtype) for _ in range(4)]
        ctx.scalars = _combine_scalars(
            tensors, n, smooth_cosine, fresnel_f0, shadow_on_sss, threads
        )
        # Softplus values and derivatives and the lobe exponentials, saved for the backward
        # (csrc CacheLayout).
        cache = torch.empty(n * (18 + 3 * ctx.scalars["num_lobes"]), dtype=dtype)
        LIBRARY.load()[f"olatbench_shading_combine_forward_{suffix}"](
            *_combine_arguments(tensors, ctx.scalars), *map(pointer, out), pointer(cache)
        )
        ctx.save_for_backward(cache, *tensors)
        # unused outputs get None gradients (passed to the kernel as null)
        ctx.set_materialize_grads(False)
        return tuple(out)

    @staticmethod
    @once_differentiable
    def backward(ctx, *grad_outputs):
        cache, *tensors = ctx.saved_tensors
        dtype = cache.dtype
        grads_in = [_contiguous(g) for g in grad_outputs]
        # Gradient buffers shaped like each present input (the kernel writes all of them).
        out = [None if t is None else torch.empty_like(t) for t in tensors]
        LIBRARY.load()[f"olatbench_shading_combine_backward_{_suffix(dtype)}"](
            *_combine_arguments(tensors, ctx.scalars),
            pointer(cache),
            *map(pointer, grads_in),
            *map(pointer, out),
        )
        if tensors[_COMBINE_TENSORS.index("specular")] is None:
            out[_COMBINE_TENSORS.index("wo")] = None
        return (*out, None, None, None, None)


def _combine_scalars(
    tensors: list[torch.Tensor | None],
    n: int,
    smooth_cosine: bool,
    fresnel_f0: float,
    shadow_on_sss: bool,
    threads: int,
) -> dict[str, int | float]:
    names = dict(zip(_COMBINE_TENSORS, tensors, strict=True))
    num_lobes = names["asg_weights"].shape[1] if names["asg_weights"] is not None else 0
    profile_channels = names["profile"].shape[1] if names["profile"] is not None else 1
    return {
        "num_lobes": num_lobes,
        "profile_channels": profile_channels,
        "n": n,
        "smooth_cosine": int(smooth_cosine),
        "shadow_on_sss": int(shadow_on_sss),
        "f0": float(fresnel_f0),
        "threads": threads,
    }


def _combine_arguments(
    tensors: list[torch.Tensor | None], scalars: dict[str, int | float]
) -> list[object]:
    """The shared leading arguments of the combine forward and backward
    (OLATBENCH_SHADING_COMBINE_ARGS)."""
    p = [pointer(t) for t in tensors]
    s = scalars
    return [
        *p[:11],
        s["num_lobes"],
        p[11],
        p[12],
        s["profile_channels"],
        p[13],
        s["n"],
        s["smooth_cosine"],
        s["shadow_on_sss"],
        s["f0"],
        s["threads"],
    ]


def _check(
    tensors: dict[str, tuple[torch.Tensor | None, tuple[int, ...]]], dtype: torch.dtype
) -> None:
    """Each given (tensor, expected shape) is a CPU tensor of ``dtype`` and that shape
    (the kernels index by it)."""
    _suffix(dtype)
    for name, (t, shape) in tensors.items():
        if t is None:
            continue
        if t.device.type != "cpu":
            raise ValueError(f"the cpu shading kernels need CPU tensors; {name} is on {t.device}")
        if t.dtype != dtype:
            raise TypeError(
                f"the cpu shading kernels need one dtype; {name} is {t.dtype}, not {dtype}"
            )
        if tuple(t.shape) != shape:
            raise ValueError(
                f"the cpu shading kernels need {name} of shape {shape}, got {tuple(t.shape)}"
            )


def shading_geometry(
    positions: torch.Tensor,
    frame_quats: torch.Tensor,
    scales: torch.Tensor | None,
    camera_position: torch.Tensor,
    light_position: torch.Tensor,
    orient_normals: bool,
    threads: int | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Directions, shading frames and inverse squared light distance of K Gaussians.

    ``positions`` (K,3) world; ``frame_quats`` (K,4) wxyz, any norm (the Gaussians' quaternions for
    the "min_scale" frame, the ``shading_quat`` attribute for "learned"); ``scales`` (K,3) for
    "min_scale" (only its argmin is used, no gradient) or None for "learned" (the frame is the
    quaternion's rotation); ``camera_position``, ``light_position`` (3,). Returns ``wi`` (K,3) =
    normalised L - p (via rsqrt of max(d², 1e-12)), ``wo`` (K,3) = ``safe_normalize(c - p)``,
    ``frames`` (K,3,3) (columns x, y, z = normal, as ``min_scale_frames``; with ``orient_normals`` x
    and z are negated where z·wo < 0, as ``orient_frames``) and ``inv_dist2`` (K,1) = 1 /
    max(d², 1e-12). Differentiable w.r.t. every tensor but ``scales``."""
    k = positions.shape[0]
    _check(
        {
            "positions": (positions, (k, 3)),
            "frame_quats": (frame_quats, (k, 4)),
            "scales": (scales, (k, 3)),
            "camera_position": (camera_position, (3,)),
            "light_position": (light_position, (3,)),
        },
        positions.dtype,
    )
    return _GeometryCPU.apply(
        positions,
        frame_quats,
        scales,
        camera_position,
        light_position,
        bool(orient_normals),
        thread_count(threads),
    )


def rotations_cpu(quats: torch.Tensor) -> torch.Tensor:
    """``projection.quat_to_rotmat`` as one autograd node: (N,4) wxyz quaternions
    (normalised here, no eps) -> (N,3,3) rotation matrices. For the few ASG lobe frames, where the
    ~60 tiny torch ops of the reference cost far more than the arithmetic."""
    _check({"quats": (quats, (quats.shape[0], 4))}, quats.dtype)
    return _RotationsCPU.apply(quats)


def shading_combine(
    wi: torch.Tensor,
    wo: torch.Tensor,
    frames: torch.Tensor,
    inv_dist2: torch.Tensor,
    intensity: torch.Tensor,
    diffuse: torch.Tensor,
    *,
    specular: torch.Tensor | None = None,
    asg_weights: torch.Tensor | None = None,
    lobe_axes: torch.Tensor | None = None,
    lam: torch.Tensor | None = None,
    mu: torch.Tensor | None = None,
    sss: torch.Tensor | None = None,
    profile: torch.Tensor | None = None,
    shadow: torch.Tensor | None = None,
    diffuse_cosine: str = "smooth",
    fresnel_f0: float = 0.04,
    shadow_on_sss: bool = False,
    threads: int | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """The colour components of K Gaussians, as `Shader.forward` computes them from its intermediate
    values.

    ``wi``, ``wo`` (K,3), ``frames`` (K,3,3), ``inv_dist2`` (K,1) from `shading_geometry`;
    ``intensity`` (3,); raw (pre-softplus) per-Gaussian ``diffuse`` (K,3). Specular term (on when
    ``specular`` is given): raw ``specular`` (K,3) and ``asg_weights`` (K,N), the lobe frames
    ``lobe_axes`` (N,3,3) (`ASGMixture.frames`) and sharpness ``lam``, ``mu`` (N,)
    (exp of ``log_sharpness``), ASG form "xu". SSS term (on when ``sss`` is given): raw ``sss``
    (K,3) and the Θ_SSS ``profile`` (K,1) or (K,3). Shadow (on when given): S (K,1).
    ``diffuse_cosine`` "smooth" or "clamped"; ``shadow_on_sss``: S multiplies the sss term too.

    Returns ``(colour, diffuse, specular, sss)``, each (K,3) and including ``I / d²`` (zeros for a
    term that is off). All four are differentiable (gradients of any combination of them are
    supported) w.r.t. every tensor input; the inputs of a term that is off get no gradient."""
    if diffuse_cosine not in ("smooth", "clamped"):
        raise ValueError(f"diffuse_cosine must be 'clamped' or 'smooth', not {diffuse_cosine!r}")
    spec = (specular, asg_weights, lobe_axes, lam, mu)
    if any(t is None for t in spec) and any(t is not None for t in spec):
        raise ValueError(
            "the specular term needs specular, asg_weights, lobe_axes, lam and mu together"
        )
    if (sss is None) != (profile is None):
        raise ValueError("the sss term needs sss and profile together")
    k, n_lobes = wi.shape[0], 0 if asg_weights is None else asg_weights.shape[-1]
    channels = 1 if profile is None or profile.dim() != 2 else profile.shape[1]
    if channels not in (1, 3):
        raise ValueError(f"the SSS profile must be (K, 1) or (K, 3), got {tuple(profile.shape)}")
    tensors = (wi, wo, frames, inv_dist2, intensity, diffuse, *spec, sss, profile, shadow)
    shapes = (
        (k, 3),
        (k, 3),
        (k, 3, 3),
        (k, 1),
        (3,),
        (k, 3),
        (k, 3),
        (k, n_lobes),
        (n_lobes, 3, 3),
        (n_lobes,),
        (n_lobes,),
        (k, 3),
        (k, channels),
        (k, 1),
    )
    _check(dict(zip(_COMBINE_TENSORS, zip(tensors, shapes, strict=True), strict=True)), wi.dtype)
    return _CombineCPU.apply(
        *tensors,
        diffuse_cosine == "smooth",
        float(fresnel_f0),
        bool(shadow_on_sss),
        thread_count(threads),
    )


__all__ = ["rotations_cpu", "shading_combine", "shading_geometry"]
