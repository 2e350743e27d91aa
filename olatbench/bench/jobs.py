"""Jobs: one training-and-evaluation run of (method, suite, scene, variant, seed), and its id.

A job's id is a content hash of everything that decides its result:

* the method name and its fully resolved config (after suite preset, variant preset and overrides),
* the suite, scene, seed, training colour space, image resolution, the train/test split names and
  the frame the method works in (when it is not the dataset's own),
* the scene's data manifest (`data_manifest_hash`: every file's relative path and content hash, but
  those of its ``novel_lights/`` folder, the ground truth under new illumination installed on first
  use, which neither training nor the test split reads: installing it leaves the scene's jobs as
  they were),
* the point cloud the Gaussians start from, when one is used (``init_points_digest``: its content
  hash; the file's path is not part of the id),
* the evaluation protocol id and version,
* the code version (`code_hash`: olatbench's version, the method's source files and the Gaussian
  core's sources; for official implementations the ``olatbench/methods/official`` package, which
  holds the pinned commit and the command lines).

Settings that do not change the result (device, output folder, checkpoint cadence, extra evaluations
such as the novel-light scores, executor, where an official implementation's checkout and
environment live, why a derived preset chose its values and where each config value came from: the
values are in the config) are kept out of the id, so a job moved to another machine or resumed
elsewhere keeps its id.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import importlib.util
import inspect
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from olatbench.atomic import write_json
from olatbench.datasets.novel_lights import FOLDER as NOVEL_LIGHTS_FOLDER

JOB_SCHEMA = "olatbench-job-v1"
ID_LENGTH = 16
_CHUNK = 1 << 20


@dataclass(frozen=True)
class Job:
    """Everything a worker needs to run one job; plain data only, so it pickles to any executor.

    ``config`` is the resolved method config as a JSON-able dict; ``resolution`` is (width, height)
    or None for the images' own size; ``folder`` is the job's run folder.
    """

    method: str
    method_ref: str
    suite: str
    scene: str
    variant: str
    seed: int
    config: dict[str, Any]
    scene_path: str
    scene_format: str
    colourspace: str
    resolution: tuple[int, int] | None
    train_split: str
    test_split: str
    protocol: str
    protocol_version: int
    data_manifest: str | None
    code: str
    folder: str
    device: str = "cpu"
    checkpoint_every: int | None = None
    checkpoint_minutes: float = 10.0
    keep_checkpoints: int = 2
    save_components: bool = False
    # after the OLAT evaluation, score the test cameras under the scene's novel-light ground truth
    # (`olatbench.bench.novel_lights.NovelLightsOptions` as a dict: samples, views); None: not asked
    novel_lights: dict[str, Any] | None = None
    # official code only: where it lives and runs (settings.CodeSettings)
    official: dict[str, Any] | None = None
    # start from a finished job of the same experiment under another variant name (bench.reuse)
    reuse: bool = True
    # the point PLY the Gaussians start from (bench.init_points), "" for the method's own init
    init_points: str = ""
    # its content digest (`file_digest`), part of the id when set
    init_points_digest: str | None = None
    # the frame the method works in (`Suite.frame`): "dataset" (the data's world frame; jobs written
    # before the field existed, and the official codes, which read the files as they are) or
    # "fitted" (the canonical frame of the training cameras, `bench.views.job_frame`); in the
    # identity when not "dataset"
    frame: str = "dataset"
    # field -> why, for a preset derived from the scene
    derived: dict[str, str] = field(default_factory=dict)
    # {"grid", "reference"}: the method's ablation grid the variant belongs to and the variant it is
    # compared with (`MethodSpec.ablation_of`); None outside grids and in job.json files written
    # before the field (the reports then ask the method's spec,
    # `olatbench.bench.ablation.job_ablation`). Not in the identity: it names, it does not decide,
    # the result
    ablation: dict[str, str] | None = None
    # config field -> where its value came from (olatbench.methods.resolve: default, suite preset,
    # variant, --set)
    sources: dict[str, str] = field(default_factory=dict)
    id: str = field(default="")

    @property
    def iterations(self) -> int:
        return int(self.config["iterations"])

    @property
    def label(self) -> str:
        """Short human label: ``scene/variant/seedK``."""
        return f"{self.scene}/{self.variant}/seed{self.seed}"

    def identity(self) -> dict[str, Any]:
        """The inputs hashed into the id (see the module docstring)."""
        return {
            "schema": JOB_SCHEMA,
            "method": self.method,
            "config": self.config,
            "suite": self.suite,
            "scene": self.scene,
            "variant": self.variant,
            "seed": self.seed,
            "colourspace": self.colourspace,
            "resolution": list(self.resolution) if self.resolution else None,
            "splits": [self.train_split, self.test_split],
            "data_manifest": self.data_manifest,
            "protocol": {"id": self.protocol, "version": self.protocol_version},
            "code": self.code,
            # only when used, so that the ids of jobs without a point cloud stay what they were
            **({"init_points": self.init_points_digest} if self.init_points_digest else {}),
        } | ({"frame": self.frame} if self.frame != "dataset" else {})

    def with_id(self) -> Job:
        """This job with ``id`` computed from `identity`."""
        return dataclasses.replace(self, id=hash_json(self.identity())[:ID_LENGTH])

    def to_json(self) -> dict[str, Any]:
        """The job.json content: id, identity and the settings that do not enter the id."""
        return {"id": self.id, "identity": self.identity(), **dataclasses.asdict(self)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Job:
        """Inverse of `to_json` (also of its JSON text parsed back: ``resolution`` becomes a tuple
        again).

        A `ValueError` names missing or unknown keys, and an ``identity`` that does not match the
        fields it is computed from (a hand-edited job.json). ``id`` is taken as written, not
        recomputed.
        """
        values = dict(data)
        identity = values.pop("identity", None)
        known = {f.name: f for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - set(known))
        missing = sorted(
            name
            for name, f in known.items()
            if name not in values
            and f.default is dataclasses.MISSING
            and f.default_factory is dataclasses.MISSING
        )
        if unknown or missing:
            raise ValueError(
                "not a job of this olatbench version: "
                + "; ".join(
                    part
                    for part in (
                        f"missing keys {', '.join(missing)}" if missing else "",
                        f"unknown keys {', '.join(unknown)}" if unknown else "",
                    )
                    if part
                )
            )
        if values.get("resolution") is not None:
            values["resolution"] = tuple(int(v) for v in values["resolution"])
        job = cls(**values)
        if identity is not None and hash_json(identity) != hash_json(job.identity()):
            changed = sorted(
                k for k, v in job.identity().items() if hash_json(v) != hash_json(identity.get(k))
            )
            raise ValueError(
                f"its identity does not match its fields ({', '.join(changed)}); was it edited?"
            )
        return job


def hash_json(data: Any) -> str:
    """SHA-256 hex digest of canonical JSON (sorted keys, no whitespace; non-JSON values via
    ``str``)."""
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), default=str, allow_nan=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def config_to_dict(config: Any) -> dict[str, Any]:
    """A config dataclass as a JSON round-trippable dict (tuples become lists, paths strings)."""
    return json.loads(json.dumps(dataclasses.asdict(config), default=str))


def file_digest(path: Path) -> str:
    """BLAKE2b-128 hex digest of a file's bytes."""
    digest = hashlib.blake2b(digest_size=16)
    with open(path, "rb") as handle:
        while chunk := handle.read(_CHUNK):
            digest.update(chunk)
    return digest.hexdigest()


def _hash_cache_path(root: Path) -> Path:
    cache = (
        Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
        / "olatbench"
        / "file-hashes"
    )
    return cache / (hashlib.sha256(str(root.resolve()).encode()).hexdigest()[:24] + ".json")


def data_manifest_hash(root: str | Path, use_cache: bool = True) -> str:
    """Hash of a scene folder: every non-hidden file's relative path and content digest, but its
    ``novel_lights/`` folder's (module docstring).

    Content digests are cached per file under ``$XDG_CACHE_HOME/olatbench/file-hashes`` keyed by
    (size, mtime in ns), as git's index does: a re-plan reads only files that changed, and a copy
    of the data (new mtimes, same bytes) still gets the same hash after one re-read.
    """
    root = Path(root)
    if not root.is_dir():
        raise FileNotFoundError(f"{root}: scene folder not found")
    files = sorted(
        p
        for p in root.rglob("*")
        if p.is_file()
        and p.relative_to(root).parts[0] != NOVEL_LIGHTS_FOLDER
        and not any(part.startswith(".") for part in p.relative_to(root).parts)
    )
    cache_file = _hash_cache_path(root)
    cache: dict[str, list] = {}
    if use_cache and cache_file.is_file():
        try:
            cache = json.loads(cache_file.read_text())
        except (OSError, json.JSONDecodeError):
            cache = {}
    entries, fresh = [], {}
    for path in files:
        relative = path.relative_to(root).as_posix()
        stat = path.stat()
        cached = cache.get(relative)
        if cached and cached[0] == stat.st_size and cached[1] == stat.st_mtime_ns:
            digest = cached[2]
        else:
            digest = file_digest(path)
        fresh[relative] = [stat.st_size, stat.st_mtime_ns, digest]
        entries.append([relative, digest])
    if use_cache and fresh != cache:
        # the cache is an optimisation; the hash is complete without it
        with contextlib.suppress(OSError):
            write_json(cache_file, fresh, indent=0)
    return hash_json(entries)


def _module_file(module_name: str) -> Path:
    """The source file of ``module_name``, found without executing it (its parent packages are
    imported: the method packages keep their ``__init__`` torch-free so dry runs stay light)."""
    try:
        found = importlib.util.find_spec(module_name)
    except (ImportError, ValueError) as error:
        raise ValueError(f"cannot locate the source of {module_name!r}: {error}") from None
    if found is None or not found.origin or not Path(found.origin).is_file():
        raise ValueError(f"cannot locate the source of {module_name!r}")
    return Path(found.origin).resolve()


def _method_source_files(implementation: type | str) -> list[Path]:
    """The method's source: its whole folder for ``olatbench.methods.<name>`` packages and for
    classes defined in a package ``__init__``; its module file otherwise. ``implementation`` is the
    class or its ``"module:Class"`` reference (located, not imported)."""
    if isinstance(implementation, str):
        module_name = implementation.partition(":")[0]
        path = _module_file(module_name)
    else:
        module_name = implementation.__module__
        source = inspect.getsourcefile(implementation)
        if source is None:
            raise ValueError(f"cannot locate the source of {implementation!r}")
        path = Path(source).resolve()
    parts = module_name.split(".")
    if path.name == "__init__.py" or (parts[:2] == ["olatbench", "methods"] and len(parts) >= 4):
        return sorted(path.parent.rglob("*.py"))
    return [path]


def _core_source_files() -> list[Path]:
    """The code every Gaussian method runs besides its own package: the Gaussian core
    (Python and C++), the shared method modules (``olatbench/methods/*.py``: interface, training
    helpers, Gaussian-method base) and the shared shading blocks
    (``olatbench/methods/shading/``)."""
    package = Path(__file__).resolve().parent.parent
    core = sorted(
        p for p in (package / "gaussians").rglob("*") if p.suffix in (".py", ".cpp", ".h", ".cu")
    )
    methods = package / "methods"
    return core + sorted(methods.glob("*.py")) + sorted((methods / "shading").rglob("*.py"))


def code_hash(implementation: type | str) -> str:
    """Hash of the code that decides a method's result: olatbench version, method and core sources.

    ``implementation`` is the method class or its ``"module:Class"`` reference
    (a spec's ``implementation``); both give the same hash, and the reference is never imported
    (no torch at plan time)."""
    from olatbench import __version__

    digest = hashlib.sha256(__version__.encode())
    package_root = Path(__file__).resolve().parent.parent.parent
    for path in _method_source_files(implementation) + _core_source_files():
        try:
            name = path.relative_to(package_root).as_posix()
        except ValueError:
            name = path.name
        digest.update(name.encode() + b"\0" + file_digest(path).encode() + b"\0")
    return digest.hexdigest()
