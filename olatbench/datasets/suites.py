"""Benchmark suites: the paper's scene lists and settings, so ``--suite nrhints`` means the paper's
setting.

Sources: the SSD-GS paper (Sec. 5 and appendix) and ``ssdgs_iclr2026.csv``. NRHints scenes are 512²
or 1024² (``resolution=None`` keeps each scene's native size); GS³ is 512²; SSS-GS is the public
256² down-scaled release. Folder aliases map the names found on disk to the canonical names of the
paper.

A user's own scenes make suites too, whose scenes are folders anywhere (``Suite.scene_paths``):
``[suites.NAME]`` tables of ``olatbench.toml`` (`user_suites`: ``scenes`` = folder paths relative to
the file, and optionally ``format``, ``protocol``, ``resolution``, ``iterations``), and the scene
folders given to ``run --data`` (`data_suite`, named ``data-<format>``, a name no built-in or user
suite may take, so their run folders never meet a suite's). Their scenes are trained and scored at
their own resolution unless the suite says otherwise; the rest of what such a suite does not say is
taken from its format's suite settings (the format module's ``SUITE_DEFAULTS``, which also make the
paper's suite of the format; the format is detected when not given), including which method preset
its jobs apply (``gs3`` for a GS³-format suite) when the method derives none from the scene
(`olatbench.methods.scene_presets`).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

from olatbench.datasets.errors import DatasetError
from olatbench.datasets.formats import FORMATS, detect_format, display_colourspace, format_module
from olatbench.datasets.formats._suite import canonical_name
from olatbench.datasets.sizes import checked_size, parse_size
from olatbench.names import case_twin, did_you_mean, match_name, path_component


@dataclass(frozen=True)
class Suite:
    """A named benchmark setting: which scenes, how they are read, trained and scored."""

    name: str
    format: str
    scenes: tuple[str, ...]
    aliases: dict[str, str] = field(default_factory=dict)  # folder name -> canonical scene name
    # no background: each scene's own (`Frame.background`, set by its format's reader) is the one
    # everything uses
    resolution: tuple[int, int] | None = None  # (width, height) or native
    iterations: int = 100_000
    protocol: str = "ssdgs"
    train_split: str = "train"
    test_split: str = "test"
    generator: str | None = None  # "module:function" creating the data on first use
    # "module:function" returning where the generator keeps its data
    generator_root: str | None = None
    # scene -> its folder (user suites; no data root)
    scene_paths: dict[str, str] = field(default_factory=dict)
    # the method preset every job applies (None: the one named like the suite)
    method_preset: str | None = None
    iterations_given: bool = False  # a user suite's own iterations: they win over that preset's
    # The frame methods work in (Views.frame): "fitted", the canonical frame fitted to the training
    # cameras (olatbench.datasets.similarity), or "dataset", the data's own world frame: the
    # built-in suites', whose method presets hold world-unit values tuned in it
    # (docs/architecture.md, "The canonical frame").
    frame: str = "fitted"
    # where a user's suite was declared ("<file> [suites.NAME]"), named by errors in its settings
    source: str = ""

    @property
    def preset(self) -> str:
        """The name of the method preset applied to every job of this suite
        (when the method has one)."""
        return self.method_preset or self.name

    @property
    def colourspace(self) -> str:
        """The space methods are trained and scored in: the format's
        (`formats.display_colourspace`)."""
        return display_colourspace(self.format)

    def canonical(self, folder: str) -> str | None:
        """The canonical scene name of a folder name, or None when it is not in this suite."""
        return canonical_name(folder, self.scenes, self.aliases)

    def scene_path(self, data_root: str | Path | None, scene: str) -> Path:
        """The folder of ``scene`` below ``data_root``: by canonical name or any alias (a suite with
        ``scene_paths`` ignores ``data_root``)."""
        canonical = self.canonical(scene) or scene
        if canonical in self.scene_paths:
            path = Path(self.scene_paths[canonical])
            if not path.is_dir():
                raise DatasetError(
                    f"scene '{canonical}' of suite '{self.name}': folder not found", path=path
                )
            return path
        if data_root is None:
            raise DatasetError(f"suite '{self.name}' needs a data root to find scene '{canonical}'")
        data_root = Path(data_root)
        if canonical not in self.scenes:
            raise DatasetError(
                f"suite '{self.name}' has no scene '{scene}'; scenes: {', '.join(self.scenes)}",
                path=data_root,
            )
        candidates = [
            canonical,
            *sorted(a for a, target in self.aliases.items() if target == canonical),
        ]
        for name in candidates:
            if (data_root / name).is_dir():
                return data_root / name
        raise DatasetError(
            f"scene '{canonical}' of suite '{self.name}' not found; looked for folders "
            f"{', '.join(candidates)}. Try: olatbench datasets download {self.name}",
            path=data_root,
        )


def _paper_suite(fmt: str) -> Suite:
    """The paper's suite of format ``fmt``, as the format's ``SUITE_DEFAULTS`` say, in the data's
    own frame."""
    defaults = format_module(fmt).SUITE_DEFAULTS
    return Suite(
        name=fmt,
        format=fmt,
        scenes=defaults.scenes,
        aliases=dict(defaults.aliases),
        resolution=defaults.resolution,
        iterations=defaults.iterations,
        protocol=defaults.protocol,
        frame="dataset",
    )


_MINI_SCENES = ("diffuse_shadow", "aniso_metal", "translucent")

SUITES: dict[str, Suite] = {
    **{fmt: _paper_suite(fmt) for fmt in ("nrhints", "gs3", "sssgs")},
    "mini": Suite(
        name="mini",
        format="nrhints",
        scenes=_MINI_SCENES,
        aliases={},
        resolution=None,
        iterations=3000,
        protocol="olatbench-v1",
        frame="dataset",
        generator="olatbench.datasets.synth.mini:ensure_mini_suite",
        generator_root="olatbench.datasets.synth.mini:default_root",
    ),
}


#: The name prefix of the suites made from ``run --data`` folders (``data-gs3``); reserved.
DATA_SUITE_PREFIX = "data-"
#: The keys a ``[suites.NAME]`` table of olatbench.toml may hold.
USER_SUITE_KEYS = ("scenes", "format", "protocol", "resolution", "iterations", "frame")
#: The frames a suite's methods may work in (`Suite.frame`).
FRAMES = ("fitted", "dataset")


def suite_names() -> list[str]:
    """Names of the built-in suites, then the user's (olatbench.toml in the working folder)."""
    return list(SUITES) + [name for name in user_suites() if name not in SUITES]


def get_suite(name: str) -> Suite:
    """The suite called ``name``: built-in, a user suite of olatbench.toml, or ``data-<format>``
    (the suite of ``run --data`` folders, here without scenes: its runs name them); case does not
    matter where only one suite matches (``Mini``); a `DatasetError` with a "did you mean" and the
    known suites otherwise."""
    if name in SUITES:
        return SUITES[name]
    users = user_suites()
    data = {f"{DATA_SUITE_PREFIX}{fmt}": fmt for fmt in FORMATS}
    # "Mini": case does not matter where only one matches
    matched = match_name(name, [*SUITES, *users, *data])
    if matched in data:
        return _own_suite(matched, data[matched], {})
    if matched is not None:
        return SUITES[matched] if matched in SUITES else users[matched]
    known = ", ".join([*SUITES, *users]) + f" (and {DATA_SUITE_PREFIX}<format> for run --data)"
    raise DatasetError(
        f"unknown suite '{name}'{did_you_mean(name, [*SUITES, *users, *data])}; known suites: "
        f"{known}"
    )


def parse_resolution(value: object, where: str) -> tuple[int, int] | None:
    """``"256x256"``, ``"256"`` (256 × 256), ``[256, 256]`` or ``"native"`` (None) as
    (width, height); a `DatasetError` naming ``where`` otherwise."""
    if value == "native":
        return None
    forms = 'resolution must be N, WxH (e.g. 256 or 320x240), [W, H] or "native"'
    if not isinstance(value, str) and not (isinstance(value, list | tuple) and len(value) == 2):
        raise DatasetError(f"{where}: {forms}, not {value!r}")
    try:
        return parse_size(value) if isinstance(value, str) else checked_size(*value)
    except ValueError as error:
        raise DatasetError(f"{where}: {forms} ({error})") from None


def _own_suite(name: str, fmt: str, scene_paths: dict[str, str], **given: object) -> Suite:
    """A suite of folders of format ``fmt`` at their own resolution and background, with the
    format's method presets, protocol and iterations (its ``SUITE_DEFAULTS``) unless ``given``
    (None: not given)."""
    base = format_module(fmt).SUITE_DEFAULTS
    settings = {key: value for key, value in given.items() if value is not None}
    return Suite(
        name=name,
        format=fmt,
        scenes=tuple(scene_paths),
        resolution=None,
        iterations=int(settings.get("iterations", base.iterations)),  # type: ignore[call-overload]
        protocol=str(settings.get("protocol", base.protocol)),
        scene_paths=scene_paths,
        method_preset=fmt,
        iterations_given="iterations" in settings,
    )


def _scene_folders(paths: list[Path], fmt: str | None, where: str) -> tuple[str, dict[str, str]]:
    """The format of ``paths`` (detected unless ``fmt``) and {scene name (the folder's name):
    absolute folder}."""
    found: dict[str, str] = {}
    formats = set()
    for path in paths:
        try:
            detected = detect_format(path)
        except DatasetError as error:
            raise DatasetError(f"{where}: {error}") from None
        if fmt is not None and detected != fmt:
            raise DatasetError(f"{where}: the folder is in {detected} format, not {fmt}", path=path)
        formats.add(detected)
        name = path.resolve().name
        twin = name if name in found else case_twin(name, found)
        if twin is not None:
            names = (
                f"'{name}'"
                if twin == name
                else f"'{twin}' and '{name}' (one folder ignoring case, as on macOS)"
            )
            raise DatasetError(
                f"{where}: two scene folders are named {names} ({found[twin]} and {path}); rename "
                "one, since run folders are named after the scene",
                path=path,
            )
        found[name] = str(path.resolve())
    if len(formats) > 1:
        raise DatasetError(
            f"{where}: the scenes mix formats ({', '.join(sorted(formats))}); a suite holds one"
        )
    return formats.pop(), found


def data_suites(paths: list[str | Path]) -> list[Suite]:
    """The suites of ``run --data`` folders: one ``data-<format>`` suite per detected format, in the
    order the folders were given."""
    by_format: dict[str, list[Path]] = {}
    for path in map(Path, paths):
        by_format.setdefault(detect_format(path), []).append(path)
    suites = []
    for fmt, folders in by_format.items():
        _, scene_paths = _scene_folders(folders, fmt, "--data")
        suites.append(_own_suite(f"{DATA_SUITE_PREFIX}{fmt}", fmt, scene_paths))
    return suites


def user_suites(folder: str | Path | None = None) -> dict[str, Suite]:
    """The ``[suites.NAME]`` tables of olatbench.toml in ``folder`` (default: the working folder) as
    suites; a `DatasetError` naming the file, the table and the key for anything malformed."""
    from olatbench.project_file import ProjectFileError, project_file_path, project_tables

    try:
        tables = project_tables("suites", '[suites.mycaptures] scenes = ["captures/cup"]', folder)
    except ProjectFileError as error:
        raise DatasetError(str(error)) from None
    path = project_file_path(folder)
    suites = {}
    for name, table in tables.items():
        where = (
            f"{path} [suites.{name if re.fullmatch(r'[A-Za-z0-9_-]+', name) else json.dumps(name)}]"
        )
        try:
            path_component(name, "suite")
        except ValueError as error:
            raise DatasetError(f"{where}: {error}") from None
        taken = case_twin(name, suites) or match_name(name, SUITES)
        if taken is not None or name.casefold().startswith(DATA_SUITE_PREFIX):
            named = (
                f" (as '{taken}', ignoring case: one folder on a case-insensitive disk)"
                if taken
                else ""
            )
            raise DatasetError(
                f"{where}: the name is taken{named} (built-in suites: {', '.join(SUITES)}; "
                f"{DATA_SUITE_PREFIX}* is reserved for run --data)"
            )
        unknown = sorted(set(table) - set(USER_SUITE_KEYS))
        if unknown:
            raise DatasetError(
                f"{where}: unknown key(s) {', '.join(unknown)}; known: {', '.join(USER_SUITE_KEYS)}"
            )
        scenes = table.get("scenes")
        if (
            not isinstance(scenes, list)
            or not scenes
            or not all(isinstance(item, str) for item in scenes)
        ):
            raise DatasetError(
                f"{where}: scenes must be a non-empty list of scene folders (relative to the file)"
            )
        fmt = table.get("format")
        if fmt is not None and fmt not in FORMATS:
            raise DatasetError(f"{where}: format must be one of {', '.join(FORMATS)}, not {fmt!r}")
        iterations = table.get("iterations")
        if iterations is not None and (
            not isinstance(iterations, int) or isinstance(iterations, bool) or iterations < 0
        ):
            raise DatasetError(
                f"{where}: iterations must be a whole number >= 0, not {iterations!r}"
            )
        protocol = table.get("protocol")
        if protocol is not None and not isinstance(protocol, str):
            raise DatasetError(
                f"{where}: protocol must be a protocol name (olatbench metrics list)"
            )
        frame = table.get("frame", "fitted")
        if frame not in FRAMES:
            raise DatasetError(f"{where}: frame must be one of {', '.join(FRAMES)}, not {frame!r}")
        fmt, scene_paths = _scene_folders(
            [path.parent / item for item in scenes], fmt, f"{where} scenes"
        )
        resolution = parse_resolution(table["resolution"], where) if "resolution" in table else None
        suites[name] = replace(
            _own_suite(name, fmt, scene_paths, protocol=protocol, iterations=iterations),
            resolution=resolution,
            frame=frame,
            source=where,
        )
    return suites


def canonical_scene_name(folder: str, format: str | None = None) -> str:
    """The paper's name of a scene folder (e.g. ``Cat_on_Decor`` -> ``CatSmall``); the folder name
    otherwise."""
    for suite in SUITES.values():
        if format is None or suite.format == format:
            canonical = suite.canonical(folder)
            if canonical is not None:
                return canonical
    return folder
