"""The CPU kernel-width pin: set before torch is imported, never over a user's choice, recorded."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys

import pytest

from olatbench import numerics

X86 = platform.machine().lower() in ("x86_64", "amd64")


def run_python(code: str, **env: str) -> str:
    environment = {k: v for k, v in os.environ.items() if k != numerics.CAPABILITY_ENV} | env
    return subprocess.run([sys.executable, "-c", code], env=environment, capture_output=True, text=True,
                          check=True).stdout.strip()


@pytest.mark.skipif(not X86, reason="the pin applies to x86_64 only")
def test_the_command_pins_torch_to_avx2_before_importing_it():
    code = ("from olatbench.cli import main\nimport sys\n"
            "try:\n    main(['doctor', '--help'])\nexcept SystemExit:\n    pass\n"
            "import torch, os\nprint(os.environ.get('ATEN_CPU_CAPABILITY'), torch.backends.cpu.get_cpu_capability())")
    assert run_python(code).splitlines()[-1] == "avx2 AVX2"  # after the help text


def test_a_users_choice_and_an_imported_torch_are_left_alone():
    assert run_python("from olatbench.numerics import pin_cpu_capability; print(pin_cpu_capability())",
                      ATEN_CPU_CAPABILITY="default") == "default"
    assert run_python("import torch\nfrom olatbench.numerics import pin_cpu_capability\n"
                      "print(pin_cpu_capability())") == "None"  # too late: torch already chose


def test_cpu_numerics_reports_what_is_in_effect():
    record = json.loads(run_python("import json\nfrom olatbench.numerics import cpu_numerics, pin_cpu_capability\n"
                                   "pin_cpu_capability()\nprint(json.dumps(cpu_numerics()))"))
    assert record["torch_threads"] >= 1 and isinstance(record["cpu_flags"], list)
    if X86:
        assert record["torch_cpu_capability"] == "AVX2" and "avx2" in record["cpu_flags"]
