"""Evaluation protocols (`olatbench.methods.evaluation_protocol`): objects a method's spec names,
which the runner drives; the generic `Method` interface knows nothing of how test views are
posed."""

from __future__ import annotations

import ast
from dataclasses import replace
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest
import test_runner_support as support

from olatbench.bench.execute import run_job
from olatbench.bench.plan import make_plan
from olatbench.bench.results import read_results
from olatbench.methods.base import Method
from olatbench.methods.evaluation_protocol import (
    EvaluationProtocol,
    RefinedView,
    evaluation_protocol,
)
from olatbench.methods.registry import get_spec, register, spec_from_class
from olatbench.methods.spec import DEFAULT_EVALUATION

PACKAGE = Path(__file__).resolve().parent.parent / "olatbench"
#: What the generic interface carried for SSD-GS's test-view fitting before protocols were objects.
FORMER_MEMBERS = (
    "refines_test_views",
    "refine_view",
    "test_pose_fitting",
    "attach_test_views",
    "fitted_test_views",
)


class ShiftedViews(EvaluationProtocol):
    """A toy protocol: fits nothing during training but counts the test views it is given; refines
    each test view by moving its light 1 unit along +x (the trivial method ignores the light, so the
    scores do not change)."""

    name: ClassVar[str] = "shifted-views"

    @property
    def fitting(self) -> str | None:
        return "toy"

    def attach_test_views(self, test) -> None:
        self.attached = list(test.frame_ids)

    def fitted_views(self) -> dict[str, dict[str, float]] | None:
        return {frame_id: {"given": 1.0} for frame_id in self.attached}

    @property
    def refines(self) -> bool:
        return True

    def refine(self, camera, light, image: np.ndarray) -> RefinedView | None:
        assert image.ndim == 3 and image.shape[2] == 3 and image.dtype == np.float32
        return RefinedView(
            camera,
            replace(light, position=np.asarray(light.position) + np.array([1.0, 0.0, 0.0])),
            {"shift": 1.0},
        )


class ShiftedTrivial(support.TrivialMethod):
    evaluation: ClassVar[str] = "test_evaluation_protocol:ShiftedViews"


def test_the_method_interface_has_no_test_view_members():
    assert [name for name in FORMER_MEMBERS if hasattr(Method, name)] == []
    assert Method.evaluation == DEFAULT_EVALUATION
    protocol = evaluation_protocol(support.TrivialMethod(support.TrivialConfig()))
    assert (
        type(protocol) is EvaluationProtocol and protocol.fitting is None and not protocol.refines
    )


def test_no_package_module_or_class_is_named_as_pytest_collects():
    """pytest's default patterns collect ``test_*.py`` files and ``Test*`` classes."""
    modules = [
        path.relative_to(PACKAGE).as_posix()
        for path in PACKAGE.rglob("*.py")
        if path.name.startswith("test_") or path.name.endswith("_test.py")
    ]
    classes = [
        f"{path.relative_to(PACKAGE).as_posix()}:{node.name}"
        for path in PACKAGE.rglob("*.py")
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.ClassDef) and node.name.startswith("Test")
    ]
    assert (modules, classes) == ([], [])


def test_ssdgs_names_its_protocol_and_the_config_switches_it():
    from olatbench.methods.ssdgs import SSDGS
    from olatbench.methods.ssdgs.evaluation import SSDGSTestViews

    assert get_spec("ssdgs").evaluation == "olatbench.methods.ssdgs.evaluation:SSDGSTestViews"
    plain = evaluation_protocol(SSDGS(SSDGS.resolve_config(None)))
    assert isinstance(plain, SSDGSTestViews) and plain.fitting is None and not plain.refines
    fitted = evaluation_protocol(
        SSDGS(
            SSDGS.resolve_config(
                None, refine_camera=True, test_pose_fitting="interleaved", test_time_refinement=True
            )
        )
    )
    assert fitted.fitting == "interleaved" and fitted.refines


def test_a_class_registered_method_carries_its_protocol_into_its_spec():
    assert spec_from_class("shifted", ShiftedTrivial).evaluation == ShiftedTrivial.evaluation
    assert spec_from_class("trivial", support.TrivialMethod).evaluation == DEFAULT_EVALUATION


def test_a_reference_to_something_else_is_refused_in_one_line():
    class Wrong(support.TrivialMethod):
        evaluation: ClassVar[str] = "olatbench.methods.base:Views"

    with pytest.raises(TypeError, match=r"^Wrong.evaluation names .*Views.*, not a subclass of "):
        evaluation_protocol(Wrong(support.TrivialConfig()))


def test_the_runner_drives_a_plugins_protocol_and_records_it(tmp_path):
    """Test views attached before training, each one refined before it is scored, both recorded in
    results.json; the train split is never refined."""
    register("shifted", ShiftedTrivial)
    data = support.write_tiny_data(tmp_path / "data")
    job = make_plan(
        "shifted",
        support.tiny_suite(),
        tmp_path / "runs",
        scenes=["Alpha"],
        data_root=data,
        progress=False,
    )[0]
    assert run_job(job, progress=False).status == "done", (
        Path(job.folder) / "error.txt"
    ).read_text()
    results = read_results(Path(job.folder) / "results.json")
    test_frames = set(results["metrics"]["test"]["per_image"])
    assert results["evaluation"]["test_pose_fitting"] == {
        "mode": "toy",
        "split": "test",
        "frames": {frame: {"given": 1.0} for frame in sorted(test_frames)},
    }
    refinement = results["evaluation"]["test_time_refinement"]
    assert refinement["split"] == "test" and refinement["frames"] == {
        frame: {"shift": 1.0} for frame in test_frames
    }
    assert (
        "loaded 2 test views for test_pose_fitting=toy"
        in (Path(job.folder) / "log.txt").read_text()
    )
