"""Crash safety: a run killed (SIGKILL, no clean-up possible) while it writes its output leaves no
output, or the complete previous output, never a partial file under the output's name.

The CLI writes through io.atomic_output: a hidden temporary file '.NAME.XXXX.partial.EXT' in the
output folder, fsynced, then renamed over the output. The test starts the real CLI on a cloud
large enough that writing the LAZ takes a while, waits until the temporary file has data in it,
and kills the process. A killed process cannot delete its temporary file: the hidden '.partial'
file is what may be left, and nothing else.
"""
from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import laspy
import numpy as np
import pytest

from cli_helpers import bumpy_ground, run_cli, sha256, start_cli, write_las, write_tiny_config

POINTS = 1_500_000


@pytest.fixture(scope="module")
def big_input(tmp_path_factory):
    folder = tmp_path_factory.mktemp("crash")
    src = write_las(folder / "big.las", bumpy_ground(POINTS, side=150.0))
    return folder, src, write_tiny_config(folder)


def _temporaries(folder: Path, out: Path) -> list[Path]:
    return [p for p in folder.iterdir() if p.name.startswith(f".{out.stem}.") and p.name.endswith(".partial.laz")]


def _kill_while_writing(config, src, out, timeout=300.0):
    """Start a run, SIGKILL it as soon as its temporary output holds data; return the temporary
    file seen (None when the run ended first) and the killed process."""
    proc = start_cli("run", config, "--backend", "cpu", "--quiet", "--input", src, "--output", out)
    seen = None
    deadline = time.monotonic() + timeout
    try:
        while proc.poll() is None and time.monotonic() < deadline:
            if out.parent.is_dir():
                busy = [p for p in _temporaries(out.parent, out) if p.exists() and p.stat().st_size > 0]
                if busy:
                    os.kill(proc.pid, signal.SIGKILL)
                    seen = busy[0]
                    break
            time.sleep(0.002)
    finally:
        if proc.poll() is None and seen is None:
            os.kill(proc.pid, signal.SIGKILL)
        proc.communicate()
    assert seen is not None, f"the run ended (exit {proc.returncode}) before it could be killed mid-write"
    assert proc.returncode == -signal.SIGKILL
    return seen, proc


def _leftovers_are_only_temporaries(folder: Path, out: Path, allowed: set[str]):
    for p in folder.iterdir():
        if p.name in allowed:
            continue
        assert p.name.startswith(".") and ".partial." in p.name, f"unexpected file {p.name} after the kill"


def test_killed_first_run_leaves_no_output(big_input, tmp_path):
    folder, src, config = big_input
    digest = sha256(src)
    out = tmp_path / "result.laz"
    seen, _ = _kill_while_writing(config, src, out)
    assert not out.exists()
    assert not out.with_suffix(".summary.json").exists()
    _leftovers_are_only_temporaries(tmp_path, out, allowed=set())
    assert sha256(src) == digest
    # the next run is not disturbed by the dead run's temporary file and writes a complete output
    proc = run_cli("run", config, "--backend", "cpu", "--quiet", "--input", src, "--output", out)
    assert proc.returncode == 0, proc.stderr
    result = laspy.read(out)
    assert len(result.points) == POINTS
    np.testing.assert_array_equal(np.asarray(result.X), np.asarray(laspy.read(src).X))


def test_killed_run_keeps_the_previous_output(big_input, tmp_path):
    folder, src, config = big_input
    out = tmp_path / "result.laz"
    previous_xyz = bumpy_ground(1000, seed=9)
    write_las(out, previous_xyz)
    before = sha256(out)
    _kill_while_writing(config, src, out)
    assert sha256(out) == before        # the complete previous output, untouched
    assert len(laspy.read(out).points) == 1000
    _leftovers_are_only_temporaries(tmp_path, out, allowed={out.name})
