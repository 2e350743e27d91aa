"""Adaptive density control: clone/split/prune/cap semantics and optimizer state following its
Gaussians."""

from __future__ import annotations

import math

import pytest
import torch

from olatbench.gaussians.densify import Densifier, DensifyConfig
from olatbench.gaussians.model import GaussianModel
from olatbench.gaussians.optim import append_rows, select_rows

EXTENT = 1.0
SMALL, LARGE = 0.005, 0.05  # max scale below / above percent_dense × extent = 0.01


def _tagged_model(n: int = 8) -> tuple[GaussianModel, torch.optim.Adam]:
    """Gaussians whose attribute ``tag`` and Adam moments encode their original row index."""
    means = torch.arange(n, dtype=torch.float32)[:, None].repeat(1, 3)
    model = GaussianModel(
        means,
        torch.full((n, 3), math.log(SMALL)),
        torch.tensor([[1.0, 0, 0, 0]]).repeat(n, 1),
        torch.zeros(n),  # opacity 0.5
        {"tag": torch.arange(n, dtype=torch.float32)[:, None], "feat": torch.zeros(n, 2, 3)},
    )
    optimizer = torch.optim.Adam(
        [{"params": [p], "lr": 1e-3} for p in model.parameters()], eps=1e-15
    )
    for p in model.parameters():
        tag = (
            torch.arange(n, dtype=torch.float32).reshape((n,) + (1,) * (p.ndim - 1)).expand(p.shape)
        )
        optimizer.state[p] = {
            "step": torch.tensor(7.0),
            "exp_avg": tag + 0.5,
            "exp_avg_sq": 2 * tag + 1,
        }
    return model, optimizer


def _check_moments_follow_tags(
    model: GaussianModel, optimizer: torch.optim.Adam, fresh: torch.Tensor
) -> None:
    """Rows with ``fresh`` have zero moments; every other row has the moments of its tag; step is
    unchanged."""
    tags = model.attributes["tag"].detach()[:, 0]
    for p in model.parameters():
        state = optimizer.state[p]
        assert float(state["step"]) == 7.0
        tag = tags.reshape((-1,) + (1,) * (p.ndim - 1)).expand(p.shape)
        fresh_b = fresh.reshape((-1,) + (1,) * (p.ndim - 1)).expand(p.shape)
        expected_avg = torch.where(fresh_b, torch.zeros_like(tag), tag + 0.5)
        expected_sq = torch.where(fresh_b, torch.zeros_like(tag), 2 * tag + 1)
        assert torch.equal(state["exp_avg"], expected_avg)
        assert torch.equal(state["exp_avg_sq"], expected_sq)


def _accumulate(
    densifier: Densifier, grads_px: torch.Tensor, radii: torch.Tensor | None = None
) -> None:
    n = grads_px.shape[0]
    radii = radii if radii is not None else torch.full((n,), 3)
    densifier.accumulate(grads_px, radii, torch.ones(n, dtype=torch.bool), width=200, height=100)


def test_clone_split_prune_keep_optimizer_state_aligned():
    model, optimizer = _tagged_model(8)
    with torch.no_grad():
        model.log_scales[[2, 3]] = math.log(LARGE)  # large
        model.opacity_logits[5] = -10.0  # transparent -> pruned
    densifier = Densifier(DensifyConfig(), seed=0)
    # NDC gradient = px gradient × (W/2, H/2) = × (100, 50); threshold 2e-4.
    grads = torch.zeros(8, 2)
    grads[[0, 2, 5], 0] = 3e-6  # 3e-4 in NDC: hot
    grads[[1, 3], 0] = 1e-6  # 1e-4: cold
    _accumulate(densifier, grads)
    report = densifier.densify_and_prune(model, optimizer, EXTENT, max_screen_size=None)
    # clones of 0 and 5; 5 and its clone pruned
    assert report == {"cloned": 2, "split": 1, "pruned": 2, "capped": 0}

    tags = model.attributes["tag"][:, 0].tolist()
    # survivors in order (0,1,3,4,6,7), then clone of 0, then the 2 children of 2
    assert tags == [0, 1, 3, 4, 6, 7, 0, 2, 2]
    fresh = torch.tensor([False] * 6 + [True] * 3)
    _check_moments_follow_tags(model, optimizer, fresh)
    # clone is an exact copy; children have scale / 1.6 and stay near the parent
    assert torch.equal(model.means[6], model.means[0])
    torch.testing.assert_close(model.scales[7:], torch.full((2, 3), LARGE / 1.6))
    assert float((model.means.detach()[7:] - 2.0).abs().max()) < 10 * LARGE
    assert not torch.equal(model.means[7], model.means[8])
    # statistics were reset for the new count; optimizer steps work afterwards
    assert densifier.grad_sum.shape == (9,) and float(densifier.grad_sum.abs().sum()) == 0.0
    for p in model.parameters():
        assert p.grad is None
    loss = model.means.sum() + model.attributes["feat"].sum() + model.opacities.sum()
    loss.backward()
    optimizer.step()


def test_screen_and_world_size_pruning_only_when_requested():
    model, optimizer = _tagged_model(4)
    with torch.no_grad():
        model.log_scales[1] = math.log(0.5)  # > 0.1 × extent
    densifier = Densifier()
    _accumulate(densifier, torch.zeros(4, 2), radii=torch.tensor([3, 3, 3, 40]))
    report = densifier.densify_and_prune(model, optimizer, EXTENT, max_screen_size=None)
    assert report["pruned"] == 0 and model.num_gaussians == 4
    _accumulate(densifier, torch.zeros(4, 2), radii=torch.tensor([3, 3, 3, 40]))
    report = densifier.densify_and_prune(model, optimizer, EXTENT, max_screen_size=20)
    assert report["pruned"] == 2
    assert model.attributes["tag"][:, 0].tolist() == [0, 2]
    _check_moments_follow_tags(model, optimizer, torch.zeros(2, dtype=torch.bool))


def test_cap_keeps_highest_priority_and_new_gaussians():
    model, optimizer = _tagged_model(6)
    densifier = Densifier(DensifyConfig(max_gaussians=4))
    grads = torch.zeros(6, 2)
    grads[4, 1] = 1e-5  # hot small -> cloned
    _accumulate(densifier, grads)
    densifier.accumulate_priority(torch.tensor([5.0, 1.0, 4.0, 0.5, 2.0, 3.0]))
    report = densifier.densify_and_prune(model, optimizer, EXTENT, max_screen_size=None)
    assert report["cloned"] == 1 and report["capped"] == 3
    # 7 candidates: priorities 5,1,4,0.5,2,3 and the clone (max = 5): keep 0, 2, 5 and the clone of
    # 4
    assert model.attributes["tag"][:, 0].tolist() == [0, 2, 5, 4]
    _check_moments_follow_tags(model, optimizer, torch.tensor([False, False, False, True]))


def test_schedule_and_opacity_reset():
    model, optimizer = _tagged_model(4)
    densifier = Densifier(DensifyConfig())
    _accumulate(densifier, torch.zeros(4, 2))
    assert densifier.step(model, optimizer, 550, EXTENT)["densified"] is False
    assert densifier.step(model, optimizer, 600, EXTENT)["densified"] is True
    # densify_from is exclusive
    assert densifier.step(model, optimizer, 500, EXTENT)["densified"] is False
    report = densifier.step(model, optimizer, 3000, EXTENT)
    assert report["densified"] and report["opacity_reset"]
    assert float(model.opacities.detach().max()) <= 0.01 + 1e-7
    state = optimizer.state[model.opacity_logits]
    assert float(state["exp_avg"].abs().sum()) == 0.0 and float(state["step"]) == 7.0
    # other parameters keep their moments through the reset
    assert float(optimizer.state[model.means]["exp_avg"].abs().sum()) > 0
    assert densifier.step(model, optimizer, 15_000, EXTENT) == {
        "densified": False,
        "cloned": 0,
        "split": 0,
        "pruned": 0,
        "capped": 0,
        "opacity_reset": False,
        "num_gaussians": model.num_gaussians,
    }


def test_config_scaling_and_validation():
    scaled = DensifyConfig().scaled(100_000 / 30_000)
    assert (
        scaled.densify_until == 50_000
        and scaled.densify_from == 1667
        and scaled.grad_threshold == 0.0002
    )
    with pytest.raises(ValueError, match="split_count"):
        DensifyConfig(split_count=1)


def test_surgery_with_multi_tensor_groups_and_no_state():
    a = torch.nn.Parameter(torch.arange(6.0).reshape(3, 2))
    b = torch.nn.Parameter(torch.arange(3.0))
    optimizer = torch.optim.Adam([{"params": [a, b]}])
    select_rows([a, b], optimizer, torch.tensor([2, 0]))  # no state yet: only the values change
    assert a.tolist() == [[4.0, 5.0], [0.0, 1.0]] and b.tolist() == [2.0, 0.0]
    (a.sum() + b.sum()).backward()
    optimizer.step()
    append_rows([a, b], optimizer, [torch.ones(1, 2), torch.ones(1)])
    assert (
        optimizer.state[a]["exp_avg"].shape == (3, 2)
        and float(optimizer.state[b]["exp_avg"][-1]) == 0.0
    )
    with pytest.raises(ValueError, match="cannot append rows"):
        append_rows([a], optimizer, [torch.ones(1, 3)])


def test_exponential_lr_closed_form():
    from olatbench.gaussians.lr import exponential_lr, exponential_lr_schedule

    assert exponential_lr(0, 1.6e-4, 1.6e-6, 30_000) == pytest.approx(1.6e-4, rel=1e-12)
    assert exponential_lr(30_000, 1.6e-4, 1.6e-6, 30_000) == pytest.approx(1.6e-6, rel=1e-12)
    # held after
    assert exponential_lr(90_000, 1.6e-4, 1.6e-6, 30_000) == pytest.approx(1.6e-6, rel=1e-12)
    assert exponential_lr(15_000, 1.6e-4, 1.6e-6, 30_000) == pytest.approx(
        math.sqrt(1.6e-4 * 1.6e-6), rel=1e-12
    )
    assert exponential_lr(-1, 1.0, 0.1, 10) == 0.0 and exponential_lr(5, 0.0, 0.0, 10) == 0.0
    # delayed warm-up: delay_mult + (1 - delay_mult) sin(π/2 · step/delay_steps)
    expected = (0.01 + 0.99 * math.sin(math.pi / 4)) * 1.0 * (0.1 / 1.0) ** (50 / 1000)
    assert exponential_lr(50, 1.0, 0.1, 1000, delay_steps=100, delay_mult=0.01) == pytest.approx(
        expected, rel=1e-12
    )
    assert exponential_lr(0, 1.0, 0.1, 1000, delay_steps=100, delay_mult=0.01) == pytest.approx(
        0.01, rel=1e-12
    )
    schedule = exponential_lr_schedule(1.0, 0.1, 1000)
    assert schedule(500) == exponential_lr(500, 1.0, 0.1, 1000)
    with pytest.raises(ValueError, match="lr_final > 0"):
        exponential_lr(1, 1.0, 0.0, 10)


def test_densifier_state_roundtrip_reproduces_splits():
    model_a, optimizer_a = _tagged_model(4)
    model_b, optimizer_b = _tagged_model(4)
    with torch.no_grad():
        for model in (model_a, model_b):
            model.log_scales[:] = math.log(LARGE)
    first = Densifier(seed=3)
    grads = torch.full((4, 2), 1e-5)
    _accumulate(first, grads)
    second = Densifier(seed=99)
    second.load_state_dict({k: v for k, v in first.state_dict().items()})
    first.densify_and_prune(model_a, optimizer_a, EXTENT, None)
    second.densify_and_prune(model_b, optimizer_b, EXTENT, None)
    assert torch.equal(model_a.means, model_b.means) and model_a.num_gaussians == 8


def test_accumulate_updates_only_the_visible_gaussians():
    """Statistics of Gaussians outside the view stay untouched, even when their gradient is NaN."""
    densifier = Densifier(DensifyConfig(), seed=0)
    visible = torch.tensor([True, False, True, False])
    grads = torch.tensor([[0.03, 0.04], [float("nan"), 1.0], [0.0, 0.02], [5.0, 5.0]])  # px units
    for radii in (torch.tensor([4, 9, 2, 7]), torch.tensor([3, 9, 6, 7])):
        densifier.accumulate(grads, radii, visible, width=200, height=100)
    # NDC norm = |(gx · 100, gy · 50)|: 3.6056 and 1.0 per view for the two visible Gaussians
    expected = torch.tensor([2 * math.hypot(3.0, 2.0), 0.0, 2.0, 0.0])
    torch.testing.assert_close(densifier.grad_sum, expected)
    assert densifier.visible_count.tolist() == [2.0, 0.0, 2.0, 0.0]
    assert densifier.max_radii.tolist() == [4.0, 0.0, 6.0, 0.0]


def test_observe_and_step_counts_iterations_from_one_so_step_0_resets_nothing():
    """The runner's step 0 is the official code's iteration 1: no opacity reset there (0 % 3000 == 0
    used to fire one, making every Gaussian nearly transparent before the first update); the first
    reset is at the runner's step 2999 (iteration 3000)."""
    from types import SimpleNamespace

    model, optimizer = _tagged_model(4)
    before = model.opacities.detach().clone()
    densifier = Densifier(DensifyConfig())
    projected = SimpleNamespace(means2d=SimpleNamespace(grad=None))
    report = densifier.observe_and_step(model, optimizer, projected, 0, EXTENT)
    assert report["opacity_reset"] is False and torch.equal(model.opacities.detach(), before)
    assert (
        densifier.observe_and_step(model, optimizer, projected, 2998, EXTENT)["opacity_reset"]
        is False
    )
    assert (
        densifier.observe_and_step(model, optimizer, projected, 2999, EXTENT)["opacity_reset"]
        is True
    )
