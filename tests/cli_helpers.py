"""Helpers for tests that drive the real CLI: in a subprocess (python -m roadx_ti ...), or many
calls of its entry function ``roadx_ti.cli.main`` in one child process (``run_in_one_process``).

Inputs are written with laspy / numpy directly, not through roadx_ti.io, so a reader bug cannot
hide behind a matching writer bug.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import laspy
import numpy as np

REPO = Path(__file__).resolve().parents[1]
CONFIGS = REPO / "configs"
PYTHON = sys.executable

# A pipeline of two cheap stages (compiles in about a second): enough to read, run kernels on and
# write a cloud, for the cases that test files and options rather than the methods.
TINY_CONFIG = """\
pipeline: road
output: {path: out/result.laz, report_png: false}
stages:
  - uniform_downsample: {ratio: 1.0}
  - grid_slope: {step: 0.5, slope_max: 0.1, dh_max: 1.0}
"""

# The demo's road pipeline with parameters shrunk so a few thousand points take seconds.
DEMO_FAST = ["--set", "stages.cloth_smooth.iterations=60", "--set", "stages.ransac_planes.hypotheses=200",
             "--set", "output.report_png=false"]


def cli_command(*args) -> list[str]:
    return [PYTHON, "-m", "roadx_ti", *map(str, args)]


def cli_env() -> dict:
    env = dict(os.environ)
    env.pop("TI_ARCH", None)   # the CLI picks its backend from --backend
    return env


def run_cli(*args, cwd=None, timeout=300) -> subprocess.CompletedProcess:
    """Run ``python -m roadx_ti ARGS`` and return the finished process (text stdout/stderr)."""
    return subprocess.run(cli_command(*args), capture_output=True, text=True, cwd=cwd,
                          timeout=timeout, env=cli_env())


def start_cli(*args, cwd=None) -> subprocess.Popen:
    """Start ``python -m roadx_ti ARGS`` without waiting (stdout/stderr to pipes)."""
    return subprocess.Popen(cli_command(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, cwd=cwd, env=cli_env())


# One child process that runs calls of cli.main, read as JSON lines from stdin, one after another:
# the imports, Taichi's start and its kernels' loading (seconds per `python -m roadx_ti`) are paid
# once. Each call's stdout and stderr are its own (redirected); what main() lets out is reported as
# `raised` (a traceback, for the tests).
# Its records are lines that start with RECORD on its stdout (what a library writes to the file
# descriptor itself may precede one on its line); SystemExit is main()'s exit code (argparse's usage
# errors, --help). A call's stderr is what it printed and, after it, what reached file descriptor 2
# itself during the call (Taichi's C++ log, processes it started), as a process's stderr has it.
RECORD = "\x1eroadx_ti-driver "
_DRIVER = textwrap.dedent("""\
    import contextlib, io, json, os, sys, tempfile, time
    from roadx_ti import cli
    def record(value):
        print(%r + json.dumps(value), flush=True)
    for line in sys.stdin:
        call = json.loads(line)
        record({"start": call["id"]})
        err, out = io.StringIO(), io.StringIO()
        t0 = time.perf_counter()
        raised = None
        with tempfile.TemporaryFile() as fd2:
            saved = os.dup(2)
            os.dup2(fd2.fileno(), 2)
            try:
                with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
                    code = cli.main(call["argv"])
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
            except BaseException as exc:
                code, raised = None, f"{type(exc).__name__}: {exc}"
            finally:
                os.dup2(saved, 2)
                os.close(saved)
            fd2.seek(0)
            written = fd2.read().decode("utf-8", "replace")
        record({"id": call["id"], "code": code, "raised": raised, "stderr": err.getvalue() + written,
                "stdout": out.getvalue(), "seconds": time.perf_counter() - t0})
    """ % RECORD)


def run_in_one_process(calls: list[dict], *, call_seconds: float, total_seconds: float) -> dict:
    """Run each call's ``argv`` through ``roadx_ti.cli.main`` in one child process; results by call
    ``id`` (code, raised, stderr, stdout, seconds). A call that runs past ``call_seconds`` or kills
    the child is reported as raised (the child is replaced for the calls after it); the whole run
    past ``total_seconds`` fails the test."""
    results: dict = {}
    deadline = time.monotonic() + total_seconds
    pending = list(calls)
    while pending:
        # its own session: a kill takes the processes it started too (Dask workers)
        proc = subprocess.Popen([PYTHON, "-c", _DRIVER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, env=cli_env(), cwd=REPO,
                                start_new_session=True)
        lines: list[str] = []
        feeder = threading.Thread(target=_feed, args=(proc, pending), daemon=True)
        reader = threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True)
        errors = threading.Thread(target=lambda: setattr(proc, "stderr_text", proc.stderr.read()), daemon=True)
        for thread in (feeder, reader, errors):
            thread.start()
        current, started, seen, lost, done_before = None, 0.0, 0, None, len(results)
        try:
            while len(results) < len(calls):
                time.sleep(0.02)
                ended = proc.poll() is not None
                if ended:
                    reader.join(2)         # what it wrote (a process it started may hold the pipe)
                for line in lines[seen:]:
                    if RECORD not in line:
                        continue            # a library's own print
                    record = json.loads(line.rsplit(RECORD, 1)[1])
                    if "start" in record:
                        current, started = record["start"], time.monotonic()
                    else:
                        results[record["id"]], current = record, None
                seen = len(lines)
                if current is not None and time.monotonic() - started > call_seconds:
                    lost = f"ran past {call_seconds:.0f} s"
                    break
                if time.monotonic() > deadline:
                    raise AssertionError(f"the in-process CLI calls ran past {total_seconds:.0f} s")
                if ended:
                    if len(results) < len(calls):
                        errors.join(5)
                        lost = f"killed the driver process (exit {proc.returncode}): " \
                               f"{getattr(proc, 'stderr_text', '')[-2000:]}"
                    break
        finally:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        if lost is not None and current is not None:
            results[current] = {"id": current, "code": None, "raised": lost, "stderr": "", "stdout": "",
                                "seconds": time.monotonic() - started}
        elif lost is not None and len(results) == done_before:
            raise AssertionError(f"the in-process CLI driver {lost} before any call")
        pending = [c for c in calls if c["id"] not in results]      # (a death between calls: again)
    return results


def _feed(proc: subprocess.Popen, calls: list[dict]) -> None:
    with contextlib.suppress(OSError):         # the child died: its calls are reported as lost
        proc.stdin.write("".join(json.dumps(c) + "\n" for c in calls))
        proc.stdin.close()


# Taichi's own stderr lines: its banner and its C++ log ('[W 11/21/26 23:36:59.570 22597] ...')
_TAICHI_LINE = re.compile(r"^\[(Taichi\]|[DIWEC] \d\d/\d\d/\d\d )")


def message_lines(stderr: str) -> list[str]:
    """stderr without Taichi's own lines (start-up banner, C++ log)."""
    return [line for line in stderr.splitlines() if line.strip() and not _TAICHI_LINE.match(line)]


def error_line(proc: subprocess.CompletedProcess, code: int) -> str:
    """Assert ``proc`` failed with exit ``code`` and said why in exactly one line; return it."""
    assert "Traceback" not in proc.stderr, proc.stderr
    assert proc.returncode == code, f"exit {proc.returncode}, expected {code}: {proc.stderr}"
    lines = message_lines(proc.stderr)
    assert len(lines) == 1, f"expected one message line, got {lines}"
    assert lines[0].startswith("roadx_ti: "), lines[0]
    return lines[0]


def sha256(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def listing(folder) -> set[str]:
    """Names of everything in ``folder`` (recursively, relative), empty when it does not exist."""
    folder = Path(folder)
    if not folder.exists():
        return set()
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def partial_files(folder) -> list[str]:
    """Temporary files the atomic writer leaves while it writes ('.NAME.*.partial.EXT')."""
    return sorted(n for n in listing(folder) if ".partial" in n or Path(n).name.startswith("."))


def write_tiny_config(folder, body: str = TINY_CONFIG) -> Path:
    path = Path(folder) / "tiny.yaml"
    path.write_text(textwrap.dedent(body))
    return path


def write_las(path, xyz, *, rgb=None, classification=None, scale=0.01, offset=None,
              point_format=None, version="1.4", crs_wkt=None) -> Path:
    """A LAS/LAZ file of world coordinates ``xyz`` (float64 (n, 3)) written by laspy alone;
    ``crs_wkt``: an OGC WKT CRS record (LAS 1.4)."""
    xyz = np.asarray(xyz, np.float64).reshape(-1, 3)
    if point_format is None:
        point_format = 7 if rgb is not None else 6
    header = laspy.LasHeader(point_format=point_format, version=version)
    header.scales = np.full(3, scale)
    header.offsets = (np.floor(xyz.min(axis=0)) if len(xyz) else np.zeros(3)) if offset is None else offset
    if crs_wkt is not None:
        header.vlrs.append(laspy.vlrs.known.WktCoordinateSystemVlr(crs_wkt))
        header.global_encoding.wkt = True
    las = laspy.LasData(header)
    if len(xyz):
        las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    else:
        las.points = laspy.ScaleAwarePointRecord.zeros(0, header=header)
    if rgb is not None:
        rgb = np.asarray(rgb, np.uint16)
        las.red, las.green, las.blue = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    if classification is not None:
        las.classification = np.asarray(classification, np.uint8)
    las.write(str(path))
    return Path(path)


def bumpy_ground(n: int, seed: int = 0, side: float = 20.0) -> np.ndarray:
    """``n`` world points on a gently undulating surface of ``side`` metres, near a UTM corner."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0.0, side, size=(n, 2))
    z = 100.0 + 0.05 * np.sin(xy[:, 0]) + 0.05 * np.cos(0.7 * xy[:, 1]) + rng.normal(0, 0.005, n)
    return np.column_stack([xy[:, 0] + 500_000.0, xy[:, 1] + 4_500_000.0, z])


def synth(path, points: str = "20k", seed: int = 0, kind: str = "uav-road") -> Path:
    proc = run_cli("synth", "--kind", kind, "--points", points, "--seed", seed, "-o", path)
    assert proc.returncode == 0, proc.stderr
    return Path(path)
