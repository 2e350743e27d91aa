"""Shared by the benchmarks that time a C++ kernel against its torch reference in one process
(``bench_ssim.py``, ``bench_shading.py``): interleaved fastest-of-N timing and the speed-up
table."""

from __future__ import annotations

import time
from collections.abc import Callable

BACKENDS = ("torch", "cpu")
KINDS = ("fwd", "fwdbwd")


def fastest_ms(runs: dict[str, Callable[[], None]], repeats: int) -> dict[str, float]:
    """Fastest wall-clock ms of each callable over ``repeats`` rounds (one call of each per round,
    after a warm-up that also builds the C++ library on first use)."""
    best = dict.fromkeys(runs, float("inf"))
    for fn in runs.values():
        fn()
    for _ in range(repeats):
        for name, fn in runs.items():
            start = time.perf_counter()
            fn()
            best[name] = min(best[name], (time.perf_counter() - start) * 1e3)
    return best


class SpeedupTable:
    """Rows of fwd / fwd+bwd ms per backend at each problem size, the cpu-over-torch speed-ups and
    whether the two backends agreed; ``summary`` is the script's last, parseable line."""

    def __init__(self, size_label: str) -> None:
        self.size_label = size_label
        self.values: dict[str, float] = {}
        self.sizes: list[int] = []
        self.agree = True
        print(f"{size_label:>6} {'backend':>8} {'fwd':>8} {'fwd+bwd':>8}")

    def measure(
        self, size: int, make_step: Callable[[str, bool], Callable[[], None]], repeats: int
    ) -> str:
        """Time ``make_step(backend, backward)`` for both backends and kinds; print the rows; return
        the speed-ups as text."""
        runs = {f"{b}_{kind}": make_step(b, kind == "fwdbwd") for b in BACKENDS for kind in KINDS}
        best = fastest_ms(runs, repeats)
        for backend in BACKENDS:
            fwd, fwdbwd = best[f"{backend}_fwd"], best[f"{backend}_fwdbwd"]
            print(f"{size:>6} {backend:>8} {fwd:>8.3f} {fwdbwd:>8.3f}")
            self.values[f"{backend}_fwd_{size}_ms"], self.values[f"{backend}_fwdbwd_{size}_ms"] = (
                fwd,
                fwdbwd,
            )
        for kind in KINDS:
            self.values[f"speedup_{kind}_{size}"] = best[f"torch_{kind}"] / best[f"cpu_{kind}"]
        self.sizes.append(size)
        return (
            f"cpu/torch speed-up: fwd {self.values[f'speedup_fwd_{size}']:.1f}x, "
            f"fwd+bwd {self.values[f'speedup_fwdbwd_{size}']:.1f}x"
        )

    def summary(self, name: str, threads: int, target: float) -> str:
        """``SUMMARY <name> threads=.. key=value ... target=.. values_agree=..
        status=ok|below-target``."""
        met = min(self.values[f"speedup_fwdbwd_{size}"] for size in self.sizes) >= target
        fields = " ".join(f"{k}={v:.3f}" for k, v in self.values.items())
        return (
            f"SUMMARY {name} threads={threads} {fields} target={target} "
            f"values_agree={'yes' if self.agree else 'NO'} "
            f"status={'ok' if met and self.agree else 'below-target'}"
        )
