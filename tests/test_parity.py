"""benchmarks/parity.py: the pieces of the step-by-step parity harness — the authors' network
layouts carried into the native ones (the same functions after the transfer), the state transfer's
refusals, and the comparison and exit logic. The harness itself against the authors' code:
tests/test_parity_slow.py."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
import torch
from torch import nn

from olatbench.methods.official.cpu_standins import tcnn
from olatbench.methods.shading.encoding import frequency_encoding
from olatbench.methods.shading.shadow_mlp import ShadowNetwork
from olatbench.methods.ssdgs.sss import SSSNetwork

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "parity.py"


@pytest.fixture(scope="module")
def parity():
    spec = importlib.util.spec_from_file_location("parity", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules["parity"] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_frequency_columns_reorder_tiny_cuda_nn_encoding_into_olatbench(parity):
    x = torch.rand(50, 3) * 4 - 2
    for frequencies in (3, 4):
        official = tcnn.frequency_encoding(x, frequencies)
        # the layouts do differ
        assert not torch.equal(official, frequency_encoding(x, frequencies))
        torch.testing.assert_close(
            official[:, parity.frequency_columns(3, frequencies)],
            frequency_encoding(x, frequencies),
            rtol=0,
            atol=0,
        )


def official_shadow(network: tcnn.Network, encoding: tcnn.Encoding, wi, pos, material, hint):
    """The authors' Neural_phase.forward (scene/neural_phase_function.py:42-48 at 26e4251) on the
    stand-ins."""
    decay = network(torch.concat([encoding(wi), encoding(pos), material, hint], dim=-1))
    return torch.relu(decay - 1e-5)


def shadow_pair(parity, input_bias: str):
    """The authors' shadow network on the stand-ins (seeded weights, scaled up so the padded columns
    matter) and a native `ShadowNetwork` with ``input_bias`` carried over from it."""
    torch.manual_seed(0)
    frequencies, hidden, layers, material_dim = 4, 32, 3, 6
    encoding = tcnn.Encoding(3, {"otype": "Frequency", "n_frequencies": frequencies})
    in_dim = material_dim + 2 * encoding.n_output_dims + 1
    network = tcnn.Network(
        in_dim,
        1,
        {
            "otype": "FullyFusedMLP",
            "activation": "LeakyReLU",
            "output_activation": "Sigmoid",
            "n_neurons": hidden,
            "n_hidden_layers": layers,
        },
    )
    with torch.no_grad():
        network.params.mul_(4.0)
    native = ShadowNetwork(material_dim, hidden, layers, frequencies, input_bias=input_bias)
    native.load_state_dict(
        parity.shadow_layers(
            network.params.detach(), in_dim, hidden, layers, frequencies, input_bias
        )
    )
    wi, pos = nn.functional.normalize(torch.randn(40, 3), dim=-1), torch.rand(40, 3) - 0.5
    inputs = (wi, pos, torch.randn(40, material_dim), torch.rand(40, 1))
    return network, encoding, native, inputs


@pytest.mark.parametrize("input_bias", ["vector", "padded_ones"])
def test_the_authors_shadow_network_carried_over_computes_the_same_function(parity, input_bias):
    network, encoding, native, (wi, pos, material, hint) = shadow_pair(parity, input_bias)
    expected = official_shadow(network, encoding, wi, pos, material, hint)
    assert expected.std() > 0.01  # not a saturated network
    torch.testing.assert_close(native(pos, wi, hint, material), expected, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize(("input_bias", "follows"), [("padded_ones", True), ("vector", False)])
def test_only_the_padded_layout_trains_like_the_authors_network(parity, input_bias, follows):
    """Five Adam steps on the same loss: tiny-cuda-nn's layout (each padded column's weight a
    parameter of its own) moves the network as the authors' does; one bias vector does not (9 padded
    columns, 9 Adam steps' worth)."""
    network, encoding, native, (wi, pos, material, hint) = shadow_pair(parity, input_bias)
    target = torch.rand(40, 1)
    official_adam = torch.optim.Adam(network.parameters(), lr=1e-2, eps=1e-15)
    native_adam = torch.optim.Adam(native.parameters(), lr=1e-2, eps=1e-15)
    for _ in range(5):
        for adam, output in (
            (official_adam, lambda: official_shadow(network, encoding, wi, pos, material, hint)),
            (native_adam, lambda: native(pos, wi, hint, material)),
        ):
            adam.zero_grad()
            ((output() - target) ** 2).mean().backward()
            adam.step()
    with torch.no_grad():
        gap = (
            native(pos, wi, hint, material)
            - official_shadow(network, encoding, wi, pos, material, hint)
        ).abs()
    # rounding: ~2e-5; the vector bias: ~1
    assert (float(gap.max()) < 1e-3) == follows, float(gap.max())


def test_a_wrongly_sized_shadow_network_is_refused(parity):
    with pytest.raises(parity.ParityError, match="FullyFusedMLP"):
        parity.shadow_layers(torch.zeros(100), 55, 32, 3, 4)


def official_sss_parameters(out: torch.Tensor):
    """The authors' ScatterMLP head (scene/scatter_mlp.py:43-49 at 26e4251): (r, σ_s', σ_a) from the
    rows."""
    r = torch.sigmoid(out[:, 0]) * 3.0 + 0.1
    sigma_s = torch.sigmoid(out[:, 1]).unsqueeze(-1) * 2.0 + 0.05
    sigma_a = torch.sigmoid(out[:, 2]).unsqueeze(-1) * 2.0 + 0.05
    return sigma_s, sigma_a, r.unsqueeze(-1)


def official_state(
    sss: nn.Sequential, params: torch.Tensor, n: int, lobes: int
) -> dict[str, torch.Tensor]:
    state = {
        "_xyz": torch.randn(n, 3),
        "_scaling": torch.randn(n, 3),
        "_rotation": torch.randn(n, 4),
        "_opacity": torch.randn(n, 1),
        "kd": torch.randn(n, 3),
        "ks": torch.randn(n, 3),
        "ksss": torch.randn(n, 3),
        "alpha_asg": torch.randn(n, lobes),
        "local_q": torch.randn(n, 4),
        "neural_material": torch.randn(n, 6),
        "asg_sigma": torch.randn(lobes),
        "asg_scales": torch.randn(lobes, 2),
        "asg_rotation": torch.randn(lobes, 4),
        "phasefunc.params": params,
    }
    state.update({f"scatter.network.{k}": v for k, v in sss.state_dict().items()})
    return state


def test_the_authors_sss_network_carried_over_gives_the_same_dipole_parameters(parity):
    torch.manual_seed(1)
    native = SSSNetwork(6, 256, 5, 4, virtual_factor="official", last_hidden=128)
    official = nn.Sequential(
        nn.Linear(3 * 27 + 3 + 6, 256),
        nn.ReLU(),
        nn.Linear(256, 256),
        nn.ReLU(),
        nn.Linear(256, 256),
        nn.ReLU(),
        nn.Linear(256, 128),
        nn.ReLU(),
        nn.Linear(128, 3),
    )
    shadow = tcnn.Network(
        55,
        1,
        {
            "otype": "FullyFusedMLP",
            "activation": "LeakyReLU",
            "output_activation": "Sigmoid",
            "n_neurons": 32,
            "n_hidden_layers": 3,
        },
    )
    layout = {
        "in_dim": 55,
        "hidden": 32,
        "num_hidden": 3,
        "frequencies": 4,
        "input_bias": "padded_ones",
    }
    tensors = parity.native_tensors(
        official_state(official, shadow.params.detach(), 5, 8), {"shadow": layout}
    )
    with torch.no_grad():
        for name, value in native.network.state_dict().items():
            value.copy_(tensors[f"shader.sss_net.network.{name}"])
    encoded = torch.randn(30, 3 * 27 + 3 + 6)
    with torch.no_grad():
        for got, expected in zip(
            native.parameters_from_input(encoded),
            official_sss_parameters(official(encoded)),
            strict=True,
        ):
            torch.testing.assert_close(got, expected)


class _Shader(nn.Module):
    def __init__(self) -> None:
        super().__init__()
        self.weight = nn.Parameter(torch.zeros(2, 3))


def fake_method(n: int) -> SimpleNamespace:
    params = {
        "means": nn.Parameter(torch.zeros(n, 3)),
        "opacity_logits": nn.Parameter(torch.zeros(n)),
    }
    return SimpleNamespace(
        model=SimpleNamespace(per_gaussian_parameters=lambda: params), shader=_Shader()
    )


def test_load_native_overwrites_in_place_and_refuses_missing_or_misshapen_tensors(parity):
    method = fake_method(4)
    kept = method.model.per_gaussian_parameters()["means"]
    tensors = {
        "means": torch.ones(4, 3),
        "opacity_logits": torch.full((4,), 2.0),
        "shader.weight": torch.ones(2, 3),
    }
    parity.load_native(method, tensors)
    assert kept is method.model.per_gaussian_parameters()["means"] and torch.equal(
        kept, torch.ones(4, 3)
    )
    assert torch.equal(method.shader.weight, torch.ones(2, 3))
    with pytest.raises(parity.ParityError, match=r"no counterpart of shader\.weight"):
        parity.load_native(
            fake_method(4), {k: v for k, v in tensors.items() if k != "shader.weight"}
        )
    with pytest.raises(parity.ParityError, match=r"means: the authors' tensor is \(5, 3\)"):
        parity.load_native(fake_method(4), {**tensors, "means": torch.ones(5, 3)})


def test_first_miss_names_the_first_step_over_the_tolerance(parity):
    steps = [
        parity.StepComparison(1, 0.5, 0.5002),
        parity.StepComparison(2, 0.4, 0.4008),
        parity.StepComparison(3, 0.3, 0.3),
    ]
    assert math.isclose(steps[1].relative, 2e-3)
    assert parity.first_miss(steps, 1e-3).step == 2
    assert parity.first_miss(steps, 3e-3) is None
    # NaN never passes
    assert parity.first_miss([parity.StepComparison(1, 0.5, float("nan"))], 1.0).step == 1


def test_largest_differences_name_tensors_they_cannot_compare(parity):
    official = {"a": torch.zeros(3), "b": torch.zeros(2), "c": torch.zeros(1)}
    native = {"a": torch.tensor([0.0, -0.5, 0.25]), "b": torch.zeros(3)}
    differences = parity.largest_differences(official, native)
    assert differences["a"] == 0.5
    assert "shapes differ" in differences["b"] and "missing" in differences["c"]


def test_bad_arguments_exit_2(parity, capsys):
    assert (
        parity.main(["--checkout", "x", "--python", "y", "--steps", "700", "--iterations", "600"])
        == 2
    )
    assert "--steps" in capsys.readouterr().err


def test_gs3s_other_effects_network_carried_over_is_the_authors_function_but_its_activation(parity):
    from olatbench.methods.baselines.gs3_shading import OtherEffectsNetwork

    torch.manual_seed(2)
    encoding = tcnn.Encoding(3, {"otype": "Frequency", "n_frequencies": 4})
    in_dim = 6 + 2 * encoding.n_output_dims
    network = tcnn.Network(
        in_dim,
        3,
        {
            "otype": "FullyFusedMLP",
            "activation": "LeakyReLU",
            "output_activation": "Sigmoid",
            "n_neurons": 128,
            "n_hidden_layers": 3,
        },
    )
    with torch.no_grad():
        network.params.mul_(3.0)
    native = OtherEffectsNetwork(6, 128, 3, 4)
    native.load_state_dict(parity.other_layers(network.params.detach(), in_dim, 128, 3, 4, "torch"))
    wo, pos, material = (
        nn.functional.normalize(torch.randn(40, 3), dim=-1),
        torch.rand(40, 3) - 0.5,
        torch.randn(40, 6),
    )
    # the authors' Neural_phase.forward (GS³ scene/neural_phase_function.py:65 at 83c8daa)
    expected = network(torch.concat([encoding(wo), encoding(pos), material], dim=-1)) * 2.0
    assert expected.std() > 0.01
    # olatbench's network has ReLU between its layers, tiny-cuda-nn LeakyReLU(0.01): a difference of
    # the two GS³s
    assert not torch.allclose(native(wo, pos, material), expected, atol=1e-3)
    for index, layer in enumerate(native.network):
        if isinstance(layer, nn.ReLU):
            native.network[index] = nn.LeakyReLU(0.01)
    # the transfer itself
    torch.testing.assert_close(native(wo, pos, material), expected, rtol=1e-5, atol=1e-6)
    # the authors' layout: the same function as is
    tiny = OtherEffectsNetwork(6, 128, 3, 4, layout="tiny_cuda_nn")
    tiny.load_state_dict(
        parity.other_layers(network.params.detach(), in_dim, 128, 3, 4, "tiny_cuda_nn")
    )
    torch.testing.assert_close(tiny(wo, pos, material), expected, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize(("layout", "follows"), [("tiny_cuda_nn", True), ("torch", False)])
def test_only_the_tiny_cuda_nn_layout_trains_like_gs3s_other_effects_network(
    parity, layout, follows
):
    from olatbench.methods.baselines.gs3_shading import OtherEffectsNetwork

    torch.manual_seed(3)
    encoding = tcnn.Encoding(3, {"otype": "Frequency", "n_frequencies": 4})
    in_dim = 6 + 2 * encoding.n_output_dims
    network = tcnn.Network(
        in_dim,
        3,
        {
            "otype": "FullyFusedMLP",
            "activation": "LeakyReLU",
            "output_activation": "Sigmoid",
            "n_neurons": 128,
            "n_hidden_layers": 3,
        },
    )
    native = OtherEffectsNetwork(6, 128, 3, 4, layout=layout)
    native.load_state_dict(parity.other_layers(network.params.detach(), in_dim, 128, 3, 4, layout))
    wo, pos, material = (
        nn.functional.normalize(torch.randn(40, 3), dim=-1),
        torch.rand(40, 3) - 0.5,
        torch.randn(40, 6),
    )
    target = torch.rand(40, 3) * 2

    def official():
        return network(torch.concat([encoding(wo), encoding(pos), material], dim=-1)) * 2.0

    adams = (
        torch.optim.Adam(network.parameters(), lr=1e-2, eps=1e-15),
        torch.optim.Adam(native.parameters(), lr=1e-2, eps=1e-15),
    )
    for _ in range(5):
        for adam, output in zip(adams, (official, lambda: native(wo, pos, material)), strict=True):
            adam.zero_grad()
            ((output() - target) ** 2).mean().backward()
            adam.step()
    with torch.no_grad():
        gap = float((native(wo, pos, material) - official()).abs().max())
    assert (gap < 1e-3) == follows, gap
