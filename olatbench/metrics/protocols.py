"""Named, versioned metric protocols: the exact recipe that turns (prediction, ground truth) into
numbers.

Numbers from different papers differ mostly through the recipe, not the method: 8-bit quantisation
(rounding vs truncation), the SSIM window border (valid region vs zero padding), the LPIPS backbone
(AlexNet vs VGG) and its input range ([-1, 1] vs the [0, 1] mistake of the 3DGS evaluation script).
Every result stores the protocol ``id`` and ``version``; a change of recipe is a new version.

>>> from olatbench.metrics.protocols import get_protocol
>>> protocol = get_protocol("olatbench-v1")
>>> values = protocol.evaluate(pred, gt)          # float32 (H, W, 3) sRGB in [0, 1]
>>> values["psnr"], values["ssim"], values["lpips"]
"""

from __future__ import annotations

import math
import sys
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from olatbench.datasets.colour import dequantize_8bit, quantize_8bit
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.formats import display_colourspace
from olatbench.datasets.official import official_ground_truth
from olatbench.datasets.records import Frame
from olatbench.metrics.registry import MetricBatch, find_metric, get_metric, metric_names
from olatbench.names import did_you_mean, match_name
from olatbench.progress import progress_bar

if TYPE_CHECKING:
    import torch

PSNR_MSE_FLOOR = 1e-10  # identical images score 100 dB instead of +inf (JSON has no infinity)
_WARNED: set[str] = set()


@dataclass(frozen=True)
class Protocol:
    """One metric recipe. ``evaluate`` takes float (H, W, 3) images with values in [0, 1], both in
    the colour space of the data (`olatbench.datasets.formats.display_colourspace`: sRGB, or gamma
    2.2 for GS³ EXRs); the space is the data's, not the protocol's, so the runner and
    ``olatbench evaluate`` always agree."""

    id: str
    version: int
    description: str
    reproduces: str
    quantize: str | None = "round"  # "round" | "truncate" | None (float images)
    ssim_variant: str = "wang"  # see olatbench.metrics.ssim
    lpips_nets: tuple[str, ...] = ("alex", "vgg")
    lpips_primary: str = "alex"
    # True: feed [0, 1] to the [-1, 1] network (3DGS mistake)
    lpips_unit_range_compat: bool = False
    masked: bool = False
    # True: the ground truth's alpha reaches the metrics as batch.alpha
    object_mask: bool = False
    #                                          (psnr_si fits there) without weighting psnr, ssim,
    #                                          lpips (masked does)
    # "frame": Frame.load(data's space, official background);
    ground_truth: str = "frame"
    #                                          "official": the official loader's image
    #                                          (olatbench.datasets.official)
    steps: tuple[str, ...] = field(default=())
    # execution only: values agree to ~1e-7
    lpips_backend: str = field(default="auto", compare=False)
    # the registered metrics it reports, in order (`olatbench.metrics.registry`); () for the
    # standard list
    metric_names: tuple[str, ...] = ()

    @property
    def metrics(self) -> tuple[str, ...]:
        """Keys of ``evaluate``'s result: ``metric_names``, or by default psnr, ssim, lpips
        (primary) and lpips_<net> when several nets."""
        if self.metric_names:
            return self.metric_names
        extra = tuple(f"lpips_{net}" for net in self.lpips_nets) if len(self.lpips_nets) > 1 else ()
        return ("psnr", "ssim", "lpips", *extra)

    def definition(self) -> dict:
        """JSON-able exact definition (stored in results and printed by
        ``olatbench metrics explain``)."""
        data = asdict(self)
        data.pop("lpips_backend")  # how LPIPS is executed, not what it computes
        data.pop("metric_names")  # the list is "metrics", below
        data["metrics"] = list(self.metrics)
        data["steps"] = list(self.steps)
        data["lpips_nets"] = list(self.lpips_nets)
        data["psnr_mse_floor"] = PSNR_MSE_FLOOR
        return data

    # --- preprocessing ----------------------------------------------------------------------------
    def prepare(self, image: np.ndarray | torch.Tensor, name: str) -> np.ndarray:
        """Check (H, W, 3) float finite, clip to [0, 1], quantise to 8 bit as the protocol says ->
        float32."""
        array = image.detach().cpu().numpy() if _is_tensor(image) else np.asarray(image)
        if array.ndim != 3 or array.shape[-1] != 3:
            raise ValueError(f"{name}: expected an (H, W, 3) image, found shape {array.shape}")
        if not np.issubdtype(array.dtype, np.floating):
            raise TypeError(f"{name}: expected float values in [0, 1], found dtype {array.dtype}")
        if not np.isfinite(array).all():
            raise ValueError(f"{name}: contains NaN or Inf values")
        array = np.clip(array.astype(np.float32), 0.0, 1.0)
        if self.quantize is not None:
            array = dequantize_8bit(quantize_8bit(array, mode=self.quantize))
        return array

    def load_ground_truth(
        self, frame: Frame, scene_format: str, resolution: tuple[int, int] | None = None
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Ground truth of ``frame`` as this protocol scores it: (rgb (H, W, 3) float32, mask (H, W)
        or None), in the format's display space (`olatbench.datasets.formats.display_colourspace`).

        ``resolution`` (width, height) resizes with area averaging
        (not with ``ground_truth="official"``).
        """
        space = display_colourspace(scene_format)
        mask = None
        if self.masked:
            mask = frame.load(colourspace=space, background=None, resolution=resolution).alpha
            if mask is None:
                raise DatasetError(
                    f"protocol {self.id} needs an alpha mask but the image has none",
                    path=frame.image_path,
                    frame=frame.frame_id,
                )
        if self.ground_truth == "official":
            if resolution is not None:
                raise ValueError(
                    f"protocol {self.id} scores the official ground truth at its native resolution"
                )
            return official_ground_truth(frame, scene_format), mask
        return frame.load(colourspace=space, background="official", resolution=resolution).rgb, mask

    # --- evaluation -------------------------------------------------------------------------------
    def lpips_available(self) -> bool:
        """True when the weights of every LPIPS network of this protocol are installed."""
        from olatbench.metrics.weights import WeightsError

        try:
            self.require_lpips()
        except WeightsError:
            return False
        return True

    def require_lpips(self) -> None:
        """Raise ``WeightsError`` (with install instructions) unless LPIPS can be computed."""
        from olatbench.metrics.lpips import get_runner

        for net in self.lpips_nets:
            get_runner(net, backend="torch")

    def lpips_batch(
        self, pred: torch.Tensor, gt: torch.Tensor, mask: torch.Tensor | None, device: str
    ) -> dict[str, list[float | None]]:
        """LPIPS of (B, 3, H, W) images per network of ``lpips_nets`` (None per image where its
        weights are not installed, with a warning once per network); the ``lpips`` metrics read it
        (`olatbench.metrics.lpips`)."""
        import torch

        from olatbench.metrics.lpips import get_runner, lpips_nchw
        from olatbench.metrics.weights import INSTALL_HINT, WeightsError

        out: dict[str, list[float | None]] = {}
        for net in self.lpips_nets:
            try:
                model = get_runner(net, None, device, self.lpips_backend)
            except WeightsError:
                if net not in _WARNED:
                    _WARNED.add(net)
                    warnings.warn(f"LPIPS-{net} is reported as None: {INSTALL_HINT}", stacklevel=3)
                out[net] = [None] * pred.shape[0]
                continue
            with torch.no_grad():
                values = lpips_nchw(model, pred, gt, mask, self.lpips_unit_range_compat)
            out[net] = [float(v) for v in values]
        return out

    def _evaluate_batch(
        self,
        preds: list[np.ndarray],
        gts: list[np.ndarray],
        masks: list[np.ndarray | None],
        device: str,
    ) -> list[dict[str, float | None]]:
        # the metric kernels load only when scoring: plans and protocol listings stay torch-free
        import torch

        pred = torch.from_numpy(np.stack(preds)).permute(0, 3, 1, 2).to(device)
        gt = torch.from_numpy(np.stack(gts)).permute(0, 3, 1, 2).to(device)
        alpha = None
        if self.masked or self.object_mask:
            alpha = torch.from_numpy(np.stack(masks).astype(np.float32))[:, None].to(device)
        batch = MetricBatch(pred, gt, alpha if self.masked else None, device, alpha=alpha)
        with torch.no_grad():
            columns = {name: get_metric(name).load()(batch, self) for name in self.metrics}
        return [{name: columns[name][i] for name in self.metrics} for i in range(len(preds))]

    def _mask(
        self, mask: np.ndarray | torch.Tensor | None, shape: tuple[int, ...], index: int
    ) -> np.ndarray | None:
        if not (self.masked or self.object_mask):
            return None
        if mask is None:
            raise ValueError(
                f"protocol {self.id} needs a mask for every image (image {index} has none)"
            )
        m = mask.detach().cpu().numpy() if _is_tensor(mask) else np.asarray(mask, dtype=np.float32)
        m = m[..., 0] if m.ndim == 3 else m
        if m.shape != shape[:2]:
            raise ValueError(
                f"mask of image {index}: shape {m.shape} does not match the image's {shape[:2]}"
            )
        if not (m > 0).any():
            raise ValueError(f"mask of image {index} is empty")
        return np.clip(m, 0.0, 1.0).astype(np.float32)

    def evaluate(
        self, pred: np.ndarray, gt: np.ndarray, mask: np.ndarray | None = None, device: str = "cpu"
    ) -> dict[str, float | None]:
        """Metrics of one image pair: float32 (H, W, 3) in [0, 1] in the data's space; mask (H, W)
        if masked or object_mask."""
        return self.evaluate_many([(pred, gt, mask)], device=device)[0]

    def evaluate_many(
        self,
        pairs: Iterable[Sequence],
        progress: bool = False,
        batch_size: int = 4,
        device: str = "cpu",
        total: int | None = None,
    ) -> list[dict[str, float | None]]:
        """Metrics of many ``(pred, gt)`` or ``(pred, gt, mask)`` pairs, batched by equal image
        size."""
        results: list[dict[str, float | None]] = []
        pending: tuple[list, list, list] = ([], [], [])

        def flush() -> None:
            if pending[0]:
                results.extend(self._evaluate_batch(*pending, device=device))
                for items in pending:
                    items.clear()

        if total is None and hasattr(pairs, "__len__"):
            total = len(pairs)  # type: ignore[arg-type]
        for index, pair in enumerate(
            progress_bar(
                pairs, total=total, disable=not progress, desc=f"metrics {self.id}", unit="img"
            )
        ):
            if len(pair) not in (2, 3):
                raise ValueError(f"pair {index}: expected (pred, gt) or (pred, gt, mask)")
            pred, gt = self.prepare(pair[0], f"pred {index}"), self.prepare(pair[1], f"gt {index}")
            if pred.shape != gt.shape:
                raise ValueError(f"pair {index}: pred shape {pred.shape} != gt shape {gt.shape}")
            mask = self._mask(pair[2] if len(pair) == 3 else None, pred.shape, index)
            if pending[0] and (pending[0][0].shape != pred.shape or len(pending[0]) >= batch_size):
                flush()
            pending[0].append(pred)
            pending[1].append(gt)
            pending[2].append(mask)
        flush()
        return results

    def mean(self, per_image: list[dict[str, float | None]]) -> dict[str, float | None]:
        """Mean over images per metric; a metric that is None for any image is None in the mean."""
        if not per_image:
            raise ValueError("no per-image results to average")
        out: dict[str, float | None] = {}
        for key in self.metrics:
            values = [row.get(key) for row in per_image]
            out[key] = None if any(v is None for v in values) else math.fsum(values) / len(values)  # type: ignore
        return out


_PROTOCOLS: dict[str, Protocol] = {}


def _is_tensor(value: object) -> bool:
    """Whether ``value`` is a torch tensor, without importing torch (a tensor exists only once torch
    is loaded)."""
    torch = sys.modules.get("torch")
    return torch is not None and isinstance(value, torch.Tensor)


def register_protocol(protocol: Protocol) -> Protocol:
    """Add a protocol to the registry (ids are unique; every metric it lists is registered)."""
    if protocol.id in _PROTOCOLS:
        raise ValueError(f"protocol {protocol.id!r} is already registered")
    unknown = [name for name in protocol.metrics if find_metric(name) is None]
    if unknown:
        raise ValueError(
            f"protocol {protocol.id!r} lists unregistered metrics {unknown}; known: "
            f"{', '.join(metric_names())} (olatbench.metrics.registry.register_metric)"
        )
    _PROTOCOLS[protocol.id] = protocol
    return protocol


def get_protocol(name: str) -> Protocol:
    """The protocol called ``name`` (ignoring case where only one matches:
    `olatbench.names.match_name`); ``ValueError`` with a "did you mean" and the known names
    otherwise."""
    matched = match_name(name, _PROTOCOLS)
    if matched is None:
        raise ValueError(
            f"unknown metric protocol {name!r}{did_you_mean(name, _PROTOCOLS)}; known: "
            f"{', '.join(protocol_names())} (see `olatbench metrics list`)"
        )
    return _PROTOCOLS[matched]


def protocol_names() -> list[str]:
    """Registered protocol ids, sorted."""
    return sorted(_PROTOCOLS)


_V1_STEPS = (
    "inputs: float (H, W, 3) sRGB-encoded images (the benchmark's evaluation space), composited on "
    "the scene's official background",
    "clip both images to [0, 1]",
    "quantise both to 8 bit by rounding to nearest (numpy rint: ties to even) and divide by 255",
    "PSNR = 10 log10(1 / MSE), MSE over all pixels and channels of the image (peak fixed at 1; "
    "MSE floored at 1e-10, i.e. at most 100 dB)",
    "SSIM: Wang et al. 2004, 11×11 Gaussian window σ = 1.5, K1 = 0.01, K2 = 0.03, data range 1, "
    "population covariance, mean over the valid region (no padding) and the channels = "
    "scikit-image structural_similarity(gaussian_weights=True, sigma=1.5, "
    "use_sample_covariance=False, data_range=1)",
    "LPIPS v0.1 (linear heads) on inputs mapped to [-1, 1] (2x - 1), AlexNet (lpips = lpips_alex) "
    "and VGG16 (lpips_vgg), spatial average; = lpips.LPIPS(net=..., version='0.1')(x, y, "
    "normalize=True)",
    "split score: arithmetic mean of the per-image values",
)

register_protocol(
    Protocol(
        id="olatbench-v1",
        version=1,
        description=(
            "olatbench's default: 8-bit rounded sRGB, PSNR, Wang SSIM (valid region), LPIPS "
            "alex+vgg on [-1, 1]."
        ),
        reproduces="the standard definitions (scikit-image SSIM, the lpips package)",
        steps=_V1_STEPS,
    )
)

register_protocol(
    Protocol(
        id="olatbench-v1-masked",
        version=1,
        description="olatbench-v1 restricted to a foreground mask (object pixels only).",
        reproduces="olatbench-v1 with the metrics weighted by the mask",
        masked=True,
        steps=(
            *_V1_STEPS[:3],
            "mask (H, W) in [0, 1] (the ground truth's alpha): PSNR's MSE is the mask-weighted "
            "mean over pixels",
            "SSIM: the Wang SSIM map (valid region) averaged with the mask (cropped to the valid "
            "region) as weight",
            "LPIPS: both images multiplied by the mask (composited on black) before the network",
            _V1_STEPS[-1],
        ),
    )
)

register_protocol(
    Protocol(
        id="ssdgs",
        version=1,
        description="As SSD-GS's official render.py + metrics.py (3DGS scripts): 8-bit PNGs, 3DGS "
        "SSIM, LPIPS-vgg on [0, 1].",
        reproduces="SSD-GS / 3DGS metrics.py: torchvision.utils.save_image PNGs, "
        "utils/loss_utils.ssim, lpipsPyTorch.lpips(net_type='vgg')",
        quantize="round",
        ssim_variant="3dgs",
        lpips_nets=("vgg",),
        lpips_primary="vgg",
        lpips_unit_range_compat=True,
        ground_truth="official",
        steps=(
            "inputs: float (H, W, 3) images in the space the official method trains in (sRGB for "
            "NRHints and SSS-GS data, gamma-2.2 encoded for GS³ EXRs); the ground truth is the "
            "official loader's image (olatbench.datasets.official, on the scene's background: "
            "NRHints PNGs composited on black (real captures; white for NRHints' synthetic "
            "scenes) and TRUNCATED to 8 bit by the GS³/SSD-GS loader; GS³ composited on white, "
            "gamma 2.2, 8 bit; SSS-GS masked on black)",
            "clip to [0, 1] and quantise to 8 bit: torchvision save_image computes floor(255x + "
            "0.5) (ties up), olatbench rounds ties to even: identical except at exact .5 ties; no "
            "truncation in these scripts",
            "PSNR = 20 log10(1 / sqrt(MSE)) per image, MSE over pixels and channels",
            "SSIM: the 3DGS ssim(): 11×11 Gaussian window σ = 1.5, ZERO padding of 5 pixels, mean "
            "over the full map including the borders (higher than Wang SSIM on images with dark "
            "borders)",
            "LPIPS: lpipsPyTorch VGG16 v0.1 heads fed the [0, 1] images directly (no 2x - 1): the "
            "3DGS mistake, kept here only to reproduce published SSD-GS/3DGS numbers",
            "split score: mean of the per-image values",
        ),
    )
)

register_protocol(
    Protocol(
        id="nrhints",
        version=1,
        description=(
            "As NRHints' utils/metrics.py: float renders, torchmetrics SSIM (data_range=1), "
            "LPIPS-alex."
        ),
        reproduces="NRHints utils/metrics.py: torchmetrics 1.0 peak_signal_noise_ratio / "
        "structural_similarity_index_measure (data_range=1.0), "
        "lpips.LPIPS(net='alex')(normalize=True)",
        quantize=None,
        ssim_variant="wang",
        lpips_nets=("alex",),
        lpips_primary="alex",
        steps=(
            "inputs: float (H, W, 3) sRGB images, NOT quantised (NRHints scores its float renders)",
            "clip to [0, 1]",
            "PSNR = 10 log10(1 / MSE) over pixels and channels",
            "SSIM: torchmetrics ≥ 1.0 with data_range=1: 11×11 Gaussian σ = 1.5, reflect padding "
            "then the padded border cropped = Wang SSIM on the valid region",
            "LPIPS-alex v0.1 on inputs mapped to [-1, 1] (normalize=True)",
            "split score: mean of the per-image values",
        ),
    )
)

register_protocol(
    Protocol(
        id="olatbench-v1-flip",
        version=1,
        description=(
            "olatbench-v1 and LDR-ꟻLIP (NVIDIA's perceptual error, mean over pixels; needs "
            "flip-evaluator)."
        ),
        reproduces="olatbench-v1, plus flip_evaluator.evaluate(gt, pred, 'LDR') of NVIDIA's ꟻLIP",
        metric_names=("psnr", "ssim", "lpips", "lpips_alex", "lpips_vgg", "flip"),
        steps=(
            *_V1_STEPS[:-1],
            "ꟻLIP: LDR-ꟻLIP of flip-evaluator >= 1.7 (Andersson et al. 2020) on the 8-bit images "
            "as sRGB, 67 pixels per degree: flip_evaluator.evaluate(gt, pred, 'LDR', "
            "inputsRGB=True, parameters={'ppd': 67}), mean error over pixels (0 = identical, "
            "lower is better); None when flip-evaluator is not installed",
            _V1_STEPS[-1],
        ),
    )
)

register_protocol(
    Protocol(
        id="olatbench-v1-novel-lights",
        version=1,
        description="Renders under novel illumination (docs/relighting.md): olatbench-v1 and the "
        "scale-invariant PSNR over the object (Stanford-ORB).",
        reproduces="olatbench-v1, plus Stanford-ORB's per-channel least-squares scale before PSNR",
        object_mask=True,
        metric_names=("psnr", "psnr_object", "psnr_si", "ssim", "lpips", "lpips_alex", "lpips_vgg"),
        steps=(
            "inputs: the render under the condition (the sum over its lights in linear light, "
            "olatbench.bench.relight.Relighter) and the ground truth rendered under it (linear "
            "RGB, straight alpha), each composited on the scene's official background in linear "
            "light and encoded to the space the suite's OLAT protocol scores in (sRGB for the "
            "NRHints-format suites such as mini)",
            *_V1_STEPS[1:-1],
            "psnr_object: PSNR over the ground truth's alpha m (object and ground, weights in [0, "
            "1]): MSE = Σ m (gt − pred)² / (3 Σ m), floored at 1e-10",
            "psnr_si: per image and channel c, over the ground truth's alpha m (object and ground, "
            "weights in [0, 1]), s_c = Σ m·gt·pred / Σ m·pred² on the 8-bit images of the steps "
            "above (1 where the render is black there); PSNR = 10 log10(1 / MSE), MSE = Σ m (gt − "
            "clip(s·pred, 0, 1))² / (3 Σ m), floored at 1e-10 (olatbench.metrics.scale_invariant)",
            "split score: arithmetic mean of the per-image values of a condition; the conditions' "
            "average is the mean of their means",
        ),
    )
)
