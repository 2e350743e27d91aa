"""The one rule that fits an iteration count written for one run length to another.

Schedules, learning-rate windows and density-control windows are written for a reference length (the
paper's 100K or 60K steps, the official scripts' flags) and a shorter or longer run takes them ×
``iterations / reference_iterations``. The native methods (`GaussianConfig.steps`,
`Schedule.scaled`) and the official runner (`OfficialCode.scaled_schedule`,
`OfficialCode.milestone_values`) call `scaled_steps`, so a native config given the authors' values
(``--variant official``) and the authors' flags compressed for their code land on the same steps.
"""

from __future__ import annotations


def scaled_steps(value: int, iterations: int, reference_iterations: int) -> int:
    """``value`` (steps in a run of ``reference_iterations``) in a run of ``iterations``:
    ``value × (iterations / reference_iterations)`` rounded to the nearest integer (halves to even,
    Python's `round`), and at least 1 where ``value`` is positive (the official scripts take some of
    them modulo; a positive window never vanishes). 0 stays 0."""
    scaled = round(value * (iterations / reference_iterations))
    return max(scaled, 1) if value > 0 else scaled
