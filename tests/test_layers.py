"""The layering rules of docs/architecture.md, checked over the package's static import graph.

Every ``import`` / ``from ... import`` in ``olatbench/**.py`` counts, wherever it is written (module
level, inside functions, under ``TYPE_CHECKING``): a lazy import is still a dependency. Layers, top
to bottom: cli → viewer → reports → bench → methods → metrics → gaussians → datasets → _native;
``olatbench.atomic`` (stdlib only) and the root package (``__version__``) may be imported by every
layer.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "olatbench"


@dataclass(frozen=True)
class Edge:
    """``source`` (a module of the package) imports ``target`` (a dotted module name) at
    ``line``."""

    source: str
    target: str
    line: int

    def __str__(self) -> str:
        return f"{self.source}:{self.line} imports {self.target}"


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_edges(root: Path = PACKAGE) -> list[Edge]:
    """Every import of every module below ``root`` (relative imports resolved; ``from a import b``
    gives ``a.b`` when ``b`` is a module of the package, ``a`` otherwise)."""
    modules = {module_name(path, root): path for path in root.rglob("*.py")}
    edges = []
    for source, path in sorted(modules.items()):
        is_package = path.name == "__init__.py"
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                edges += [Edge(source, alias.name, node.lineno) for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = source.split(".")
                    anchor = anchor[: len(anchor) - node.level + (1 if is_package else 0)]
                    base = ".".join([*anchor, base] if base else anchor)
                for alias in node.names:
                    candidate = f"{base}.{alias.name}"
                    edges.append(
                        Edge(source, candidate if candidate in modules else base, node.lineno)
                    )
    return list(dict.fromkeys(edges))


def layer(module: str) -> str | None:
    """``olatbench.<layer>...`` -> layer; ``None`` for modules outside the package."""
    parts = module.split(".")
    if parts[0] != "olatbench":
        return None
    return parts[1] if len(parts) > 1 else "olatbench"


# the root package (__version__) and the stdlib-only leaf helpers every layer may use: atomic
# writes, progress lines, the olatbench.toml reader, matching typed names (each imports nothing of
# olatbench: the leaf rules below)
SHARED = {"olatbench", "atomic", "progress", "project_file", "names"}


@dataclass(frozen=True)
class Rule:
    name: str
    source_layer: str
    forbidden: frozenset[str] = frozenset()  # layers of olatbench it must not import
    only: frozenset[str] | None = None  # when set: the only layers of olatbench it may import
    # top-level third-party packages it must not import
    forbidden_external: frozenset[str] = frozenset()
    # exact modules exempt from ``forbidden`` (named exceptions)
    allowed_modules: frozenset[str] = frozenset()
    # modules of the layer the rule does not cover (with a reason)
    exempt_sources: frozenset[str] = frozenset()
    leaf: bool = False  # imports nothing of olatbench at all, not even the shared modules

    def violations(self, edges: Iterable[Edge]) -> list[str]:
        found = []
        for edge in edges:
            if layer(edge.source) != self.source_layer or edge.source in self.exempt_sources:
                continue
            target_layer = layer(edge.target)
            if target_layer is None:
                if edge.target.split(".")[0] in self.forbidden_external:
                    found.append(str(edge))
                continue
            if edge.target in self.allowed_modules or target_layer == self.source_layer:
                continue
            outside_only = self.only is not None and target_layer not in self.only | SHARED
            if self.leaf or outside_only or target_layer in self.forbidden:
                found.append(str(edge))
        return found


RULES = [
    # The data layer is imported alone by other projects: numpy only. `torch_adapter` is the one
    # opt-in module that hands records to a torch DataLoader; nothing in the layer imports it (a
    # separate rule below checks that).
    Rule(
        "datasets import only atomic and themselves, never torch",
        "datasets",
        only=frozenset(),
        forbidden_external=frozenset({"torch", "click"}),
        exempt_sources=frozenset({"olatbench.datasets.torch_adapter"}),
    ),
    Rule("_native imports nothing of olatbench", "_native", leaf=True),
    Rule("atomic imports nothing of olatbench", "atomic", leaf=True),
    Rule("progress imports nothing of olatbench", "progress", leaf=True),
    Rule("project_file imports nothing of olatbench", "project_file", leaf=True),
    Rule("names imports nothing of olatbench", "names", leaf=True),
    Rule(
        "gaussians import no methods, bench, reports or cli",
        "gaussians",
        forbidden=frozenset({"methods", "bench", "reports", "cli"}),
    ),
    Rule(
        "metrics import no gaussians, methods, bench, reports or cli",
        "metrics",
        forbidden=frozenset({"gaussians", "methods", "bench", "reports", "cli"}),
    ),
    Rule(
        "methods import no bench, reports, viewer or cli",
        "methods",
        forbidden=frozenset({"bench", "reports", "viewer", "cli"}),
    ),
    Rule(
        "bench imports no reports, viewer or cli",
        "bench",
        forbidden=frozenset({"reports", "viewer", "cli"}),
    ),
    Rule(
        "reports import no methods (a report that renders goes through bench.restore), no viewer "
        "and no cli",
        "reports",
        forbidden=frozenset({"methods", "viewer", "cli"}),
    ),
    Rule(
        "the viewer imports no methods (it renders through bench.restore) and no cli",
        "viewer",
        forbidden=frozenset({"methods", "cli"}),
    ),
]


#: Rules the code still breaks on this commit, each with the work that removes it. strict: once that
#: work lands, the test passes, the xfail fails, and the entry must go.
KNOWN_BREAKS: dict[str, str] = {}


def _param(rule: Rule):
    reason = KNOWN_BREAKS.get(rule.source_layer)
    marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
    return pytest.param(rule, id=rule.name, marks=marks)


@pytest.mark.parametrize("rule", [_param(rule) for rule in RULES])
def test_layer_rule(rule: Rule):
    violations = rule.violations(import_edges())
    assert not violations, f"{rule.name}:\n  " + "\n  ".join(violations)


def test_only_cli_imports_click():
    violations = [
        str(edge)
        for edge in import_edges()
        if edge.target.split(".")[0] == "click" and layer(edge.source) != "cli"
    ]
    assert not violations, "\n  ".join(violations)


def test_nothing_in_the_data_layer_imports_its_torch_adapter():
    adapter = "olatbench.datasets.torch_adapter"
    violations = [
        str(edge)
        for edge in import_edges()
        if edge.target == adapter and edge.source != adapter and layer(edge.source) == "datasets"
    ]
    assert not violations, "\n  ".join(violations)


def test_the_graph_sees_every_kind_of_import(tmp_path):
    """The checker itself: a broken rule is found whether the import is relative, lazy or under
    TYPE_CHECKING."""
    root = tmp_path / "olatbench"
    for package in ("", "datasets", "gaussians", "methods", "reports", "bench"):
        (root / package / "__init__.py").parent.mkdir(parents=True, exist_ok=True)
        (root / package / "__init__.py").write_text("")
    (root / "datasets" / "records.py").write_text(
        "def load():\n    import torch\n    return torch\n"
    )
    (root / "gaussians" / "model.py").write_text("from ..methods import base\n")
    (root / "methods" / "base.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
        "    from olatbench.bench.jobs import Job\n"
    )
    (root / "reports" / "video.py").write_text(
        "from olatbench.bench import restore\nfrom . import tables\n"
    )
    (root / "reports" / "tables.py").write_text("")
    edges = import_edges(root)
    by_rule = {rule.source_layer: rule.violations(edges) for rule in RULES}
    assert by_rule["datasets"] == ["olatbench.datasets.records:2 imports torch"]
    assert by_rule["gaussians"] == ["olatbench.gaussians.model:1 imports olatbench.methods.base"]
    assert by_rule["methods"] == ["olatbench.methods.base:3 imports olatbench.bench.jobs"]
    assert by_rule["reports"] == []  # bench (restore) and its own modules are allowed
