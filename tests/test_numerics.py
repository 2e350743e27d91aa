"""The numerics pins: set before torch is imported, never over a user's choice, recorded with the
CPU's id; the CPUs the README's seed-0 figures were measured on, as data the README, docs/runner.md
and ``olatbench doctor`` follow."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from olatbench import numerics

X86 = platform.machine().lower() in ("x86_64", "amd64")
ROOT = Path(__file__).resolve().parents[1]


def run_python(code: str, **env: str) -> str:
    environment = {k: v for k, v in os.environ.items() if k not in numerics.ROUNDING_ENV} | env
    return subprocess.run(
        [sys.executable, "-c", code], env=environment, capture_output=True, text=True, check=True
    ).stdout.strip()


@pytest.mark.skipif(not X86, reason="the pin applies to x86_64 only")
def test_the_command_pins_torch_to_avx2_before_importing_it():
    code = (
        "from olatbench.cli import main\nimport sys\ntry:\n    main(['doctor', '--help'])\nexcept "
        "SystemExit:\n    pass\nimport torch, os\nprint(os.environ.get('ATEN_CPU_CAPABILITY'), "
        "torch.backends.cpu.get_cpu_capability())"
    )
    assert run_python(code).splitlines()[-1] == "avx2 AVX2"  # after the help text


def test_a_users_choice_and_an_imported_torch_are_left_alone():
    assert (
        run_python(
            "from olatbench.numerics import pin_numerics; "
            "print(pin_numerics()['ATEN_CPU_CAPABILITY'])",
            ATEN_CPU_CAPABILITY="default",
        )
        == "default"
    )
    assert run_python(
        "import torch\nfrom olatbench.numerics import pin_numerics\n"
        # too late: torch already chose
        "print(pin_numerics())"
    ) == str(dict.fromkeys(numerics.PINS))


def test_cpu_numerics_reports_what_is_in_effect():
    record = json.loads(
        run_python(
            "import json\nfrom olatbench.numerics import cpu_numerics, pin_numerics\n"
            "pin_numerics()\nprint(json.dumps(cpu_numerics()))",
            MKL_CBWR="AUTO",
        )
    )
    assert record["torch_threads"] >= 1 and isinstance(record["cpu_flags"], list)
    # set / unset, both recorded
    assert record["MKL_CBWR"] == "AUTO" and record["ONEDNN_MAX_CPU_ISA"] is None
    assert set(record["cpu_id"]) == {"vendor", "family", "model", "stepping"}
    assert set(record["torch_libraries"]) == {"mkl", "onednn"}
    if X86:
        assert record["torch_cpu_capability"] == "AVX2" and "avx2" in record["cpu_flags"]
        assert record["cpu_id"]["vendor"] is not None and isinstance(
            record["cpu_id"]["family"], int
        )


INTEL = """processor\t: 0
vendor_id\t: GenuineIntel
cpu family\t: 6
model\t\t: 207
model name\t: Intel(R) Xeon(R) Processor
stepping\t: 2
flags\t\t: fpu sse4_2 avx avx2 fma avx512f avx512_vnni

processor\t: 1
vendor_id\t: OtherVendor
cpu family\t: 99
"""
ARM = """processor\t: 0
BogoMIPS\t: 50.00
Features\t: fp asimd evtstrm
CPU implementer\t: 0x41
CPU architecture: 8
CPU variant\t: 0x3
CPU part\t: 0xd0c
CPU revision\t: 1
"""


def test_cpu_id_reads_the_first_processor():
    assert numerics.cpu_id(INTEL) == {
        "vendor": "GenuineIntel",
        "family": 6,
        "model": 207,
        "stepping": 2,
    }
    assert numerics.cpu_id(ARM) == {"vendor": "0x41", "family": 8, "model": "0xd0c", "stepping": 1}
    assert numerics.cpu_id("") == dict.fromkeys(("vendor", "family", "model", "stepping"))
    assert numerics.cpu_flags(INTEL) == ["sse4_2", "avx", "avx2", "fma", "avx512f", "avx512_vnni"]


def here(**changes) -> dict:
    """cpu_numerics() of a made-up Intel machine with the olatbench pins and 2 threads, changed by
    ``changes``."""
    return {
        "cpu_id": numerics.cpu_id(INTEL),
        "cpu_flags": numerics.cpu_flags(INTEL),
        "torch_threads": 2,
        **dict.fromkeys(numerics.ROUNDING_ENV),
        **numerics.PINS,
        **changes,
    }


def test_seed_figure_run_finds_this_cpus_run_and_says_what_differs():
    runs = [
        {
            "cpu": {"vendor": "AuthenticAMD", "family": 25, "model": None, "stepping": None},
            "flags": ["avx2"],
            "threads": None,
            "pins": dict(numerics.PINS),
        },
        {
            "cpu": {"vendor": "GenuineIntel", "family": 6, "model": 207, "stepping": 2},
            "flags": ["avx2", "avx512f"],
            "threads": 2,
            "pins": dict(numerics.PINS),
        },
    ]
    assert numerics.seed_figure_run(here(), runs) == (runs[1], [])
    run, differences = numerics.seed_figure_run(
        here(torch_threads=8, ATEN_CPU_CAPABILITY="avx512"), runs
    )
    assert run is runs[1] and differences == [
        "ATEN_CPU_CAPABILITY: avx512 here, avx2 there",
        "torch threads: 8 here, 2 there",
    ]
    other_stepping = here(cpu_id={**numerics.cpu_id(INTEL), "stepping": 3})
    assert numerics.seed_figure_run(other_stepping, runs) == (None, [])
    amd = here(
        cpu_id={"vendor": "AuthenticAMD", "family": 25, "model": 17, "stepping": 1},
        torch_threads=16,
    )
    # model, stepping and threads not recorded there
    assert numerics.seed_figure_run(amd, runs) == (runs[0], [])


def test_the_readme_and_the_runner_docs_quote_every_measured_cpu():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    runner = (ROOT / "docs" / "runner.md").read_text(encoding="utf-8")
    runs = numerics.seed_figure_runs()
    # one run per CPU
    assert len({json.dumps(run["cpu"], sort_keys=True) for run in runs}) == len(runs)
    for run in runs:
        quoted = " / ".join(
            "—" if run["psnr"][scene] is None else f"{run['psnr'][scene]:.4f}"
            # —: not measured yet
            for scene in ("diffuse_shadow", "aniso_metal", "translucent")
        )
        label = numerics.cpu_label(run["cpu"])
        for name, text in (("README.md", readme), ("docs/runner.md", runner)):
            assert quoted in text and run["date"] in text and label in text, (name, quoted, label)
