"""Tiles on dask.distributed: a LocalCluster of 2 worker processes, then a real `dask scheduler` with
two `dask worker` processes on 127.0.0.1, give the labels of the in-process run; killing a worker
mid-run still gives the complete, identical result (Dask reruns its tile on the other worker)."""
from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import laspy
import numpy as np
import pytest

from roadx_ti import config, tiling

REPO = Path(__file__).resolve().parents[1]
DASK = Path(sys.executable).with_name("dask")
TILE = 25.0            # two of the six IGN tiles in 25 m tiles: 8 tiles, several per worker
START_TIMEOUT = 90      # seconds for the scheduler and workers to come up
RUN_TIMEOUT = 300       # seconds for one run

WRAPPER = """\
import json, sys
from roadx_ti import config, tiling
cfg = config.load(sys.argv[1], ["backend=cpu"])
summary = tiling.run_catalog(cfg, sys.argv[2].split("|"), sys.argv[3], scheduler=sys.argv[4],
                             tile_size=float(sys.argv[5]), progress=True)
print(json.dumps({"executor": summary["executor"], "workers": [t["worker"] for t in summary["tiles"]]}))
"""


def inputs(shared_data) -> list[str]:
    return sorted(str(p) for p in (shared_data / "tiles").glob("*.laz"))[:2]


def ground_cfg():
    return config.load(REPO / "configs" / "ground.yaml", ["backend=cpu"])


def labels(path) -> tuple[np.ndarray, ...]:
    las = laspy.read(path)
    return (np.asarray(las.classification), np.asarray(las["roadx_label"]), np.asarray(las["segment_id"]),
            np.asarray(las.points.array["X"]), np.asarray(las.points.array["Y"]))


def assert_same(got, want):
    for a, b in zip(got, want):
        assert np.array_equal(a, b)


@pytest.fixture(scope="module")
def reference(shared_data, tmp_path_factory):
    """The in-process tiled run every executor must reproduce exactly."""
    out = tmp_path_factory.mktemp("ref") / "in_process.laz"
    summary = tiling.run_catalog(ground_cfg(), inputs(shared_data), out, tile_size=TILE, progress=False)
    assert summary["executor"] == "in-process"
    return labels(out)


def test_local_cluster_of_two_processes_gives_the_in_process_labels(reference, shared_data, tmp_path):
    out = tmp_path / "local.laz"
    summary = tiling.run_catalog(ground_cfg(), inputs(shared_data), out, tile_size=TILE, workers=2,
                                 progress=False)
    assert summary["executor"] == "local-cluster" and summary["workers"] == 2
    assert_same(labels(out), reference)
    pids = {t["worker"].rsplit(":", 1)[1] for t in summary["tiles"]}
    assert str(os.getpid()) not in pids            # the tiles ran in the worker processes


class DaskProcesses:
    """`dask scheduler` and named `dask worker` processes (no nanny: a killed worker stays dead)
    on 127.0.0.1 with free ports, stopped on exit."""

    def __init__(self, folder: Path, n_workers: int):
        self.folder, self.n_workers = folder, n_workers
        self.scheduler_file = folder / "scheduler.json"
        self.procs: dict[str, subprocess.Popen] = {}
        self.logs = []

    def _spawn(self, name, args, wrap=(), env=None):
        log = open(self.folder / f"{name}.log", "w")
        self.logs.append(log)
        self.procs[name] = subprocess.Popen([*wrap, str(DASK), *args], stdout=log, stderr=subprocess.STDOUT,
                                            cwd=self.folder, start_new_session=True,
                                            env=None if env is None else dict(os.environ, **env))

    def _worker_args(self, name):
        return ["worker", "--scheduler-file", str(self.scheduler_file), "--host", "127.0.0.1",
                "--nthreads", "1", "--no-nanny", "--no-dashboard", "--name", name,
                "--death-timeout", "60", "--local-directory", str(self.folder)]

    def add_worker(self, name, extra, wrap=(), env=None):
        """Start one more worker (``extra`` arguments, e.g. --preload) and wait until it joined."""
        self._spawn(name, [*self._worker_args(name), *extra], wrap=wrap, env=env)
        deadline = time.monotonic() + START_TIMEOUT
        while name not in {w["name"] for w in self.client.scheduler_info()["workers"].values()}:
            if time.monotonic() > deadline or self.procs[name].poll() is not None:
                pytest.fail(f"worker {name} did not start: " + (self.folder / f"{name}.log").read_text()[-2000:])
            time.sleep(0.2)

    def stop_worker(self, name):
        proc = self.procs.pop(name)
        proc.terminate()
        proc.wait(timeout=30)
        deadline = time.monotonic() + START_TIMEOUT
        while name in {w["name"] for w in self.client.scheduler_info()["workers"].values()}:
            assert time.monotonic() < deadline, f"worker {name} did not leave"
            time.sleep(0.2)

    def __enter__(self):
        from distributed import Client

        self._spawn("scheduler", ["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                  "--scheduler-file", str(self.scheduler_file)])
        deadline = time.monotonic() + START_TIMEOUT
        while not self.scheduler_file.exists():
            if time.monotonic() > deadline or self.procs["scheduler"].poll() is not None:
                self.__exit__(None, None, None)
                pytest.fail("dask scheduler did not start: " + (self.folder / "scheduler.log").read_text()[-2000:])
            time.sleep(0.2)
        for i in range(self.n_workers):
            self._spawn(f"w{i}", self._worker_args(f"w{i}"))
        self.client = Client(scheduler_file=str(self.scheduler_file), timeout=30)
        if self.n_workers:
            self.client.wait_for_workers(self.n_workers, timeout=START_TIMEOUT)
        self.address = self.client.scheduler.address
        assert self.address.startswith("tcp://127.0.0.1:")
        return self

    def worker_name(self, address: str) -> str:
        return self.client.scheduler_info()["workers"][address]["name"]

    def __exit__(self, *exc):
        with contextlib.suppress(Exception):
            self.client.close()
        for name in sorted(self.procs, key=lambda n: n == "scheduler"):   # workers first
            proc = self.procs[name]
            if proc.poll() is None:
                proc.terminate()
        for proc in self.procs.values():
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=10)
        for log in self.logs:
            log.close()


def start_wrapper(tmp_path: Path, paths: list[str], out: Path, address: str) -> subprocess.Popen:
    script = tmp_path / "run_scheduler.py"
    script.write_text(WRAPPER)
    return subprocess.Popen([sys.executable, str(script), str(REPO / "configs" / "ground.yaml"), "|".join(paths),
                             str(out), address, str(TILE)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, cwd=tmp_path)


def finish(proc: subprocess.Popen) -> dict:
    try:
        stdout, stderr = proc.communicate(timeout=RUN_TIMEOUT)
    except subprocess.TimeoutExpired:
        proc.kill()
        stdout, stderr = proc.communicate()
        pytest.fail(f"run did not finish in {RUN_TIMEOUT} s: {stderr[-2000:]}")
    assert proc.returncode == 0, stderr[-3000:]
    return json.loads(stdout.strip().splitlines()[-1])


def test_existing_scheduler_with_two_worker_processes_gives_the_same_labels(reference, shared_data, tmp_path):
    out = tmp_path / "scheduler.laz"
    with DaskProcesses(tmp_path, 2) as dask_procs:
        result = finish(start_wrapper(tmp_path, inputs(shared_data), out, dask_procs.address))
    assert result["executor"] == "scheduler"
    assert_same(labels(out), reference)


def test_killing_a_worker_mid_run_still_gives_the_complete_identical_result(reference, shared_data, tmp_path):
    out = tmp_path / "killed.laz"
    with DaskProcesses(tmp_path, 2) as dask_procs:
        run = start_wrapper(tmp_path, inputs(shared_data), out, dask_procs.address)
        victim, deadline = None, time.monotonic() + RUN_TIMEOUT
        busy_since = {}
        while victim is None and time.monotonic() < deadline and run.poll() is None:
            for address, keys in dask_procs.client.processing().items():
                if any(str(k).startswith("roadx-tile-") for k in keys):
                    busy_since.setdefault(address, time.monotonic())
                    if time.monotonic() - busy_since[address] > 0.5:   # well inside a tile
                        victim = dask_procs.worker_name(address)
                        break
                else:
                    busy_since.pop(address, None)
            time.sleep(0.05)
        assert victim is not None, "no worker was seen running a tile"
        os.kill(dask_procs.procs[victim].pid, signal.SIGKILL)
        result = finish(run)
        assert dask_procs.procs[victim].wait(timeout=10) == -signal.SIGKILL
    assert result["executor"] == "scheduler"
    assert_same(labels(out), reference)


# ------------------------------------------------------------------- failures in one line (issue 18)

# (an unreachable scheduler: tests/test_bad_inputs.py case_unreachable_scheduler)


OTHER_VERSION = """\
import roadx_ti
roadx_ti.__version__ = "0.0.0+other"      # a worker installed from another release
"""

# where a mount namespace cannot be made (no privileges): the worker's Python cannot open the folder
NO_ACCESS = """\
import builtins, os
_hidden = os.environ["ROADX_TEST_HIDDEN"]
if not getattr(builtins.open, "hides", None):          # dask may run a preload twice
    _open = builtins.open
    def _guarded(file, *args, **kwargs):
        if isinstance(file, (str, os.PathLike)) and os.path.abspath(os.fspath(file)).startswith(_hidden):
            raise FileNotFoundError(2, "No such file or directory", os.fspath(file))
        return _open(file, *args, **kwargs)
    _guarded.hides = _hidden
    builtins.open = _guarded
"""


def _mount_namespaces() -> bool:
    try:
        return subprocess.run(["unshare", "-m", "true"], capture_output=True, timeout=10).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def test_worker_with_another_version_or_without_the_inputs_fails_in_one_line(tmp_path):
    from cli_helpers import error_line, run_cli, write_las, bumpy_ground
    data = tmp_path / "data"
    data.mkdir()
    src = write_las(data / "in.laz", bumpy_ground(500))
    (tmp_path / "other_version.py").write_text(OTHER_VERSION)
    (tmp_path / "no_access.py").write_text(NO_ACCESS)
    out = tmp_path / "out" / "r.laz"

    def run(address):
        return run_cli("run", REPO / "configs" / "ground.yaml", "--backend", "cpu", "--quiet", "--input", src,
                       "--output", out, "--scheduler", address, timeout=RUN_TIMEOUT)

    with DaskProcesses(tmp_path, 0) as dask_procs:
        dask_procs.add_worker("old", ["--preload", str(tmp_path / "other_version.py")])
        line = error_line(run(dask_procs.address), 1)
        assert "runs roadx_ti 0.0.0+other" in line and "every worker needs the client's environment" in line
        dask_procs.stop_worker("old")
        if _mount_namespaces():       # the worker sees an empty folder where the data is (a missing mount)
            dask_procs.add_worker("blind", [], wrap=["unshare", "-m", "sh", "-c",
                                                     f'mount -t tmpfs none "{data}" && exec "$0" "$@"'])
        else:
            dask_procs.add_worker("blind", ["--preload", str(tmp_path / "no_access.py")],
                                  env={"ROADX_TEST_HIDDEN": str(data)})
        line = error_line(run(dask_procs.address), 1)
        assert f"cannot read {src}" in line and "same absolute path on every worker" in line
    assert not out.exists()


@pytest.mark.parametrize("greeting", [None, b"SSH-2.0-OpenSSH_9.6\r\n"])
def test_a_server_that_is_not_a_dask_scheduler_is_named_at_once(greeting):
    """--scheduler at a port where something else listens: a web server (the dashboard's port), which
    waits for a request (the client waited for ever), or a server that speaks first in another
    protocol (its bytes were read as a frame length of exabytes): one ClusterError within the
    connect timeout."""
    import socket
    import threading

    from roadx_ti.tiling.cluster import _reachable
    from roadx_ti.tiling.errors import ClusterError

    server = socket.create_server(("127.0.0.1", 0))
    accepted = []

    def serve():
        conn, _ = server.accept()
        accepted.append(conn)
        if greeting:
            conn.sendall(greeting)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    t0 = time.perf_counter()
    with pytest.raises(ClusterError, match="not a Dask scheduler"):
        _reachable(f"tcp://127.0.0.1:{server.getsockname()[1]}", 1.0)
    assert time.perf_counter() - t0 < 5.0
    thread.join(5)
    for conn in accepted:
        conn.close()
    server.close()


def _synthetic_street(path: Path, points: int, seed: int, density: float | None = None) -> Path:
    """The scene `python -m roadx_ti synth --kind uav-road` writes, made in this process (a CLI
    start less)."""
    from roadx_ti import io, synthetic

    cloud = synthetic.generate("uav-road", points, seed, density=density)
    io.write(path, cloud, classification=cloud.classification)
    return path


def test_ctrl_c_during_a_run_with_workers_says_one_line(tmp_path):
    """A terminal's Ctrl-C reaches every process of the group: the workers used to print tracebacks
    and Dask's shutdown warnings (3 to 36 lines); now the CLI's one line, exit 130, the previous
    output kept and no scratch records left."""
    import re as _re

    from cli_helpers import cli_command, cli_env, message_lines, sha256, write_las, bumpy_ground
    src = _synthetic_street(tmp_path / "street.laz", 150_000, seed=2)
    out = tmp_path / "out" / "r.laz"
    out.parent.mkdir()
    write_las(out, bumpy_ground(500))
    before = sha256(out)
    proc = subprocess.Popen(cli_command("run", Path(__file__).parents[1] / "configs" / "road_uav.yaml", "--backend", "cpu",
                                        "--input", src, "--output", out, "--workers", "2", "--tile-size", "20"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=cli_env(),
                            start_new_session=True)
    lines = []
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline:
        line = proc.stderr.readline()
        if not line:
            break
        lines.append(line)
        if _re.match(r"roadx_ti: tile 2/", line):     # workers busy with the next tiles
            os.killpg(proc.pid, signal.SIGINT)
            break
    rest = proc.communicate(timeout=120)[1]
    assert proc.returncode == 130, "".join(lines) + rest
    said = [line for line in message_lines(rest) if not line.startswith("roadx_ti: tile ")]   # progress lines
    assert "Traceback" not in rest and said == ["roadx_ti: interrupted; no partial output was left"], rest
    assert sha256(out) == before
    assert sorted(p.name for p in out.parent.iterdir()) == ["r.laz"]


def test_stage_warnings_of_the_workers_are_the_clis_lines_each_once_per_worker(tmp_path):
    """Each tile's stages warn alike (a 60 k road scene at 20 points/m2: its height noise blurs
    kerbs): the workers said it once per tile through Python's last-resort handler, without the
    'roadx_ti:' prefix (12 lines for 16 tiles); now once per worker, prefixed."""
    from cli_helpers import run_cli
    src = _synthetic_street(tmp_path / "street.laz", 60_000, seed=3, density=20.0)
    proc = run_cli("run", Path(__file__).parents[1] / "configs" / "road_uav.yaml", "--backend", "cpu", "--quiet",
                   "--input", src, "--output", tmp_path / "r.laz", "--workers", "2", "--tile-size", "25")
    assert proc.returncode == 0, proc.stderr
    noise = [line for line in proc.stderr.splitlines() if "kerbs lower than" in line]
    assert 1 <= len(noise) <= 2 and all(line.startswith("roadx_ti: road_regions: height noise") for line in noise), \
        proc.stderr
