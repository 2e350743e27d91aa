"""The fake-CUDA dry run of the GPU path (docs/gpu.md): no host sync or device mix in a training
step beyond the allowances of `olatbench.gaussians.host_sync`, and the dry run fails where one is
put in.

The dry run needs gsplat (its Python runs the camera pass) and a C++ compiler for the no-op CUDA
guard of a CPU-only torch; the project's test environment has both (pyproject's test extra, and the
compiler the C++ kernels use).
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

pytest.importorskip("gsplat")

from olatbench.bench import gpu_dryrun
from olatbench.gaussians.fake_cuda import fake_cuda
from olatbench.gaussians.fake_cuda.gsplat_kernels import rasterize_to_pixels_3dgs_fwd
from olatbench.gaussians.host_sync import ALLOWANCES, allowed_host_sync
from olatbench.methods.gaussian_method import GaussianMethod

THREE_DGS = tuple(case for case in gpu_dryrun.CASES if case[0] == "3dgs")


@pytest.fixture(autouse=True)
def _own_cache(tmp_path, monkeypatch):
    """The guard library is built into the test's own cache folder (never the user's)."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


def test_the_gpu_path_makes_no_host_sync_or_device_mix_beyond_the_allowances():
    """SSD-GS (nrhints preset), GS³ and 3DGS: setup, a step before any phase, the first
    densification step with every phase on and the step after it, logging, render; every case runs
    to its end and nothing is a violation, while the allowed syncs are seen where the code names
    them (so the camera pass, the light pass and density control did run on the fake GPU)."""
    run = gpu_dryrun.dry_run()
    assert not run.errors, run.report()
    assert not run.violations(), run.report()
    assert len(run.log) == len(gpu_dryrun.CASES), run.report()
    for label, *_ in gpu_dryrun.CASES:
        seen = {f.allowance for f in run.findings if f.phase.startswith(f"{label}: train_step")}
        expected = {"tile-intersections", "density-control"} | (
            {"light-pass-entries"} if label != "3dgs" else set()
        )
        assert expected <= seen, (label, seen, run.report())
    assert all(f.where.startswith("olatbench/") for f in run.findings if "setup" not in f.phase), (
        run.report()
    )


def test_an_item_inside_train_step_fails_the_dry_run(monkeypatch):
    """A ``.item()`` of the loss inside `compute_gradients` is a violation at its line."""
    original = GaussianMethod.compute_gradients

    def with_item(self, step, index=None):
        result = original(self, step, index)
        result["loss"] = result["loss"].item()  # the injected host sync
        return result

    monkeypatch.setattr(GaussianMethod, "compute_gradients", with_item)
    run = gpu_dryrun.dry_run(THREE_DGS)
    bad = run.violations()
    assert bad and all(f.where.startswith(f"{__file__}:") for f in bad), run.report()
    assert {f.phase for f in bad} == {
        "3dgs: train_step 0",
        "3dgs: train_step 23",
        "3dgs: train_step 24",
    }
    assert all("scalar read" in f.what for f in bad)


def test_a_cpu_tensor_inside_train_step_fails_the_dry_run(monkeypatch):
    """A CPU tensor in the loss (the target image left on the host) is a device mix at its line."""
    original = GaussianMethod.loss

    def with_cpu_target(self, render, target):
        # the injected CPU tensor
        return original(self, render, torch.zeros(target.shape, device="cpu"))

    monkeypatch.setattr(GaussianMethod, "loss", with_cpu_target)
    run = gpu_dryrun.dry_run(THREE_DGS)
    mixes = [f for f in run.violations() if f.kind == "device mix"]
    assert mixes and all("cpu" in f.what and "cuda:0" in f.what for f in mixes), run.report()
    assert any(f.phase == "3dgs: train_step 0" for f in mixes)


# a real tensor made outside the fake mode (allow_non_fake_inputs lets it in)
CPU_CONSTANT = torch.ones(3)


def test_the_recorder_classifies_each_kind_of_sync_and_mix():
    """Each kind the module docstring lists, as torch on a GPU would sync: scalar reads, blocking
    copies both ways, data-dependent sizes; a CPU constant (made outside or inside the mode) mixed
    into a CUDA op is a device mix, a 0-d CPU tensor is not (CUDA ops take CPU scalars); a
    non-blocking upload is not a sync."""
    with fake_cuda() as recorder:
        a = torch.randn(4, 3, device="cuda")
        expected = []
        float(a.sum())
        expected.append(("sync", "scalar read"))
        a[a > 0]
        expected.append(("sync", "boolean-mask indexing"))
        torch.repeat_interleave(
            torch.arange(4, device="cuda"), torch.ones(4, dtype=torch.long, device="cuda")
        )
        expected.append(("sync", "repeat_interleave"))
        a.cpu()
        expected.append(("sync", "device-to-host"))
        torch.tensor([1.0, 2.0], device="cuda")
        expected.append(("sync", "host-to-device"))
        a[0] + CPU_CONSTANT
        expected.append(("device mix", "cpu, cuda:0"))
        a[0] + torch.from_numpy(np.ones(3, dtype=np.float32))
        expected.append(("device mix", "cpu, cuda:0"))
        a + torch.tensor(2.0)  # a CPU scalar: allowed on a GPU
        torch.ones(3).to("cuda", non_blocking=True)  # queued, not waited for
    found = [(f.kind, f.what) for f in recorder.findings]
    assert len(found) == len(expected), found
    for (kind, what), (want_kind, want_text) in zip(found, expected, strict=True):
        assert kind == want_kind and want_text in what, (kind, what)
    assert all(f.where.startswith(f"{__file__}:") for f in recorder.findings)


def test_an_allowance_counts_its_syncs_and_flags_those_over_its_limit():
    """Two reads inside one "tile-intersections" block (limit 1): the second is over the limit."""
    assert ALLOWANCES["tile-intersections"].limit == 1
    with fake_cuda() as recorder:
        recorder.phase = "train_step 0"
        counts = torch.ones(5, dtype=torch.long, device="cuda")
        with allowed_host_sync("tile-intersections"):
            int(counts.sum())
            int(counts.max())
        with allowed_host_sync("tile-intersections"):
            int(counts.sum())
    assert [(f.allowance, f.over_limit) for f in recorder.findings] == [
        ("tile-intersections", False),
        ("tile-intersections", True),
        ("tile-intersections", False),
    ]


def test_the_gsplat_kernel_stand_in_checks_what_the_kernel_checks():
    """gsplat's host binding requires CUDA, contiguous tensors and the dtypes its kernel reads:
    int64 tile ids (as olatbench's bins hold them, before rasterize_cuda converts) are refused;
    int32 ones give gsplat's shapes."""
    with fake_cuda():
        n, h, w = 10, 20, 36
        args = [
            torch.zeros(1, n, 2, device="cuda"),
            torch.zeros(1, n, 3, device="cuda"),
            torch.zeros(1, n, 5, device="cuda"),
            torch.zeros(1, n, device="cuda"),
            None,
            None,
            w,
            h,
            16,
        ]
        offsets = torch.zeros(1, 2, 3, dtype=torch.int32, device="cuda")
        with pytest.raises(RuntimeError, match=r"flatten_ids must be torch\.int32"):
            rasterize_to_pixels_3dgs_fwd(
                *args, offsets, torch.zeros(7, dtype=torch.int64, device="cuda")
            )
        with pytest.raises(RuntimeError, match="must be a CUDA tensor"):
            rasterize_to_pixels_3dgs_fwd(
                *args, offsets.cpu(), torch.zeros(7, dtype=torch.int32, device="cuda")
            )
        renders, alphas, last = rasterize_to_pixels_3dgs_fwd(
            *args, offsets, torch.zeros(7, dtype=torch.int32, device="cuda")
        )
        assert (renders.shape, alphas.shape, last.shape) == ((1, h, w, 5), (1, h, w, 1), (1, h, w))
        assert renders.device.type == "cuda" and last.dtype == torch.int32


@pytest.mark.parametrize(
    "mode, offset", [("uniform", False), ("density", True), ("footprint", False)]
)
def test_the_light_pass_gather_of_a_chunk_makes_no_host_sync(mode, offset):
    """The light pass's per-chunk gather runs in the dry run only where the copied entry layout has
    entries, which fake values never give: run on fake CUDA inputs directly, it makes no sync and
    mixes no device."""
    from olatbench.gaussians.shadow import _gather_chunk

    with fake_cuda() as recorder:
        n, pairs, total = 50, 80, 900

        def cuda(*shape, dtype=torch.float32):
            return torch.zeros(*shape, dtype=dtype, device="cuda")

        box = tuple(cuda(pairs, dtype=torch.int64) for _ in range(4))
        sums = [cuda(n, dtype=torch.float64) for _ in range(3)]
        _gather_chunk(
            cuda(n, 2),
            cuda(n, 3),
            cuda(n),
            64,
            cuda(pairs, dtype=torch.int64),
            cuda(pairs, dtype=torch.int64),
            0,
            pairs,
            box,
            total,
            mode,
            2.0,
            offset,
            sums,
        )
        assert all(s.shape == (n,) and s.device.type == "cuda" for s in sums)
    assert recorder.findings == []
