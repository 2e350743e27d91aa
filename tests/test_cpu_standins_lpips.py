"""The stand-ins of nrhints-official's device=cpu jobs: ``lpips``
(olatbench.methods.official.cpu_standins.lpips) against independent references — the ``lpips``
package's own numbers (lpips 0.1.4, recorded in tests/test_lpips.py: seeded random weights, and the
real weights) and olatbench's `lpips` on the same images in its channel-last layout — and its
refusals; ``Tensor.to`` under no_grad (cpu_standins.device_copy) against a real device move; and the
job environment of nrhints-official (only these on the path, not the other stand-ins nor the CUDA
device shim)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from test_cpu_standins import run_cpu_job
from test_lpips import EXPECTED, EXPECTED_REAL, SEED, images, needs_weights, seeded_state

from olatbench.methods.official.cpu_standins import (
    NRHINTS_SITE,
    OLATBENCH_ROOT,
    SITE,
    job_environment,
    standins_for,
)
from olatbench.methods.official.cpu_standins.lpips import LPIPS
from olatbench.metrics.lpips import clear_caches, lpips
from olatbench.metrics.weights import save_state


@pytest.fixture()
def seeded_alex(monkeypatch, tmp_path) -> Path:
    """The seeded random LPIPS-Alex weights of tests/test_lpips.py installed as the only weights
    (``OLATBENCH_WEIGHTS_DIR``); the LPIPS caches cleared before and after."""
    folder = tmp_path / "weights"
    save_state(
        seeded_state("alex", SEED, None), folder, "alex", {"source": "test_lpips.seeded_state"}
    )
    monkeypatch.setenv("OLATBENCH_WEIGHTS_DIR", str(folder))
    clear_caches()
    yield folder
    clear_caches()


def nrhints_call(rgb: torch.Tensor, rgb_gt: torch.Tensor) -> float:
    """NRHints' utils/metrics.py:18-24 with the stand-in: [H, W, 3] images in [0, 1] -> one
    float."""
    rgb = torch.moveaxis(rgb, -1, 0)[None, ...]
    rgb_gt = torch.moveaxis(rgb_gt, -1, 0)[None, ...]
    model = LPIPS(net="alex", verbose=False).cpu()
    return float(model(rgb, rgb_gt, normalize=True).item())


def test_standin_is_the_lpips_package_on_nchw_unit_images(seeded_alex):
    # (3, 64, 48, 3) images: H != W, so a stand-in reading the layout wrong gives other numbers
    # (or fails)
    a, b = images(SEED + 1, 3, 64, 48)
    # NHWC -> NCHW, as NRHints' moveaxis
    x, y = (torch.from_numpy(v).permute(0, 3, 1, 2) for v in (a, b))
    out = LPIPS(net="alex", verbose=False).cpu()(x, y, normalize=True)
    assert out.shape == (3, 1, 1, 1)  # lpips' [N, 1, 1, 1]
    # the lpips package's values (normalize=True: 2x - 1), and not those of the [0, 1] mistake
    np.testing.assert_allclose(
        out.flatten().numpy(), EXPECTED[("alex", "random", "unit")], rtol=1e-5, atol=1e-8
    )
    assert not np.allclose(out.flatten().numpy(), EXPECTED[("alex", "random", "raw01")], rtol=1e-2)
    # olatbench's lpips() on the same images in its own channel-last layout
    np.testing.assert_allclose(out.flatten().numpy(), lpips(a, b, net="alex"), rtol=1e-5, atol=1e-8)
    # the layout matters: the same pixels read as the transposed image give other distances
    swapped = LPIPS()(x.transpose(2, 3), y.transpose(2, 3), normalize=True).flatten().numpy()
    assert not np.allclose(swapped, EXPECTED[("alex", "random", "unit")], rtol=1e-3)


def test_standin_as_nrhints_calls_it(seeded_alex):
    a, b = images(SEED + 1, 3, 64, 48)
    # one [H, W, 3] view at a time, a new LPIPS each call, as utils/metrics.py
    for index in range(3):
        value = nrhints_call(torch.from_numpy(a[index]), torch.from_numpy(b[index]))
        assert value == pytest.approx(EXPECTED[("alex", "random", "unit")][index], rel=1e-5)
    assert nrhints_call(torch.from_numpy(a[0]), torch.from_numpy(a[0])) == pytest.approx(
        0.0, abs=1e-7
    )
    # no range guard, as lpips: a NeuS blend a rounding error above 1 is scored, not refused
    over = torch.from_numpy(a[0]).clone()
    over[0, 0] = 1 + 1e-5
    assert nrhints_call(over, torch.from_numpy(b[0])) == pytest.approx(
        EXPECTED[("alex", "random", "unit")][0], rel=1e-4
    )


@needs_weights
def test_standin_with_the_installed_weights_is_the_lpips_package():
    clear_caches()
    a, b = images(SEED + 2, 2, 96, 80)
    x, y = (torch.from_numpy(v).permute(0, 3, 1, 2) for v in (a, b))
    out = LPIPS(net="alex", verbose=False).cpu()(x, y, normalize=True).flatten().numpy()
    np.testing.assert_allclose(out, EXPECTED_REAL[("alex", "unit")], rtol=1e-5)
    np.testing.assert_allclose(out, lpips(a, b, net="alex"), rtol=1e-5)


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"net": "vgg"}, "net='vgg'"),
        ({"net": "squeeze"}, "net='squeeze'"),
        ({"spatial": True}, "spatial=True"),
        ({"pretrained": False}, "pretrained=False"),
        ({"version": "0.0"}, "version='0.0'"),
        ({"lpips": False}, "lpips=False"),
        ({"pnet_rand": True}, "pnet_rand=True"),
        ({"pnet_tune": True}, "pnet_tune=True"),
        ({"model_path": "x.pth"}, "model_path='x.pth'"),
        ({"eval_mode": False}, "eval_mode=False"),
    ],
)
def test_standin_refuses_what_nrhints_does_not_use(kwargs, named):
    with pytest.raises(
        NotImplementedError, match=rf"lpips stand-in .*LPIPS\({named}\) is not implemented"
    ):
        LPIPS(**kwargs)


def test_standin_refuses_other_calls_and_layouts():
    x = torch.rand(1, 3, 40, 40)
    model = LPIPS(net="alex", verbose=False)
    with pytest.raises(NotImplementedError, match=r"normalize=False\) .* is not implemented"):
        model(x, x)
    with pytest.raises(NotImplementedError, match="retPerLayer=True"):
        model(x, x, retPerLayer=True, normalize=True)
    with pytest.raises(ValueError, match=r"\[N, 3, H, W\] \(NCHW, RGB\), got \(1, 40, 40, 3\)"):
        model(x.permute(0, 2, 3, 1), x.permute(0, 2, 3, 1), normalize=True)  # NHWC
    with pytest.raises(ValueError, match=r"got \(3, 40, 40\)"):
        model(x[0], x[0], normalize=True)
    with pytest.raises(ValueError, match="differ in shape"):
        model(x, torch.rand(1, 3, 40, 48), normalize=True)


# ------------------------------------------------------------------------------- Tensor.to under
# no_grad
@pytest.fixture()
def device_copy():
    from olatbench.methods.official.cpu_standins import device_copy as module

    module.install()
    yield module
    module.uninstall()


def nrhints_normals(x: torch.Tensor) -> torch.Tensor:
    """fields/sdf_field.py:136-147 under get_eval_dicts' no_grad: d sdf / d x with
    create_graph=True."""
    net = torch.nn.Sequential(
        torch.nn.Linear(3, 16), torch.nn.Softplus(beta=100), torch.nn.Linear(16, 1)
    )
    x.requires_grad_(True)
    with torch.inference_mode(False), torch.enable_grad():
        y = net(x)
    return torch.autograd.grad(
        y, x, torch.ones_like(y), create_graph=True, retain_graph=True, only_inputs=True
    )[0]


def test_device_move_under_no_grad_drops_the_graph_as_a_real_copy(device_copy):
    with torch.no_grad():
        normals = nrhints_normals(torch.rand(8, 3))
        assert normals.grad_fn is not None  # the graph the CPU kept for every chunk
        kept = normals.to("cpu")
        # a real device move under no_grad (what .to('cpu') is on a GPU)
        real_copy = normals.to("meta")
        assert kept.grad_fn is None and real_copy.grad_fn is None and not kept.requires_grad
        assert kept.data_ptr() == normals.data_ptr() and torch.equal(kept, normals)
        # conversions: unchanged (no graph under no_grad)
        assert normals.to(torch.float64).grad_fn is None
        plain = torch.rand(3)
        assert plain.to("cpu") is plain  # nothing to detach: the tensor itself, as torch
    graph = nrhints_normals(torch.rand(8, 3))
    assert graph.to("cpu") is graph  # grad mode on: unchanged, gradients still flow
    device_copy.uninstall()
    with torch.no_grad():
        assert normals.to("cpu") is normals  # torch's own behaviour, which kept every chunk's graph


# ----------------------------------------------------------------------------------------- the job
# environment
NRHINTS_PROBE = """
import importlib.util, sys, torch
import lpips
assert lpips.__file__.startswith(sys.argv[1]), lpips.__file__
for name in ("tinycudann", "gsplat", "simple_knn", "diff_gaussian_rasterization_light", "torchvision"):
    spec = importlib.util.find_spec(name)  # the real package (if installed here) or nothing, never a stand-in
    assert spec is None or "cpu_standins" not in str(spec.origin), (name, spec.origin)
assert sys.modules["sitecustomize"].__file__.startswith(sys.argv[1]), sys.modules["sitecustomize"].__file__
assert torch.zeros(1).device.type == "cpu" and not torch.cuda.is_available()
try:  # no CUDA device shim: a CUDA request fails as it does on any CPU-only machine
    torch.zeros(1, device="cuda")
except (AssertionError, RuntimeError):
    pass
else:
    raise AssertionError("CUDA requests are served: the SSD-GS/GS3 device shim is installed")
x = torch.rand(4, 3, requires_grad=True)
with torch.no_grad():
    assert x.to("cpu").grad_fn is None and not x.to("cpu").requires_grad  # device_copy installed
try:
    lpips.pretrained_networks
except AttributeError as error:
    assert "only lpips.LPIPS" in str(error), error
else:
    raise AssertionError("lpips.pretrained_networks must not exist")
a = torch.rand(1, 3, 40, 40, generator=torch.Generator().manual_seed(0))
print("lpips", float(lpips.LPIPS(net="alex", verbose=False).cpu()(a, a, normalize=True).item()))
"""  # noqa: E501


def test_nrhints_job_environment_puts_only_lpips_on_the_path(seeded_alex):
    assert standins_for("nrhints-official") == ("lpips", "sitecustomize")
    assert "lpips" not in standins_for("ssdgs-official") and "tinycudann" not in standins_for(
        "nrhints-official"
    )
    env = job_environment("nrhints-official", {"PYTHONPATH": "/somewhere"})
    assert env["CUDA_VISIBLE_DEVICES"] == "" and "OLATBENCH_STANDIN_LIGHT" not in env
    assert env["PYTHONPATH"].split(os.pathsep) == [
        str(NRHINTS_SITE),
        str(OLATBENCH_ROOT),
        "/somewhere",
    ]
    assert NRHINTS_SITE != SITE and sorted(
        p.name for p in NRHINTS_SITE.iterdir() if p.name != "__pycache__"
    ) == ["lpips", "sitecustomize.py"]
    done = subprocess.run(
        [sys.executable, "-c", NRHINTS_PROBE, str(NRHINTS_SITE)],
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert float(done.stdout.split()[-1]) == pytest.approx(0.0, abs=1e-7)
    # outside such a job the name lpips is never the stand-in
    plain = subprocess.run(
        [sys.executable, "-c", "import lpips; print(lpips.__file__)"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert "cpu_standins" not in plain.stdout


def test_a_nrhints_cpu_job_imports_the_lpips_standin_and_records_it(tmp_path):
    log, official, checkout = run_cpu_job(
        tmp_path,
        "nrhints-official",
        "main.py",
        "import importlib.util, lpips\nprint('lpips from', lpips.__file__)\n"
        "print('tinycudann', importlib.util.find_spec('tinycudann'))\n",
    )
    assert (
        f"lpips from {NRHINTS_SITE / 'lpips' / '__init__.py'}" in log and "tinycudann None" in log
    )
    assert official["device"] == "cpu" and official["standins"] == ["lpips", "sitecustomize"]
    assert not (checkout / "lpips").exists()
