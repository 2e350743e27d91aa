"""A native library as its owner declares it: name, C++ sources, include folders and typed symbol
table.

The owner of C++ code (``gaussians/csrc/``, ``metrics/csrc/``, ``methods/ssdgs/csrc/``) declares one
``NativeLibrary`` beside its Python, with a symbol table giving every exported function's
``restype`` and ``argtypes`` once. ``load()`` builds the library on first use (``build.build``),
loads it with ctypes, checks its ABI version and that it exports every declared symbol, and sets
each function's types; call sites index the loaded ``Library`` by symbol name, so a call with the
wrong number or kind of arguments raises instead of passing garbage. The outcome (library or error)
is kept for the process.
"""

from __future__ import annotations

import ctypes
import threading
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .backends import Unavailable
from .build import ABI_VERSION, BuildError, build, library_path

CType = Any  # a ctypes type (ctypes.c_int, ctypes.c_void_p, ...); None as a restype means void
# the suffix of a function's float/double version
FLOAT_TYPES = {"f32": ctypes.c_float, "f64": ctypes.c_double}
INSTALL_HINT = (
    "install a C++ compiler with OpenMP (e.g. `apt-get install g++`) or point OLATBENCH_CXX at one"
)


@dataclass(frozen=True)
class Signature:
    """One exported C function's types: ``restype`` (None for void) and ``argtypes`` in order."""

    restype: CType
    argtypes: tuple[CType, ...]


def per_float(table: Callable[[str, CType], dict[str, Signature]]) -> dict[str, Signature]:
    """The symbol table of functions that exist once per float type: ``table(suffix, real)`` for
    ("f32", c_float) and ("f64", c_double), merged."""
    symbols: dict[str, Signature] = {}
    for suffix, real in FLOAT_TYPES.items():
        symbols.update(table(suffix, real))
    return symbols


class Library:
    """A loaded library: its declared functions, typed, by symbol name
    (``lib["olatbench_forward_f32"](...)``)."""

    def __init__(self, path: Path, note: str, functions: Mapping[str, Any]) -> None:
        self.path, self.note, self._functions = path, note, dict(functions)

    def __getitem__(self, symbol: str) -> Any:
        try:
            return self._functions[symbol]
        except KeyError:
            raise KeyError(f"{symbol} is not in the symbol table of {self.path.name}") from None


class NativeLibrary:
    """``name``: file and cache name; ``sources``: the C++ files compiled together; ``symbols``: the
    typed symbol table; ``include_dirs``: header folders besides the sources' own and
    ``_native/include``."""

    def __init__(
        self,
        name: str,
        sources: Sequence[Path],
        symbols: Mapping[str, Signature],
        include_dirs: Sequence[Path] = (),
    ) -> None:
        self.name, self.sources, self.include_dirs = name, tuple(sources), tuple(include_dirs)
        self.symbols = dict(symbols)
        self._lock = threading.Lock()
        self._outcome: Library | BuildError | None = None

    def path(self, variant: str = "openmp") -> Path:
        """Where the build of ``variant`` ("openmp" or "serial") of the current sources is
        cached."""
        return library_path(self.name, self.sources, self.include_dirs, variant)

    def load(self) -> Library:
        """The loaded library, built on first use; the outcome is kept for the process. Raises
        BuildError."""
        with self._lock:
            if self._outcome is None:
                try:
                    self._outcome = self._load()
                except BuildError as error:
                    self._outcome = error
            if isinstance(self._outcome, BuildError):
                raise self._outcome
            return self._outcome

    def _load(self) -> Library:
        path, note = build(self.name, self.sources, self.include_dirs)
        try:
            handle = ctypes.CDLL(str(path))
        except OSError as error:
            raise BuildError(f"could not load the C++ library {path}: {error}") from error
        functions = {}
        for symbol, signature in {
            "olatbench_abi_version": Signature(ctypes.c_int, ()),
            **self.symbols,
        }.items():
            try:
                function = getattr(handle, symbol)
            except AttributeError:
                raise BuildError(
                    f"{path} does not export {symbol} (declared in its symbol table)"
                ) from None
            function.restype, function.argtypes = signature.restype, signature.argtypes
            functions[symbol] = function
        version = functions["olatbench_abi_version"]()
        if version != ABI_VERSION:
            raise BuildError(
                f"{path} has ABI version {version}, expected {ABI_VERSION}; delete it to rebuild"
            )
        if note:  # runs, but slower: say so once, as a fallback to torch is said
            warnings.warn(
                f"olatbench: the C++ library {self.name} is a {note}", RuntimeWarning, stacklevel=3
            )
        return Library(path, note, functions)

    def status(self) -> tuple[bool, str]:
        """(ok, detail): builds/loads if needed; ``detail`` is the library path (with the
        single-threaded note) or why it is unavailable (for ``olatbench doctor`` and the fallback
        warnings)."""
        try:
            library = self.load()
        except BuildError as error:
            return False, str(error)
        return True, f"{library.path} ({library.note})" if library.note else str(library.path)

    def unavailable(self) -> Unavailable | None:
        """None when the library loads, else why (a missing backend: ``choose_backend`` warns on
        falling back)."""
        ok, detail = self.status()
        return (
            None
            if ok
            else Unavailable(
                f"its C++ library {self.name} is unavailable: {detail}\nTo use it, {INSTALL_HINT}.",
                missing=True,
            )
        )

    def reset(self) -> None:
        """Forget the load outcome (tests use this after changing the compiler environment)."""
        with self._lock:
            self._outcome = None


__all__ = ["FLOAT_TYPES", "Library", "NativeLibrary", "Signature", "per_float"]
