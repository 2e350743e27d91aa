"""Whether an official implementation's job scored test views it fitted, for results.json files
written before the official runner recorded it (``evaluation.test_pose_fitting`` with mode
``"official"``).

The job's method spec names its `OfficialCode`, which says it from the job's suite and
``render_args`` (`OfficialCode.fits_test_views`); the reports read it through
`olatbench.reports.collect.posed_splits`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from olatbench.methods.registry import get_spec
from olatbench.methods.spec import import_reference


def official_fitted_test_views(method: str, suite: str, config: Mapping[str, Any]) -> bool:
    """Whether a job of the official implementation ``method`` on ``suite`` with ``config`` (its
    resolved `OfficialConfig` as a dict) scored test views fitted by its training; False for a
    method that is no official implementation or is not installed here."""
    try:
        spec = get_spec(method)
    except (KeyError, ImportError):
        return False
    if spec.kind != "official":
        return False
    code = import_reference(spec.implementation)
    return bool(code.fits_test_views(suite, tuple(config.get("render_args") or ())))
