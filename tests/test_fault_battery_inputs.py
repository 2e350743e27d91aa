"""The input fault battery (#58): bad sizes, names, devices and project files, each met where it
enters, give one clear error naming the flag, file or field, the documented exit code and no
traceback, before anything is allocated, trained or written (nothing outside the output folder,
ever).

Faults: image sizes (`CAMERA_PATH_SIZES` in a camera path, `SIZE_OPTIONS` on the command line and in
olatbench.toml and transforms files: below one pixel, 1e12, 100000, ...), names that would leave the
output folder or take another's (`SUITE_NAMES`, and every name `job_folder` makes a folder of),
devices (`DEVICES`, each met by `DEVICE_VERBS`), olatbench.toml that is not UTF-8 or names an
unknown protocol, ``report --figures`` into a folder that cannot be written (`FIGURE_FOLDERS`), and
names mistyped or ambiguous (`NAME_FAULTS`). The number of faults is `FAULT_COUNT`, stated in
docs/guarantees.md.
"""

from __future__ import annotations

import errno
import json
import subprocess
import sys
from pathlib import Path

import pytest
import test_runner_support as support
import torch
from datasets_trees import write_nrhints_tree
from test_fault_battery_runner import SimulatedFault, assert_one_clear_error, run_cli

from olatbench.bench.store import job_folder
from olatbench.datasets import suites

ROOT = Path(__file__).resolve().parents[1]
#: a device torch has no way to use on this machine (no CUDA build, or one index past its GPUs)
MISSING_DEVICE = f"cuda:{torch.cuda.device_count()}" if torch.cuda.is_available() else "cuda"


@pytest.fixture(autouse=True)
def tiny_suite(monkeypatch):
    """The tiny suite registered as 'tiny' for the CLI."""
    monkeypatch.setitem(suites.SUITES, "tiny", support.tiny_suite())


@pytest.fixture(autouse=True)
def working_folder(tmp_path, monkeypatch):
    """The test's folder is the working folder, so olatbench.toml written there is the one read."""
    monkeypatch.chdir(tmp_path)


@pytest.fixture(scope="module")
def gaussian_job(tmp_path_factory) -> Path:
    """A finished 3DGS job (4 steps on a 64×48 scene)."""
    from trained_jobs import train_tiny

    return train_tiny("3dgs", tmp_path_factory.mktemp("input_faults"), iterations=4)


def files_below(folder: Path) -> set[Path]:
    return {path.relative_to(folder) for path in folder.rglob("*")}


def write_project_file(folder: Path, text: str | bytes) -> None:
    path = folder / "olatbench.toml"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())


# ---- sizes ---------------------------------------------------------------------------------------

# name: (render_width, render_height, phrase of the message, run in a child process)
CAMERA_PATH_SIZES = {
    "below one pixel": (
        0.5,
        16,
        "render_width: expected a whole number of pixels from 1 to 16384, not 0.5",
        True,
    ),
    "1e12": (1e12, 16, "render_width: 1000000000000 pixels is outside 1 to 16384", False),
    "100000": (100_000, 16, "render_width: 100000 pixels is outside 1 to 16384", False),
    "a height of 100000": (
        16,
        100_000,
        "render_height: 100000 pixels is outside 1 to 16384",
        False,
    ),
    "true": (
        True,
        16,
        "render_width: expected a whole number of pixels from 1 to 16384, not True",
        False,
    ),
    "text": (
        "640",
        16,
        "render_width: expected a whole number of pixels from 1 to 16384, not '640'",
        False,
    ),
}


@pytest.mark.parametrize("case", list(CAMERA_PATH_SIZES))
def test_a_camera_path_size_out_of_bounds_is_refused_before_rendering(gaussian_job, tmp_path, case):
    """Before #58 a width below one pixel ended the process with SIGSEGV (hence the child process),
    1e12 raised an OverflowError and 100000 failed in the video encoder after rendering."""
    width, height, phrase, child = CAMERA_PATH_SIZES[case]
    path = tmp_path / "path.json"
    frame = {"camera_to_world": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 4, 0, 0, 0, 1], "fov": 40}
    path.write_text(
        json.dumps(
            {"render_width": width, "render_height": height, "fps": 10, "camera_path": [frame]}
        )
    )
    args = [
        "render",
        gaussian_job,
        "--camera-path",
        path,
        "-o",
        tmp_path / "video",
        "--quiet",
        "--device",
        "cpu",
    ]
    if child:
        done = subprocess.run(
            [sys.executable, "-m", "olatbench", *map(str, args)],
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert done.returncode == 2, (done.returncode, done.stderr)
        assert "Traceback" not in done.stderr and f"{path}: {phrase}" in done.stderr, done.stderr
    else:
        assert_one_clear_error(run_cli(*args), 2, f"{path}: {phrase}")
    assert not (tmp_path / "video").exists()


def _toml_resolution(value: str):
    def make(folder: Path) -> list[str | Path]:
        write_nrhints_tree(folder / "Cup", n_train=3, n_test=1, size=(16, 12))
        write_project_file(folder, f'[suites.mine]\nscenes = ["Cup"]\nresolution = {value}\n')
        return ["run", "-m", "trivial", "-s", "mine", "-o", folder / "runs", "--dry-run"]

    return make


def _transforms_width(folder: Path) -> list[str | Path]:
    write_nrhints_tree(folder / "Cup", n_train=3, n_test=1, size=(16, 12))
    transforms = folder / "Cup" / "transforms_train.json"
    transforms.write_text(json.dumps({**json.loads(transforms.read_text()), "w": 0.5, "h": 12}))
    return ["datasets", "info", folder / "Cup"]


SIZE_OPTIONS = {  # name: (arguments made in a folder, exit code, phrases of the message)
    "render --resolution 100000": (
        lambda folder: ["render", folder, "--resolution", "100000"],
        2,
        ("'--resolution': 100000 pixels is outside 1 to 16384",),
    ),
    "render --resolution 0": (
        lambda folder: ["render", folder, "--resolution", "0x48"],
        2,
        ("'--resolution': width: 0 pixels is outside 1 to 16384",),
    ),
    "run --resolution 20000x10": (
        lambda folder: [
            "run",
            "-m",
            "trivial",
            "-s",
            "tiny",
            "--resolution",
            "20000x10",
            "--dry-run",
        ],
        2,
        ("'--resolution': width: 20000 pixels is outside 1 to 16384",),
    ),
    "synth --resolution 100000": (
        lambda folder: [
            "datasets",
            "synth",
            "--recipe",
            "nope",
            "--resolution",
            "100000",
            "-o",
            folder / "synth",
        ],
        2,
        ("'--resolution': 100000 pixels is outside 4 to 16384",),
    ),
    "view --max-resolution 100000": (
        lambda folder: ["view", folder, "--max-resolution", "100000"],
        2,
        ("'--max-resolution': 100000 is not in the range 8<=x<=16384",),
    ),
    "olatbench.toml resolution 100000": (
        _toml_resolution('"100000"'),
        2,
        (
            "olatbench.toml [suites.mine]: resolution must be",
            "(100000 pixels is outside 1 to 16384)",
        ),
    ),
    "olatbench.toml resolution [0.5, 3]": (
        _toml_resolution("[0.5, 3]"),
        2,
        (
            "olatbench.toml [suites.mine]: resolution must be",
            "(width: expected a whole number of pixels from 1 to 16384, not 0.5)",
        ),
    ),
    "olatbench.toml resolution [20000, 10]": (
        _toml_resolution("[20000, 10]"),
        2,
        ("(width: 20000 pixels is outside 1 to 16384)",),
    ),
    "transforms w 0.5": (
        _transforms_width,
        1,
        (
            "transforms_train.json",
            "'w'",
            "expected a whole number of pixels from 1 to 16384, not 0.5",
        ),
    ),
}


@pytest.mark.parametrize("case", list(SIZE_OPTIONS))
def test_a_size_out_of_bounds_is_one_error_naming_where_it_was_given(tmp_path, case):
    """Before #58 each of these was accepted (the suite's 100000 reached OpenCV, asking for 160
    GB)."""
    make, code, phrases = SIZE_OPTIONS[case]
    assert_one_clear_error(run_cli(*make(tmp_path)), code, *phrases)
    assert not (tmp_path / "runs").exists() and not (tmp_path / "synth").exists()


# ---- names that become folders -------------------------------------------------------------------

SUITE_NAMES = {  # the TOML key: (the name, the reason given)
    '"../escaped"': ("../escaped", "it holds a path separator"),
    '""': ("", "it is empty"),
    '".."': ("..", "'..' is not a folder of its own"),
    '"a/b"': ("a/b", "it holds a path separator"),
    '"tab\\tname"': ("tab\tname", "it holds a control character"),
}


@pytest.mark.parametrize("key", list(SUITE_NAMES))
def test_a_suite_name_that_cannot_be_one_folder_writes_nothing(tmp_path, key):
    """Before #58 ``run -s ../escaped`` wrote its jobs beside the output folder and ``-s ''`` where
    a suite's folder belongs."""
    name, reason = SUITE_NAMES[key]
    write_nrhints_tree(tmp_path / "Cup", n_train=3, n_test=1, size=(16, 12))
    write_project_file(tmp_path, f'[suites.{key}]\nscenes = ["Cup"]\n')
    before = files_below(tmp_path)
    result = run_cli(
        "run",
        "-m",
        "trivial",
        "-s",
        name,
        "-o",
        tmp_path / "out" / "runs",
        "--quiet",
        "--device",
        "cpu",
        "--iterations",
        "2",
    )
    assert_one_clear_error(
        result,
        2,
        f"olatbench.toml [suites.{key}]: suite name {name!r} cannot name a folder: {reason}",
    )
    assert files_below(tmp_path) == before


@pytest.mark.parametrize("kind", ["suite", "method", "variant", "scene"])
def test_every_name_of_a_job_folder_is_one_folder_below_the_output(tmp_path, kind):
    """A name from Python (a plugin's method or preset, a suite made in a notebook) meets the same
    check."""
    names = {"suite": "s", "method": "m", "variant": "default", "scene": "Cup"}
    for bad in ("..", "", "a/b", "a\\b", "x" * 256):
        with pytest.raises(ValueError, match=f"{kind} name .* cannot name a folder"):
            job_folder(tmp_path, **{**names, kind: bad}, seed=0)
    assert (
        job_folder(tmp_path, **names, seed=0) == tmp_path / "s" / "m" / "default" / "Cup" / "seed0"
    )
    if kind == "method":  # a plugin's spec is refused where it is declared
        from olatbench.methods.spec import MethodSpec

        with pytest.raises(ValueError, match=r"method name '\.\./x' cannot name a folder"):
            MethodSpec(name="../x", description="", implementation="m:C", config="m:D")


# ---- devices -------------------------------------------------------------------------------------

DEVICES = {  # --device: phrase of the message
    "nope": "unknown device 'nope': expected auto, cpu, cuda, mps, xpu",
    "cuda:x": "unknown device 'cuda:x'",
    MISSING_DEVICE: f"device '{MISSING_DEVICE}' is not usable here",
}
DEVICE_VERBS = {
    "render": lambda job, out: ["render", job, "--frames", "1", "-o", out, "--quiet"],
    "export": lambda job, out: ["export", job, "--under-light", "0", "-o", out / "lit.ply"],
    "view --record": lambda job, out: [
        "view",
        job,
        "--record",
        "light-orbit",
        out / "orbit.mp4",
        "--frames",
        "1",
    ],
    "run": lambda job, out: [
        "run",
        "-m",
        "trivial",
        "-s",
        "tiny",
        "--data-root",
        support.write_tiny_data(out.parent / "data"),
        "-o",
        out,
        "--quiet",
    ],
}


@pytest.mark.parametrize("verb", list(DEVICE_VERBS))
@pytest.mark.parametrize("device", list(DEVICES))
def test_a_device_this_machine_cannot_use_is_refused_up_front(gaussian_job, tmp_path, verb, device):
    """Before #58 render, export and view printed torch's traceback, and run failed each job on
    it."""
    out = tmp_path / "out"
    result = run_cli(*DEVICE_VERBS[verb](gaussian_job, out), "--device", device)
    assert_one_clear_error(result, 2, "Invalid value for '--device'", DEVICES[device])
    assert not out.exists()


# ---- olatbench.toml ------------------------------------------------------------------------------

PROJECT_FILES = {  # name: (content, phrases)
    "not UTF-8": (
        b'[suites.mine]\nscenes = ["Cup\xff"]\n',
        ("olatbench.toml: not UTF-8 text (byte 0xff at offset",),
    ),
    "an unknown protocol": (
        '[suites.mine]\nscenes = ["Cup"]\nprotocol = "nrhint"\n',
        (
            "olatbench.toml [suites.mine]: protocol: unknown metric protocol 'nrhint' (did you "
            "mean 'nrhints'?)",
        ),
    ),
}


@pytest.mark.parametrize("case", list(PROJECT_FILES))
def test_a_bad_project_file_is_one_error_naming_it(tmp_path, case):
    text, phrases = PROJECT_FILES[case]
    write_nrhints_tree(tmp_path / "Cup", n_train=3, n_test=1, size=(16, 12))
    write_project_file(tmp_path, text)
    result = run_cli("run", "-m", "trivial", "-s", "mine", "-o", tmp_path / "runs", "--dry-run")
    assert_one_clear_error(result, 2, *phrases)


# ---- report --figures into a folder that cannot be written ---------------------------------------

FIGURE_FOLDERS = ("below a regular file", "read-only")


@pytest.mark.parametrize("case", FIGURE_FOLDERS)
def test_report_figures_into_an_unwritable_folder_is_one_line(
    gaussian_job, tmp_path, monkeypatch, case
):
    """Root ignores file modes, so read-only is a folder below a regular file, or writes that raise
    EROFS."""
    (tmp_path / "a-file").write_text("mine")
    if case == "below a regular file":
        page, reason = tmp_path / "a-file" / "report.html", "Not a directory"
    else:
        page, reason = tmp_path / "out" / "report.html", "Read-only file system"
        SimulatedFault(monkeypatch, tmp_path / "out", errno.EROFS).on()
    result = run_cli("report", gaussian_job.parents[4], "-o", page, "--figures", "png")
    assert_one_clear_error(result, 1, "cannot write", reason, "choose another -o")
    assert (tmp_path / "a-file").read_text() == "mine" and not (tmp_path / "out").exists()


# ---- names mistyped or ambiguous -----------------------------------------------------------------


def _report(*extra: str):
    return lambda job, folder: ["report", job.parents[4], *extra]


def _own_suites(text: str):
    def make(job: Path, folder: Path) -> list[str | Path]:
        write_nrhints_tree(folder / "Cup", n_train=3, n_test=1, size=(16, 12))
        write_project_file(folder, text)
        return ["run", "-m", "trivial", "-s", "mine", "-o", folder / "runs", "--dry-run"]

    return make


def _case_twin_scenes(job: Path, folder: Path) -> list[str | Path]:
    write_nrhints_tree(folder / "a" / "Cup", n_train=3, n_test=1, size=(16, 12))
    write_nrhints_tree(folder / "b" / "cup", n_train=3, n_test=1, size=(16, 12))
    return [
        "run",
        "-m",
        "trivial",
        "--data",
        folder / "a" / "Cup",
        "--data",
        folder / "b" / "cup",
        "--dry-run",
    ]


def _own_data(*extra: str):
    def make(job: Path, folder: Path) -> list[str | Path]:
        write_nrhints_tree(folder / "Cup", n_train=3, n_test=1, size=(16, 12))
        return [
            "run",
            "-m",
            "trivial",
            "--data",
            folder / "Cup",
            "-o",
            folder / "runs",
            "--dry-run",
            *extra,
        ]

    return make


NAME_FAULTS = {  # name: (arguments from the job and a folder, phrases of the usage error)
    "report --metrics pnsr": (
        _report("--metrics", "pnsr"),
        ("--metrics: unknown metric 'pnsr' (did you mean 'psnr'?)",),
    ),
    "report --splits tets": (
        _report("--splits", "tets"),
        ("--splits: unknown split 'tets' (did you mean 'test'?)",),
    ),
    "report --methods 3dgs,nope": (
        _report("--methods", "3dgs,nope"),
        ("--methods: unknown method 'nope'",),
    ),
    "report --metrics ''": (_report("--metrics", ""), ("'--metrics': '' names nothing",)),
    "run --protocol nrhint": (
        _own_data("--protocol", "nrhint"),
        ("unknown metric protocol 'nrhint' (did you mean 'nrhints'?)",),
    ),
    "status -s data-nrhint": (
        lambda job, folder: ["status", job.parents[4], "-s", "data-nrhint"],
        ("unknown suite 'data-nrhint' (did you mean 'data-nrhints'",),
    ),
    "run --variant ablation-A+": (
        lambda job, folder: [
            "run",
            "-m",
            "trivial",
            "-s",
            "tiny",
            "--variant",
            "ablation-A+",
            "--dry-run",
        ],
        ("variant 'ablation-A+' has an empty preset name",),
    ),
    "run --scenes ''": (
        lambda job, folder: ["run", "-m", "trivial", "-s", "tiny", "--scenes", "", "--dry-run"],
        ("'--scenes': '' names nothing",),
    ),
    "two suites one folder ignoring case": (
        _own_suites('[suites.mine]\nscenes = ["Cup"]\n[suites.MINE]\nscenes = ["Cup"]\n'),
        ("[suites.MINE]: the name is taken (as 'mine', ignoring case",),
    ),
    "a suite named like a built-in": (
        _own_suites('[suites.Mini]\nscenes = ["Cup"]\n[suites.mine]\nscenes = ["Cup"]\n'),
        ("[suites.Mini]: the name is taken (as 'mini', ignoring case",),
    ),
    "two scene folders one folder ignoring case": (
        _case_twin_scenes,
        ("two scene folders are named 'Cup' and 'cup' (one folder ignoring case",),
    ),
}


@pytest.mark.parametrize("case", list(NAME_FAULTS))
def test_a_mistyped_or_ambiguous_name_is_a_usage_error(gaussian_job, tmp_path, case):
    """Before #58 --metrics pnsr and --splits tets gave a table of empty cells (exit 0), the others
    no or the wrong "did you mean", an empty preset name, every scene, or two things in one
    folder."""
    make, phrases = NAME_FAULTS[case]
    assert_one_clear_error(run_cli(*make(gaussian_job, tmp_path)), 2, *phrases)


def test_report_methods_match_names_ignoring_case_as_run_does(gaussian_job):
    """``run -m 3DGS`` runs 3dgs; ``report --methods 3DGS`` found nothing before #58."""
    result = run_cli(
        "report",
        gaussian_job.parents[4],
        "--methods",
        "3DGS",
        "--metrics",
        "PSNR",
        "--splits",
        "Test",
    )
    assert result.exit_code == 0, result.output
    assert "3dgs" in result.output and "PSNR" in result.output


FAULT_COUNT = (
    len(CAMERA_PATH_SIZES)
    + len(SIZE_OPTIONS)
    + len(SUITE_NAMES)
    + 1
    + len(DEVICES) * len(DEVICE_VERBS)
    + len(PROJECT_FILES)
    + len(FIGURE_FOLDERS)
    + len(NAME_FAULTS)
    + 1
)


def test_the_battery_states_its_fault_count_in_the_docs():
    text = (ROOT / "docs" / "guarantees.md").read_text(encoding="utf-8")
    assert f"input fault battery: {FAULT_COUNT} faults" in text, FAULT_COUNT
