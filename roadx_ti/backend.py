"""The only place that initialises Taichi.

Everything version-specific about Taichi (how to ask whether it is initialised, which arch is in
use, the names of archs) lives here, so that a move to a maintained fork of Taichi stays small.
A host program that already called ``ti.init`` keeps its runtime: ``init`` then only reports it.
"""
from __future__ import annotations

import contextlib
import gc
import glob
import io
import logging
import os
import sys
import threading

from roadx_ti.kernels import taichi_compat
from roadx_ti.kernels.taichi_compat import ti

log = logging.getLogger("roadx_ti.backend")

CHOICES = ("auto", "cpu", "vulkan", "cuda", "metal")

_ARCHS = {"cpu": ti.cpu, "vulkan": ti.vulkan, "cuda": ti.cuda, "metal": ti.metal}


class BackendError(RuntimeError):
    """The requested backend cannot be started on this machine."""


def is_initialized() -> bool:
    """True when a Taichi runtime exists (started by roadx_ti or by the host program)."""
    return taichi_compat.is_initialized()


def current_arch() -> str:
    """Name of the arch in use: 'cpu', 'vulkan', 'cuda', 'metal', ... ('' when not initialised)."""
    if not is_initialized():
        return ""
    name = taichi_compat.current_arch().name
    return "cpu" if name in ("x64", "arm64") else name


def _hardware_gpu_present() -> bool:
    # Mesa installs Vulkan ICDs for several vendors even where there is no such device, and its
    # lavapipe driver runs Vulkan on the CPU, slower than Taichi's own CPU backend. A real GPU
    # shows up as a DRM render node or an NVIDIA device node.
    return bool(glob.glob("/dev/dri/renderD*") or os.path.exists("/dev/nvidia0"))


def _cuda_present() -> bool:
    import ctypes.util

    return os.path.exists("/dev/nvidia0") or ctypes.util.find_library("cuda") is not None


def _auto_candidates() -> list[str]:
    # only try what can be there: a failed try costs time and prints Taichi warnings
    order = ["cuda"] if _cuda_present() else []
    if sys.platform == "darwin":
        order.append("metal")
    elif _hardware_gpu_present():
        order.append("vulkan")
    order.append("cpu")
    return order


def init(backend: str = "auto", *, threads: int | None = None, debug: bool = False,
         offline_cache: bool = True, fast_math: bool = False) -> str:
    """Start Taichi on ``backend`` unless a runtime already exists; return the arch in use.

    ``auto`` tries cuda, then metal (macOS) or vulkan (when a hardware GPU is present), then cpu.
    A runtime started by a host program is used as is, whatever ``backend`` says.
    """
    if backend not in CHOICES:
        raise BackendError(f"backend {backend!r} is not one of {', '.join(CHOICES)}")
    if is_initialized():
        arch = current_arch()
        log.info("Taichi already initialised by the host: using arch %s", arch)
        return arch
    candidates = _auto_candidates() if backend == "auto" else [backend]
    # Taichi's TI_ARCH overrides the arch ti.init is asked for (TI_ARCH=vulkan ran a --backend cpu
    # run on lavapipe, other labels; an unknown name aborted the process): the backend asked for
    # here decides, and the variable is said to be ignored
    environment_arch = os.environ.pop("TI_ARCH", None)
    if environment_arch is not None:
        log.warning("TI_ARCH=%s in the environment is ignored: the backend is chosen by --backend or the "
                    "config's backend (here %s)", environment_arch[:40], backend)
    # fast_math off: LLVM may then not contract or reorder float expressions, so taichi 1.7.4
    # (LLVM 15) and taichi-forge (LLVM 20) compute the same bits (curvature, plane distances)
    kwargs = dict(offline_cache=offline_cache, debug=debug, log_level=ti.WARN, fast_math=fast_math,
                  default_ip=ti.i32, default_fp=ti.f32)
    if threads:
        kwargs["cpu_max_num_threads"] = int(threads)
    for name in candidates:
        # trying a GPU arch that is missing, Taichi warns that it falls back to the CPU: a line
        # before our own error (or the next candidate's start) that says nothing to a user
        trying = kwargs if name == "cpu" else dict(kwargs, log_level=ti.ERROR)
        # ti.init prints the arch it starts to stdout, which belongs to the CLI's results: to
        # stderr, for a GPU arch only once it is known to be that arch (not the fallback), and
        # not at all when our own info lines are off (the CLI's --quiet)
        banner = io.StringIO()
        try:
            with contextlib.redirect_stdout(banner):
                ti.init(arch=_ARCHS[name], **trying)
        except Exception as exc:  # Taichi raises assorted types for missing drivers
            log.debug("backend %s unavailable: %s", name, exc)
            continue
        arch = current_arch()
        # Taichi silently falls back to the CPU when the requested GPU arch is missing.
        if name != "cpu" and arch == "cpu":
            ti.reset()
            continue
        if name != "cpu":
            ti.set_logging_level(kwargs["log_level"])
        if log.isEnabledFor(logging.INFO):
            sys.stderr.write(banner.getvalue())
        log.info("Taichi started on arch %s", arch)
        return arch
    raise BackendError(f"backend {backend!r} is not available on this machine "
                       f"(tried {', '.join(candidates)})")


@contextlib.contextmanager
def collect_in_this_thread():
    """For work that makes Taichi ndarrays on a GPU arch in a thread other than the main one (a
    Dask worker runs its tasks in a pool thread and its event loop in the main thread): the cyclic
    garbage collector is paused for the block and run in this thread at its end. A collection runs
    in whichever thread crosses the allocation threshold, and an ndarray freed on a thread without
    the CUDA context aborts the process (CUDA_ERROR_INVALID_CONTEXT in cuMemFreeAsync, seen on an
    H200). A no-op on the CPU and in the main thread. Limits: an explicit ``gc.collect()`` in
    another thread still runs (Dask's memory manager calls one when a worker nears its memory
    limit), and only the thread that started Taichi holds the context, so a worker with several
    task threads (an external ``dask worker`` with its default threads) is not covered; the local
    cluster roadx_ti starts has one thread per worker."""
    from roadx_ti.chunks import cyclic_gc_paused

    if current_arch() in ("", "cpu") or threading.current_thread() is threading.main_thread():
        yield
        return
    with cyclic_gc_paused():
        try:
            yield
        finally:
            gc.collect()


def reset() -> None:
    """Tear the runtime down (tests switching arch use this; pipelines never do)."""
    ti.reset()


def available(name: str) -> bool:
    """Whether ``name`` can be started here (starts and tears down a runtime when none exists)."""
    if is_initialized():
        return current_arch() == name
    try:
        init(name)
    except BackendError:
        return False
    reset()
    return True
