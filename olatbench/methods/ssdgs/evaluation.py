"""SSD-GS's evaluation protocol: its test views scored as given, fitted during training, or refined
after it.

Two config switches choose, and they combine: ``test_pose_fitting="interleaved"`` (the official
real-data protocol: each test view's pose and light offsets are fitted to its image in passes
interleaved with the training epochs, `olatbench.methods.ssdgs.view_fitting`) and
``test_time_refinement`` (each test view's pose and light fitted to its image after training, from
its interleaved fit when it has one, `SSDGS.refine_view`). With both off the views are scored as
given, as every other method's are. The runner records both in results.json
(``evaluation.test_pose_fitting``, ``evaluation.test_time_refinement``) and the reports footnote
such numbers.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

from olatbench.methods.evaluation_protocol import EvaluationProtocol, RefinedView

if TYPE_CHECKING:
    import numpy as np

    from olatbench.datasets.records import Camera, PointLight
    from olatbench.methods.base import Views
    from olatbench.methods.ssdgs.method import SSDGS


class SSDGSTestViews(EvaluationProtocol):
    """The protocol `olatbench.methods.ssdgs.spec.SPEC` names; ``method`` is an `SSDGS`."""

    name: ClassVar[str] = "ssdgs-test-views"
    method: SSDGS

    @property
    def fitting(self) -> str | None:
        return "interleaved" if self.method.config.test_pose_fitting == "interleaved" else None

    def attach_test_views(self, test: Views) -> None:
        self.method.attach_test_views(test)

    def fitted_views(self) -> dict[str, dict[str, float]] | None:
        return self.method.fitted_test_views()

    @property
    def refines(self) -> bool:
        return bool(self.method.config.test_time_refinement)

    def refine(self, camera: Camera, light: PointLight, image: np.ndarray) -> RefinedView | None:
        return self.method.refine_view(camera, light, image)


__all__ = ["SSDGSTestViews"]
