"""Crash safety: a run killed (SIGKILL, no clean-up possible) while it writes its output leaves no
output, or the complete previous output, never a partial file under the output's name.

The CLI writes through io.atomic_output: a hidden temporary file '.NAME.XXXX.partial.EXT' in the
output folder, fsynced, then renamed over the output. The test starts the real CLI on a cloud
large enough that writing the LAZ takes a while, waits until the temporary file has data in it,
and kills the process. A killed process cannot delete its temporary file: the hidden '.partial'
file is what may be left, and nothing else; the next run of the same output removes it, and never
a live run's temporary file or anything else (issue 18).
"""
from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import laspy
import numpy as np
import pytest

import socket
import subprocess
import sys

from cli_helpers import bumpy_ground, cli_env, run_cli, sha256, start_cli, write_las, write_tiny_config

POINTS = 1_500_000


@pytest.fixture(scope="module")
def big_input(tmp_path_factory):
    folder = tmp_path_factory.mktemp("crash")
    src = write_las(folder / "big.las", bumpy_ground(POINTS, side=150.0))
    return folder, src, write_tiny_config(folder)


def _temporaries(folder: Path, out: Path) -> list[Path]:
    return [p for p in folder.iterdir() if p.name.startswith(f".{out.stem}.") and p.name.endswith(".partial.laz")]


def _kill_while_writing(config, src, out, timeout=300.0, sig=signal.SIGKILL):
    """Start a run, send it ``sig`` as soon as its temporary output holds data; return the
    temporary file seen and the killed process."""
    proc = start_cli("run", config, "--backend", "cpu", "--quiet", "--input", src, "--output", out)
    seen = None
    deadline = time.monotonic() + timeout
    try:
        while proc.poll() is None and time.monotonic() < deadline:
            if out.parent.is_dir():
                busy = [p for p in _temporaries(out.parent, out) if p.exists() and p.stat().st_size > 0]
                if busy:
                    os.kill(proc.pid, sig)
                    seen = busy[0]
                    break
            time.sleep(0.002)
    finally:
        if proc.poll() is None and seen is None:
            os.kill(proc.pid, signal.SIGKILL)
        proc.stderr_text = proc.communicate()[1]
    assert seen is not None, f"the run ended (exit {proc.returncode}) before it could be killed mid-write"
    if sig == signal.SIGKILL:
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
    seen, killed = _kill_while_writing(config, src, out)
    assert not out.exists()
    assert not out.with_suffix(".summary.json").exists()
    _leftovers_are_only_temporaries(tmp_path, out, allowed=set())
    assert sha256(src) == digest
    assert seen.exists() and f"p{killed.pid}-" in seen.name          # the dead run's file, named by its pid
    # the next run is not disturbed by the dead run's temporary file, writes a complete output and
    # removes the temporary file the killed run left
    proc = run_cli("run", config, "--backend", "cpu", "--quiet", "--input", src, "--output", out)
    assert proc.returncode == 0, proc.stderr
    result = laspy.read(out)
    assert len(result.points) == POINTS
    np.testing.assert_array_equal(np.asarray(result.X), np.asarray(laspy.read(src).X))
    assert not seen.exists() and _temporaries(tmp_path, out) == []


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


def test_sigterm_unwinds_and_leaves_no_temporary_file(big_input, tmp_path):
    from cli_helpers import message_lines
    folder, src, config = big_input
    out = tmp_path / "result.laz"
    seen, proc = _kill_while_writing(config, src, out, sig=signal.SIGTERM)
    assert proc.returncode == 128 + signal.SIGTERM, proc.stderr_text
    assert "Traceback" not in proc.stderr_text
    assert message_lines(proc.stderr_text) == ["roadx_ti: stopped by SIGTERM; no partial output was left"]
    assert not seen.exists() and not out.exists()
    assert list(tmp_path.iterdir()) == []


HOLDER = """\
import sys, time
from pathlib import Path
from roadx_ti.io.atomic import atomic_output
with atomic_output(sys.argv[1]) as tmp:
    Path(tmp).write_bytes(b"live")
    print(tmp, flush=True)
    sys.stdin.readline()          # hold the temporary file open until told to finish
"""


def _dead_pid() -> int:
    done = subprocess.Popen([sys.executable, "-c", "pass"])
    done.wait()
    return done.pid


def test_clean_up_removes_only_dead_runs_files_of_its_own_output(tmp_path):
    from roadx_ti.io.atomic import host_tag as _host
    src = write_las(tmp_path / "small.las", bumpy_ground(2000))
    config = write_tiny_config(tmp_path)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    out = out_dir / "result.laz"
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(out)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True, env=cli_env())
    try:
        live = Path(holder.stdout.readline().strip())          # a concurrent run's live file
        assert live.exists() and str(holder.pid) in live.name
        dead, host = _dead_pid(), _host()
        stale = out_dir / f".result.p{dead}-{host}-abc123.partial.laz"
        keep = {
            "other output": out_dir / f".other.p{dead}-{host}-abc123.partial.laz",
            "other host": out_dir / f".result.p{dead}-{host}x-abc123.partial.laz",
            "no pid (older format)": out_dir / ".result.k2j4h1.partial.laz",
            "another suffix": out_dir / f".result.p{dead}-{host}-abc123.partial.las",
            "a user file": out_dir / "result.partial.laz",
        }
        for p in [stale, *keep.values()]:
            p.write_bytes(b"x")
        link = out_dir / f".result.p{dead}-{host}-link01.partial.laz"
        link.symlink_to(src)                                   # never followed nor removed
        proc = run_cli("run", config, "--backend", "cpu", "--input", src, "--output", out)
        assert proc.returncode == 0, proc.stderr
        assert not stale.exists()
        assert f"removed {stale.name}" in proc.stderr
        assert live.exists() and live.read_bytes() == b"live"
        for what, p in keep.items():
            assert p.exists(), what
        assert link.is_symlink() and src.exists()
    finally:
        holder.communicate("done\n", timeout=60)
    assert holder.returncode == 0 and not live.exists()          # the holder then renamed its file
    assert out.read_bytes() == b"live"


def test_an_output_group_replaces_all_its_files_or_none(tmp_path):
    from roadx_ti.io.atomic import atomic_output, output_group
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    a.write_text("old a")
    with pytest.raises(RuntimeError):
        with output_group():
            with atomic_output(a) as tmp:
                tmp.write_text("new a")
            assert a.read_text() == "old a"          # written, not yet in place
            with atomic_output(b) as tmp:
                tmp.write_text("new b")
            raise RuntimeError("the last sidecar failed")
    assert a.read_text() == "old a" and not b.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]
    with output_group():
        for path, text in ((a, "new a"), (b, "new b")):
            with atomic_output(path) as tmp:
                tmp.write_text(text)
    assert a.read_text() == "new a" and b.read_text() == "new b"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt"]
    # a folder where a file of the group goes: nothing renamed
    (tmp_path / "c.txt").mkdir()
    with pytest.raises(Exception, match="is a folder"):
        with output_group():
            for path in (a, tmp_path / "c.txt"):
                with atomic_output(path) as tmp:
                    tmp.write_text("newer")
    assert a.read_text() == "new a"


@pytest.mark.parametrize("failure", ["disk full", "interrupt"])
def test_a_run_failing_at_its_last_sidecar_keeps_every_previous_output(tmp_path, monkeypatch, capsys, failure):
    """The picture is written last: a disk filling up there, or Ctrl-C then, used to leave the new
    cloud in place of the old one under a message saying the output was not changed."""
    import errno

    from roadx_ti import cli, report
    src = write_las(tmp_path / "small.las", bumpy_ground(3000))
    config = write_tiny_config(tmp_path)
    out = tmp_path / "result.laz"
    assert cli.main(["run", str(config), "--backend", "cpu", "--quiet", "--input", str(src), "--output", str(out),
                     "--set", "output.report_png=true"]) == 0
    before = {p.name: sha256(p) for p in tmp_path.iterdir() if p.name.startswith("result")}
    assert {"result.laz", "result.summary.json", "result.config.yaml", "result.png"} <= set(before)

    def failing_png(path, *args, **kwargs):
        from roadx_ti.io.atomic import atomic_output
        with atomic_output(path) as tmp:
            if failure == "interrupt":
                raise KeyboardInterrupt
            raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(report, "top_view_png", failing_png)
    code = cli.main(["run", str(config), "--backend", "cpu", "--quiet", "--input", str(src), "--output", str(out),
                     "--set", "output.report_png=true", "--set", "seed=5"])
    assert code == (130 if failure == "interrupt" else 1)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and ("not changed" in err[0] or "no partial output" in err[0]), err
    after = {p.name: sha256(p) for p in tmp_path.iterdir() if p.name.startswith("result")}
    assert after == before
    assert not [p for p in tmp_path.iterdir() if ".partial" in p.name]


def test_a_compressor_failing_to_write_is_one_line_and_changes_nothing(tmp_path):
    """lazrs reports a full disk as its own LazrsError ('IoError: Failed to call write'), which had
    reached the user as an unexpected error asking for a bug report."""
    from roadx_ti.io import InputError
    from roadx_ti.io.atomic import atomic_output

    class LazrsError(Exception):
        pass
    out = tmp_path / "r.laz"
    out.write_bytes(b"previous")
    with pytest.raises(InputError, match="writing failed .*IoError: Failed to call write.*not changed"):
        with atomic_output(out) as tmp:
            tmp.write_bytes(b"half")
            raise LazrsError("IoError: Failed to call write")
    assert out.read_bytes() == b"previous" and sorted(p.name for p in tmp_path.iterdir()) == ["r.laz"]


def test_point_counts_are_whole_numbers():
    import argparse

    from roadx_ti.config import parse_point_count
    assert [parse_point_count(t) for t in ("1000", "250k", "1.5M", "2.5k")] == [1000, 250_000, 1_500_000, 2500]
    for text in ("1.5", "1.0005k", "-3", "x"):
        with pytest.raises(argparse.ArgumentTypeError):
            parse_point_count(text)


def test_ctrl_c_arriving_after_the_outputs_were_renamed_says_they_are_complete(tmp_path, monkeypatch, capsys):
    """Signals wait while a run's files are renamed together; one held there arrives after the
    renames. The run then stops with the new outputs complete, which the line says (it said only
    'no partial output was left', read as 'nothing changed')."""
    from roadx_ti import cli
    from roadx_ti.io import atomic
    src = write_las(tmp_path / "small.las", bumpy_ground(3000))
    config = write_tiny_config(tmp_path)
    out = tmp_path / "result.laz"
    commit = atomic._Group.commit

    def commit_then_interrupt(self):
        commit(self)
        raise KeyboardInterrupt
    monkeypatch.setattr(atomic._Group, "commit", commit_then_interrupt)
    code = cli.main(["run", str(config), "--backend", "cpu", "--quiet", "--input", str(src), "--output", str(out)])
    assert code == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "complete before it:" in err[0] and "result" in err[0], err
    assert out.is_file() and out.with_suffix(".summary.json").is_file()
    assert not [p for p in tmp_path.iterdir() if ".partial" in p.name]


def test_a_failed_run_removes_the_output_folders_it_made(tmp_path, monkeypatch, capsys):
    """Output folders are made before the work (as PDAL's users expect); a run failing or
    interrupted after that left them behind, empty. Folders that existed stay."""
    from roadx_ti import cli, pipelines
    src = write_las(tmp_path / "small.las", bumpy_ground(3000))
    config = write_tiny_config(tmp_path)
    (tmp_path / "kept").mkdir()
    out = tmp_path / "kept" / "new" / "deeper" / "result.laz"

    def interrupted(*args, **kwargs):
        assert out.parent.is_dir()              # made before the work
        raise KeyboardInterrupt
    monkeypatch.setattr(pipelines, "run", interrupted)
    code = cli.main(["run", str(config), "--backend", "cpu", "--quiet", "--input", str(src), "--output", str(out)])
    assert code == 130
    assert (tmp_path / "kept").is_dir() and not (tmp_path / "kept" / "new").exists()
