"""Which ablation grid a job belongs to and the variant it is compared with, as the reports need it.

Every planned job records both in its job.json (``Job.ablation``: ``{"grid", "reference"}`` from the
method's spec, `olatbench.methods.spec.MethodSpec.ablation_of`; ``null`` outside every grid). A
job.json written before the field existed has no ``ablation`` key, and a results.json may have no
job.json beside it: for those the method's spec is asked now, with the job's variant, as the plan
would have asked it (None when the method is not installed here). The reports read it only through
`job_ablation`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from olatbench.methods.registry import get_spec

#: The job.json key (`olatbench.bench.jobs.Job.ablation`).
ABLATION_KEY = "ablation"


def job_ablation(
    job_file: Mapping[str, Any] | None, method: str, variant: str
) -> dict[str, str] | None:
    """``{"grid", "reference"}`` of a job of ``method`` and ``variant`` (its label, ``~overrides``
    allowed) whose job.json is ``job_file`` (None: no job.json), or None when it belongs to no
    ablation grid."""
    if job_file is not None and ABLATION_KEY in job_file:
        recorded = job_file[ABLATION_KEY]
        return dict(recorded) if isinstance(recorded, Mapping) else None
    try:
        spec = get_spec(method)
    except (KeyError, ImportError):
        return None
    return spec.ablation_of(variant)
