"""``olatbench export``: a finished job's Gaussians in the 3DGS PLY layout, read back with a parser
written here (numpy only) and compared with the checkpoint's tensors (jobs trained in the data's own
frame, so the file holds the tensors as stored), and in world units for a job trained in a fitted
canonical frame."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import test_runner_support as support
import torch
from click.testing import CliRunner
from moved_scenes import ROTATION, SCALE, move_point, move_scene
from trained_jobs import train_tiny

from olatbench.bench.checkpoints import load_checkpoint
from olatbench.bench.execute import run_job
from olatbench.bench.plan import make_plan
from olatbench.bench.restore import read_job
from olatbench.bench.store import list_checkpoints
from olatbench.cli import main
from olatbench.datasets.colour import convert_colourspace

SH_C0 = 1.0 / (2.0 * math.sqrt(math.pi))  # Y_0^0
LAYOUT_HEAD = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]


def parse_ply(path) -> tuple[list[str], list[str], np.ndarray]:
    """(comments, property names, structured vertex array) of a binary little-endian all-float
    PLY."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    lines = data[:end].decode("ascii").splitlines()
    assert lines[:2] == ["ply", "format binary_little_endian 1.0"]
    comments = [line[len("comment ") :] for line in lines if line.startswith("comment ")]
    (count,) = [int(line.split()[2]) for line in lines if line.startswith("element vertex ")]
    names = [line.split()[2] for line in lines if line.startswith("property ")]
    assert all(line.split()[1] == "float" for line in lines if line.startswith("property "))
    table = np.frombuffer(
        data[end:], dtype=np.dtype([(name, "<f4") for name in names]), count=count
    )
    assert len(data) == end + table.nbytes  # nothing after the vertices
    return comments, names, table


def columns(table: np.ndarray, prefix: str, count: int) -> np.ndarray:
    return np.stack([table[f"{prefix}{i}"] for i in range(count)], axis=1)


def final_model(job) -> dict[str, torch.Tensor]:
    _step, path = list_checkpoints(job)[-1]
    return load_checkpoint(path, read_job(job).id)["method"]["model"]


def check_core(table: np.ndarray, model: dict[str, torch.Tensor]) -> None:
    np.testing.assert_array_equal(
        np.stack([table[axis] for axis in "xyz"], axis=1), model["means"].numpy()
    )
    np.testing.assert_array_equal(columns(table, "scale_", 3), model["log_scales"].numpy())
    np.testing.assert_array_equal(columns(table, "rot_", 4), model["quats"].numpy())
    np.testing.assert_array_equal(table["opacity"], model["opacity_logits"].numpy().reshape(-1))
    assert not np.any(np.stack([table[axis] for axis in ("nx", "ny", "nz")]))


@pytest.fixture(scope="module")
def ssdgs_job(tmp_path_factory):
    return train_tiny(
        "ssdgs",
        tmp_path_factory.mktemp("export_ssdgs"),
        iterations=8,
        frame="dataset",
        shadow_resolution=32,
    )


@pytest.fixture(scope="module")
def gs3dgs_job(tmp_path_factory):
    return train_tiny("3dgs", tmp_path_factory.mktemp("export_3dgs"), iterations=8, frame="dataset")


def test_ssdgs_exports_albedo_as_sh_dc_and_its_other_attributes_as_extras(ssdgs_job, tmp_path):
    out = tmp_path / "model.ply"
    result = CliRunner().invoke(main, ["export", str(ssdgs_job), "-o", str(out)])
    assert result.exit_code == 0, result.output
    comments, names, table = parse_ply(out)
    model = final_model(ssdgs_job)
    n = model["means"].shape[0]
    assert len(table) == n and f"{n} Gaussians at step 8" in result.output
    # the 3DGS order: position, normal, colour (degree 3, the higher coefficients zero: no view
    # dependence), opacity, scale, rot
    assert names[: 9 + 45 + 5] == [
        *LAYOUT_HEAD,
        *(f"f_rest_{j}" for j in range(45)),
        "opacity",
        "scale_0",
        "scale_1",
        "scale_2",
        "rot_0",
    ]
    assert not np.any(columns(table, "f_rest_", 45))
    check_core(table, model)
    albedo = torch.nn.functional.softplus(model["attributes.diffuse"]).numpy()
    shown = np.clip(convert_colourspace(albedo, read_job(ssdgs_job).colourspace, "srgb"), 0, 1)
    np.testing.assert_allclose(0.5 + SH_C0 * columns(table, "f_dc_", 3), shown, atol=1e-6)
    extras = {
        name for name in model if name.startswith("attributes.") and name != "attributes.diffuse"
    }
    assert extras  # specular, sss, asg_weights, material, ...
    for key in extras:
        value = model[key].numpy().reshape(n, -1)
        np.testing.assert_array_equal(
            columns(table, f"{key.split('.', 1)[1]}_", value.shape[1]), value
        )
    assert "diffuse_0" not in names and any("albedo" in line for line in comments)


def test_3dgs_exports_its_spherical_harmonics_channel_major(gs3dgs_job, tmp_path):
    out = tmp_path / "model.ply"
    assert CliRunner().invoke(main, ["export", str(gs3dgs_job), "-o", str(out)]).exit_code == 0
    _, names, table = parse_ply(out)
    model = final_model(gs3dgs_job)
    check_core(table, model)
    # (N, 1, 3), (N, 15, 3)
    dc, rest = model["attributes.sh_dc"].numpy(), model["attributes.sh_rest"].numpy()
    np.testing.assert_array_equal(columns(table, "f_dc_", 3), dc[:, 0, :])
    count = rest.shape[1]
    assert count == 15 and sum(name.startswith("f_rest_") for name in names) == 3 * count
    # f_rest_{c·15 + k} is coefficient k+1 of channel c (3DGS's features_rest.transpose)
    for channel in range(3):
        for k in range(count):
            np.testing.assert_array_equal(
                table[f"f_rest_{channel * count + k}"], rest[:, k, channel]
            )
    assert names.index("f_rest_44") < names.index("opacity")
    # encoded as f_dc / f_rest, not repeated
    assert not any(name.startswith("sh_") for name in names)


def test_export_refuses_an_unfinished_job_naming_the_checkpoint(ssdgs_job, tmp_path):
    import shutil

    copy = tmp_path / "job"
    shutil.copytree(ssdgs_job, copy)
    for checkpoint in (copy / "checkpoints").iterdir():
        checkpoint.unlink()
    result = CliRunner().invoke(main, ["export", str(copy), "-o", str(tmp_path / "x.ply")])
    assert (
        result.exit_code == 1
        and "no checkpoint" in result.output
        and not (tmp_path / "x.ply").exists()
    )


def test_export_of_a_folder_that_is_no_job_is_a_usage_error_as_for_render(tmp_path):
    """A folder without job.json was the wrong argument: exit 2 naming the file, as `render` does; a
    job folder that cannot be exported (no checkpoint, above) exits 1."""
    (tmp_path / "empty").mkdir()
    for command in (
        ["export", str(tmp_path / "empty"), "-o", str(tmp_path / "x.ply")],
        ["render", str(tmp_path / "empty"), "-o", str(tmp_path / "videos")],
    ):
        result = CliRunner().invoke(main, command)
        assert result.exit_code == 2 and "job.json: not found" in result.output, (
            command,
            result.output,
        )
    assert not (tmp_path / "x.ply").exists()


def quaternion_matrices(quats: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations of (N, 4) wxyz quaternions (normalised here)."""
    w, x, y, z = (quats / np.linalg.norm(quats, axis=1, keepdims=True)).T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        1,
    )


def test_export_writes_world_units_of_each_dataset(tmp_path):
    """A tiny scene and a copy moved by scale 10, a rotation and a translation
    (tests/moved_scenes.py) train to the same canonical model (to float32 rounding); their files
    hold that model in each dataset's own world units: the copy's centres are the original's moved,
    log-scales + log 10, rotations R · R_i, and the view-dependent colour turned with them (the SH
    function at R u is the original's at u)."""
    from olatbench.methods.baselines.sh import eval_sh

    data = support.write_tiny_data(tmp_path / "data", scenes=("Alpha",))
    move_scene(data / "Alpha", data / "Moved")
    jobs = make_plan(
        "3dgs",
        support.tiny_suite(scenes=("Alpha", "Moved")),
        tmp_path / "runs",
        variants=["mini"],
        iterations=6,
        data_root=data,
        progress=False,
    )
    tables = []
    for job in jobs:
        assert job.frame == "fitted"  # a suite that is not built in
        job = replace(
            job, config={**job.config, "num_init_gaussians": 200, "sh_increase_interval": 2}
        ).with_id()
        assert run_job(job, progress=False).status == "done"
        out = tmp_path / f"{job.scene}.ply"
        assert CliRunner().invoke(main, ["export", job.folder, "-o", str(out)]).exit_code == 0
        tables.append(parse_ply(out)[2])
    original, copy = tables
    means = np.stack([original[axis] for axis in "xyz"], axis=1).astype(np.float64)
    copy_means = np.stack([copy[axis] for axis in "xyz"], axis=1)
    np.testing.assert_allclose(
        copy_means, np.stack([move_point(m) for m in means]), rtol=1e-4, atol=1e-3
    )
    np.testing.assert_allclose(
        columns(copy, "scale_", 3), columns(original, "scale_", 3) + np.log(SCALE), atol=1e-3
    )
    np.testing.assert_allclose(
        quaternion_matrices(columns(copy, "rot_", 4).astype(np.float64)),
        ROTATION @ quaternion_matrices(columns(original, "rot_", 4).astype(np.float64)),
        atol=1e-3,
    )

    # f_rest_{c·15 + k}: coefficient k + 1 of channel c
    def sh(table):
        rest = columns(table, "f_rest_", 45).reshape(-1, 3, 15).transpose(0, 2, 1)
        return torch.as_tensor(
            np.concatenate([columns(table, "f_dc_", 3)[:, None], rest], 1), dtype=torch.float64
        )

    # the view-dependent colour trained
    assert np.abs(columns(original, "f_rest_", 45)).max() > 1e-4
    dirs = torch.nn.functional.normalize(torch.randn(len(original), 3, dtype=torch.float64), dim=-1)
    torch.testing.assert_close(
        eval_sh(3, sh(copy), dirs @ torch.as_tensor(ROTATION).T),
        eval_sh(3, sh(original), dirs),
        rtol=1e-3,
        atol=1e-4,
    )
