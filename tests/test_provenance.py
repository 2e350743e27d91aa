"""Hardware identity read from /proc/cpuinfo, checked on hand-written files of known machines."""

from __future__ import annotations

import os

from olatbench.bench.provenance import cpu_identity, hardware_identity

TWO_SOCKETS = "".join(
    f"processor\t: {index}\nmodel name\t: Intel(R) Xeon(R) Gold 6230 CPU @ 2.10GHz\nphysical id\t: "
    f"{socket}\ncore id\t\t: {core}\n\n"
    for index, (socket, core) in enumerate(
        (s, c) for _ in range(2) for s in range(2) for c in range(4)
    )
)


def test_two_sockets_with_hyperthreads_count_physical_cores(tmp_path):
    """16 logical CPUs = 2 sockets × 4 cores × 2 threads: 8 physical cores
    (core ids repeat across sockets)."""
    path = tmp_path / "cpuinfo"
    path.write_text(TWO_SOCKETS)
    cpu = cpu_identity(path)
    assert cpu["model"] == "Intel(R) Xeon(R) Gold 6230 CPU @ 2.10GHz" and cpu["cores"] == 8
    assert cpu["threads"] == os.cpu_count()


def test_missing_cpuinfo_gives_nulls_not_an_error(tmp_path):
    cpu = cpu_identity(tmp_path / "absent")
    assert cpu["cores"] is None and cpu["threads"] == os.cpu_count()


def test_hardware_identity_has_every_key():
    identity = hardware_identity()
    assert set(identity) == {"machine", "cpu", "gpus", "numerics"} and isinstance(
        identity["gpus"], list
    )
    import torch

    assert identity["numerics"]["torch_cpu_capability"] == torch.backends.cpu.get_cpu_capability()
    assert identity["numerics"]["torch_threads"] == torch.get_num_threads()
