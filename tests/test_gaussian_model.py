"""GaussianModel: constructors, nearest-neighbour scales, save/load, state_dict with a different N,
PLY I/O."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from olatbench.gaussians.knn import mean_neighbour_sq_distance
from olatbench.gaussians.model import GaussianModel
from olatbench.gaussians.ply import PlyError, read_ply_points, write_ply_points


def _brute_mean_sq(points: torch.Tensor, k: int = 3) -> torch.Tensor:
    sq = (
        torch.cdist(points.double(), points.double(), compute_mode="donot_use_mm_for_euclid_dist")
        ** 2
    )
    sq.fill_diagonal_(float("inf"))
    return sq.topk(k, dim=1, largest=False).values.mean(1)


@pytest.mark.parametrize(
    "points",
    [
        torch.rand(800, 3, generator=torch.Generator().manual_seed(1)),
        # a dense cluster inside a sparse cloud, plus exact duplicates
        torch.cat(
            [
                torch.randn(300, 3, generator=torch.Generator().manual_seed(2)) * 1e-3,
                torch.rand(500, 3, generator=torch.Generator().manual_seed(3)) * 5,
                torch.zeros(3, 3),
            ]
        ),
        # a flat (planar) cloud
        torch.cat(
            [torch.rand(600, 2, generator=torch.Generator().manual_seed(4)), torch.zeros(600, 1)], 1
        ),
    ],
    ids=["uniform", "clustered", "planar"],
)
def test_neighbour_distances_match_brute_force(points):
    got = mean_neighbour_sq_distance(points).double()
    expected = _brute_mean_sq(points)
    torch.testing.assert_close(got, expected, rtol=1e-5, atol=1e-12)


def test_from_points_follows_3dgs_initialisation():
    points = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 3], [5, 5, 5]])
    model = GaussianModel.from_points(
        points, colours=torch.rand(5, 3), attributes={"kd": (3,), "m": (2, 4)}
    )
    expected = _brute_mean_sq(points).sqrt()
    torch.testing.assert_close(model.scales, expected[:, None].expand(5, 3).float())
    torch.testing.assert_close(model.opacities, torch.full((5,), 0.1))
    torch.testing.assert_close(model.quats, torch.tensor([[1.0, 0, 0, 0]]).expand(5, 4))
    assert model.attributes["kd"].shape == (5, 3) and model.attributes["m"].shape == (5, 2, 4)
    assert model.attributes["colour"].shape == (5, 3)
    assert model.num_gaussians == 5


def test_random_in_sphere_is_uniform_in_the_ball():
    model = GaussianModel.random_in_sphere(4000, radius=2.0, attributes={"kd": (3,)}, seed=3)
    r = model.means.detach().norm(dim=1)
    assert float(r.max()) <= 2.0
    # uniform in the ball: P(r < R/2) = 1/8
    assert abs(float((r < 1.0).float().mean()) - 0.125) < 0.02
    same = GaussianModel.random_in_sphere(4000, radius=2.0, attributes={"kd": (3,)}, seed=3)
    assert torch.equal(model.means, same.means)


def test_random_in_box_bounds():
    model = GaussianModel.random_in_box(500, low=(-1, 0, 2), high=(1, 1, 3), seed=0)
    lo, hi = model.means.min(0).values, model.means.max(0).values
    assert bool((lo >= torch.tensor([-1.0, 0, 2])).all()) and bool(
        (hi <= torch.tensor([1.0, 1, 3])).all()
    )


def test_save_load_roundtrip_is_identical(tmp_path):
    model = GaussianModel.random_in_sphere(300, attributes={"kd": (3,), "latent": (2, 5)}, seed=1)
    with torch.no_grad():
        for p in model.parameters():
            p.add_(torch.randn_like(p))
    path = model.save(tmp_path / "g.pt")
    loaded = GaussianModel.load(path)
    assert set(loaded.attributes) == {"kd", "latent"}
    for (name, a), (name_b, b) in zip(
        model.state_dict().items(), loaded.state_dict().items(), strict=True
    ):
        assert name == name_b and torch.equal(a, b)


def test_load_rejects_foreign_files(tmp_path):
    torch.save({"means": torch.zeros(2, 3)}, tmp_path / "x.pt")
    with pytest.raises(ValueError, match="not a GaussianModel checkpoint"):
        GaussianModel.load(tmp_path / "x.pt")
    (tmp_path / "bad.pt").write_bytes(b"garbage")
    with pytest.raises(ValueError, match="cannot read"):
        GaussianModel.load(tmp_path / "bad.pt")
    with pytest.raises(FileNotFoundError):
        GaussianModel.load(tmp_path / "missing.pt")


def test_state_dict_loads_into_a_model_with_another_count():
    source = GaussianModel.random_in_sphere(50, attributes={"kd": (3,), "extra": (1,)}, seed=2)
    target = GaussianModel.random_in_sphere(10, attributes={"kd": (3,)}, seed=5)
    means_param = target.means
    target.load_state_dict(source.state_dict())
    assert target.means is means_param  # identity kept (optimizers stay valid)
    assert target.num_gaussians == 50 and "extra" in target.attributes
    assert torch.equal(target.attributes["kd"], source.attributes["kd"])


def test_shape_errors_are_clear():
    with pytest.raises(ValueError, match="quats must have shape"):
        GaussianModel(torch.zeros(3, 3), torch.zeros(3, 3), torch.zeros(3, 3), torch.zeros(3))
    with pytest.raises(ValueError, match="attributes\\['kd'\\] must have 3 rows"):
        GaussianModel(
            torch.zeros(3, 3),
            torch.zeros(3, 3),
            torch.zeros(3, 4),
            torch.zeros(3),
            {"kd": torch.zeros(2)},
        )


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_ply_reader_formats(tmp_path, fmt):
    rng = np.random.default_rng(0)
    points = rng.normal(size=(7, 3)).astype(np.float32)
    colours = rng.integers(0, 256, size=(7, 3)).astype(np.uint8)
    header = (
        f"ply\nformat {fmt} 1.0\ncomment test\nelement vertex 7\nproperty float x\nproperty float "
        "y\nproperty float z\nproperty float nx\nproperty uchar red\nproperty uchar "
        "green\nproperty uchar blue\nelement face 1\nproperty list uchar int "
        "vertex_indices\nend_header\n"
    )
    if fmt == "ascii":
        rows = zip(points.tolist(), colours, strict=True)
        body = "".join(f"{p[0]!r} {p[1]!r} {p[2]!r} 0 {c[0]} {c[1]} {c[2]}\n" for p, c in rows)
        body += "3 0 1 2\n"
        data = (header + body).encode()
    else:
        order = "<" if fmt.endswith("little_endian") else ">"
        table = np.empty(
            7,
            dtype=[
                ("x", order + "f4"),
                ("y", order + "f4"),
                ("z", order + "f4"),
                ("nx", order + "f4"),
                ("r", "u1"),
                ("g", "u1"),
                ("b", "u1"),
            ],
        )
        table["x"], table["y"], table["z"] = points.T
        table["nx"] = 0
        table["r"], table["g"], table["b"] = colours.T
        data = (
            header.encode()
            + table.tobytes()
            + b"\x03"
            + np.array([0, 1, 2], dtype=order + "i4").tobytes()
        )
    (tmp_path / "p.ply").write_bytes(data)
    got_points, got_colours = read_ply_points(tmp_path / "p.ply")
    np.testing.assert_allclose(got_points, points, rtol=1e-6)
    np.testing.assert_allclose(got_colours, colours / 255.0, rtol=1e-6)


def test_ply_writer_roundtrip_and_from_ply(tmp_path):
    points = np.random.default_rng(1).normal(size=(20, 3))
    colours = np.random.default_rng(2).random((20, 3))
    write_ply_points(tmp_path / "c.ply", points, colours)
    got_points, got_colours = read_ply_points(tmp_path / "c.ply")
    np.testing.assert_allclose(got_points, points, rtol=1e-6)
    np.testing.assert_allclose(got_colours, np.round(colours * 255) / 255, atol=1e-6)
    model = GaussianModel.from_ply(tmp_path / "c.ply")
    assert model.num_gaussians == 20 and "colour" in model.attributes


def test_ply_header_counts_are_checked_against_the_files_size_before_reading(tmp_path):
    """A header declaring more points than the file holds (or than any file may) is one error naming
    the file, before anything is allocated (#58); a file that holds exactly what it declares reads,
    ascii without a final newline too."""
    header = (
        b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty "
        b"float z\nend_header\n"
    )
    (tmp_path / "exact.ply").write_bytes(header + b"1 2 3\n4 5 6")
    np.testing.assert_array_equal(
        read_ply_points(tmp_path / "exact.ply")[0], [[1, 2, 3], [4, 5, 6]]
    )
    (tmp_path / "short.ply").write_bytes(header.replace(b"vertex 2", b"vertex 3") + b"1 2 3\n4 5 6")
    with pytest.raises(
        PlyError, match=r"short\.ply: the header declares 3 'vertex' elements, which take at least"
    ):
        read_ply_points(tmp_path / "short.ply")
    binary = header.replace(b"ascii", b"binary_little_endian").replace(
        b"vertex 2", b"vertex 4000000000"
    )
    (tmp_path / "huge.ply").write_bytes(binary + bytes(24))
    with pytest.raises(
        PlyError, match=r"huge\.ply: the header declares 4,000,000,000 'vertex' elements, more than"
    ):
        read_ply_points(tmp_path / "huge.ply")


def test_ply_errors_name_the_file(tmp_path):
    (tmp_path / "a.ply").write_bytes(
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n"
    )
    with pytest.raises(PlyError, match=r"a\.ply: vertex element lacks properties \['y', 'z'\]"):
        read_ply_points(tmp_path / "a.ply")
    (tmp_path / "b.ply").write_bytes(b"not a ply")
    with pytest.raises(PlyError, match="not a PLY file"):
        read_ply_points(tmp_path / "b.ply")
    with pytest.raises(PlyError, match="no such PLY file"):
        read_ply_points(tmp_path / "none.ply")


def test_opacity_and_scale_activations():
    model = GaussianModel.from_points(torch.rand(10, 3), opacity=0.3)
    torch.testing.assert_close(model.opacities, torch.full((10,), 0.3))
    scales = model.scales.detach()
    assert math.isclose(
        float(model.log_scales.detach().exp().mean()), float(scales.mean()), rel_tol=1e-6
    )
