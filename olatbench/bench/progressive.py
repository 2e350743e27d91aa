"""A relight that refines progressively: the image under ``N`` lights
(`olatbench.bench.relight.Relighter`) built a few renders at a time, each intermediate image an
estimate of the final one (the viewer's environment-map mode, docs/viewer.md).

The probes (`Relighter.rendered_probes`: for an environment map the ``N`` importance samples, each
weighted ``1 / N`` of the map's estimate) are rendered in `refinement_order`, a bit-reversal
(van der Corput) permutation of their indices: `sample_map` returns its stratified samples in the
order of their strata, so every prefix of this order takes strata spread over the whole map (the
first 2^m of a power-of-two ``N`` are every ``N / 2^m``-th stratum) rather than its first rows.
After ``n`` of the ``N`` probes the estimate is ``N / n`` × their sum (the average of their ``n``
images, each an estimate of the whole lighting), composited on the background once; after all ``N``
it is the relighter's own image of the same samples (up to the order of the float32 sum).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from olatbench.bench.relight import Relighter
from olatbench.datasets.lighting import SampledLights
from olatbench.datasets.records import Camera


def refinement_order(count: int) -> np.ndarray:
    """The permutation (count,) int of ``range(count)`` in which a progressive relight renders its
    probes: sorted by the base-2 radical inverse of the index (stable), so that every prefix is
    spread over the indices."""
    if count < 1:
        raise ValueError(f"a progressive relight needs at least one light, not {count}")
    index = np.arange(count)
    radical = np.zeros(count)
    digit, scale = index.copy(), 0.5
    while np.any(digit):
        radical += (digit & 1) * scale
        digit, scale = digit >> 1, scale / 2.0
    return np.argsort(radical, kind="stable")


class ProgressiveRelight:
    """The image of ``camera`` under ``lights`` for ``relighter``, refined by `advance`
    (module docstring).

    ``done`` probes have been rendered of ``total`` (after `Relighter.rendered_probes`: 1 for a
    method that ignores the light); `estimate` is the current image, linear (H, W, 3) float32. Not
    thread-safe: one caller advances it.
    """

    def __init__(self, relighter: Relighter, camera: Camera, lights: SampledLights) -> None:
        self.relighter = relighter
        self.camera = camera
        probes = relighter.rendered_probes(lights)
        self.probes = [probes[i] for i in refinement_order(len(probes))]
        self.done = 0
        self._sum: np.ndarray | None = None
        self._empty: np.ndarray | None = None

    @property
    def total(self) -> int:
        return len(self.probes)

    @property
    def finished(self) -> bool:
        return self.done == self.total

    def advance(self, count: int, stop: Callable[[], bool] | None = None) -> int:
        """Render up to ``count`` more probes (fewer when all are done, or when ``stop()`` turns
        true: it is asked before each render); how many were rendered."""
        import torch

        rendered = 0
        with torch.no_grad():
            while rendered < count and not self.finished:
                if stop is not None and stop():
                    break
                lit, self._empty = self.relighter.contribution(self.camera, self.probes[self.done])
                self._sum = lit if self._sum is None else self._sum + lit
                self.done += 1
                rendered += 1
        return rendered

    def estimate(self) -> np.ndarray:
        """The image so far, linear (H, W, 3) float32: ``total / done`` × the rendered probes' sum,
        with the background (a `ValueError` before any probe was rendered)."""
        if self._sum is None or self._empty is None:
            raise ValueError("nothing rendered yet: advance first")
        scale = np.float32(self.total / self.done)
        return self.relighter.composite(
            self._sum if self.finished else self._sum * scale, self._empty
        )


__all__ = ["ProgressiveRelight", "refinement_order"]
