"""The one import of Taichi, and every call that depends on which Taichi it is.

roadx_ti runs on Taichi 1.7.4 (``import taichi``; wheels up to Python 3.13) and on taichi-forge
(``import taichi_forge``; a maintained fork that keeps 1.7.4's API, wheels for Python 3.10-3.14).
Every module of the project takes ``ti`` from here, so the choice is made once per process:

- ``ROADX_TI_TAICHI=taichi`` or ``=taichi_forge`` asks for one (an error when it is not installed);
- otherwise (``auto``) ``taichi`` where it is installed, else ``taichi_forge``.

The two keep their runtimes apart: a host program that embeds roadx_ti and calls ``ti.init``
itself must use the same distribution (``DISTRIBUTION`` says which one roadx_ti took).
The internals read below (``ti.lang.impl``, ``ti.lang._ndarray``) are not public API in either,
which is why they live here and nowhere else.
"""
from __future__ import annotations

import importlib
import os

DISTRIBUTIONS = ("taichi", "taichi_forge")
ENVIRONMENT_VARIABLE = "ROADX_TI_TAICHI"


class TaichiImportError(ImportError):
    """Neither Taichi distribution can be imported (or the one asked for is missing)."""


def _import_taichi():
    wanted = os.environ.get(ENVIRONMENT_VARIABLE, "auto").strip().lower().replace("-", "_") or "auto"
    if wanted not in DISTRIBUTIONS + ("auto",):
        raise TaichiImportError(f"{ENVIRONMENT_VARIABLE}={wanted!r}: use one of auto, "
                                f"{', '.join(DISTRIBUTIONS)}")
    candidates = DISTRIBUTIONS if wanted == "auto" else (wanted,)
    for name in candidates:
        try:
            return importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:   # installed but broken: say so, do not hide it behind a fallback
                raise
    raise TaichiImportError(
        f"no Taichi found ({' or '.join(candidates)}): pip install "
        f"{'taichi==1.7.4 (Python <= 3.13)' if 'taichi' in candidates else ''}"
        f"{' or ' if len(candidates) == 2 else ''}"
        f"{'taichi-forge' if 'taichi_forge' in candidates else ''}")


ti = _import_taichi()
DISTRIBUTION: str = ti.__name__
VERSION: tuple = tuple(ti.__version__)
CPU_ARCHS = (ti.x64, ti.arm64)
NDARRAY_TYPE = ti.lang._ndarray.Ndarray


def is_initialized() -> bool:
    """True when a Taichi runtime exists (started by roadx_ti or by the host program)."""
    return ti.lang.impl.get_runtime().prog is not None


def runtime_program():
    """An object that identifies the current runtime (one ti.init): Taichi's Python runtime object,
    which ti.init / ti.reset replace. Not the C++ program's pybind wrapper: a new program allocated
    at a freed one's address comes back as the old wrapper while a reference to it is held, so the
    scratch cache of kernels/grid.py took a dead runtime's buffers for live ones (intermittent
    'RuntimeError: argument not found' after a backend switch in the tests)."""
    return ti.lang.impl.get_runtime()


def current_arch():
    """The arch of the running runtime (a ``ti`` arch object)."""
    return ti.lang.impl.current_cfg().arch


def cpu_threads() -> int:
    """Threads the CPU backend was started with (``cpu_max_num_threads``)."""
    return int(ti.lang.impl.current_cfg().cpu_max_num_threads)


def description() -> str:
    """e.g. 'taichi 1.7.4' or 'taichi_forge 0.7.0', for logs, reports and benchmark records."""
    return f"{DISTRIBUTION} {'.'.join(str(v) for v in VERSION)}"
