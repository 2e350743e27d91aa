"""Evaluation protocols: how a method's test views are posed before they are scored.

Most methods are scored at the test views' given cameras and lights (the base `EvaluationProtocol`).
Some papers score otherwise: SSD-GS's real-data protocol fits each test view's pose and light to its
image while the model trains, or refines them after training. Such a protocol is an object of its
own, named by the method's spec (``MethodSpec.evaluation``, a ``"module:Class"`` string, copied onto
the `Method` class), so the generic `Method` interface carries none of it. The runner
(`olatbench.bench.execute`) builds the protocol with the method and asks it, in order:

1. ``fitting`` (before ``setup``): the name of a fit of the test views that runs during training, or
   None; when set, the runner loads the test split and hands it over with `attach_test_views`;
2. ``refines`` / `refine` (while scoring the test split): a view's camera and light fitted to its
   image, the model frozen;
3. `fitted_views` (after training): how far each test view was fitted, for
   ``evaluation.test_pose_fitting`` in results.json.

The model is never changed by a protocol; the scored image is always the method's `Method.render` of
the view the protocol returns.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

from olatbench.methods.spec import DEFAULT_EVALUATION, import_reference

if TYPE_CHECKING:
    import numpy as np

    from olatbench.datasets.records import Camera, PointLight
    from olatbench.methods.base import Method, Views


@dataclass
class RefinedView:
    """An evaluation view after test-time refinement: the ``camera`` and ``light`` to render with,
    and a ``summary`` of plain floats for the results file (e.g. loss before/after, how far the pose
    moved)."""

    camera: Camera
    light: PointLight
    summary: dict[str, float]


class EvaluationProtocol:
    """The interface, and the default protocol: every test view is rendered and scored at its given
    camera and light.

    Subclasses (a method's own protocol) override the members below; ``method`` is the trained
    (or training) method the protocol serves.
    """

    name: ClassVar[str] = "given-views"

    def __init__(self, method: Method) -> None:
        self.method = method

    @property
    def fitting(self) -> str | None:
        """The mode of a test-view fit run during training (e.g. ``"interleaved"``), or None: no
        test views are given to the method before ``setup``."""
        return None

    def attach_test_views(self, test: Views) -> None:
        """Receive the test views (images included) for `fitting`; called before ``setup``."""
        raise NotImplementedError(f"{type(self).__name__} fits no test views")

    def fitted_views(self) -> dict[str, dict[str, float]] | None:
        """Per test frame id, plain floats saying how far its pose/light were fitted
        (None: no fitting)."""
        return None

    @property
    def refines(self) -> bool:
        """Whether `refine` is called on each test view before it is rendered for scoring."""
        return False

    def refine(self, camera: Camera, light: PointLight, image: np.ndarray) -> RefinedView | None:
        """Test-time refinement of an evaluation view's pose and/or light against its image.

        ``image`` (H, W, 3) float32 is the ground truth in the training space and background. The
        model stays frozen. Returns None when the view is scored as given; the runner records which
        views were refined and how far.
        """
        return None


def evaluation_protocol(method: Method) -> EvaluationProtocol:
    """The protocol the method's class names (``Method.evaluation``, from its spec), built for
    ``method``."""
    protocol_class = import_reference(getattr(method, "evaluation", DEFAULT_EVALUATION))
    if not (isinstance(protocol_class, type) and issubclass(protocol_class, EvaluationProtocol)):
        raise TypeError(
            f"{type(method).__name__}.evaluation names {protocol_class!r}, not a subclass of "
            f"{DEFAULT_EVALUATION}"
        )
    return protocol_class(method)


__all__ = ["DEFAULT_EVALUATION", "EvaluationProtocol", "RefinedView", "evaluation_protocol"]
