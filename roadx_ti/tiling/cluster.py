"""The Dask cluster of a run: a client on an existing scheduler or on a LocalCluster we own, checked
before any tile (scheduler reachable, a worker present, the same environment, the inputs readable)."""
from __future__ import annotations

import contextlib
import logging
import socket
import sys

from roadx_ti.quiet_logs import quieted
from roadx_ti.tiling.errors import ClusterError

CONNECT_TIMEOUT = 5.0            # s: reaching the scheduler
WORKER_TIMEOUT = 30.0            # s: waiting for the first worker
MAX_HANDSHAKE_BYTES = 1 << 24    # a Dask handshake's length is small; more: another protocol
# what must match between the client and every worker (README, Scale-out)
ENVIRONMENT_PACKAGES = ("numpy", "laspy", "lazrs", "scipy", "dask", "distributed")


def environment() -> dict:
    """The versions a worker must share with the client: roadx_ti, Python (major.minor), the Taichi
    distribution and version, and ENVIRONMENT_PACKAGES. Runs on every worker (Client.run)."""
    import importlib.metadata as metadata

    import roadx_ti
    from roadx_ti.kernels import taichi_compat

    env = {"roadx_ti": roadx_ti.__version__, "python": "%d.%d" % sys.version_info[:2],
           taichi_compat.DISTRIBUTION: ".".join(map(str, taichi_compat.ti.__version__))}
    for name in ENVIRONMENT_PACKAGES:
        try:
            env[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            env[name] = None
    return env


def unreadable(paths) -> list:
    """[(path, problem)] of the input files this process cannot read (runs on every worker)."""
    problems = []
    for p in paths:
        try:
            with open(p, "rb") as f:
                f.read(1)
        except OSError as exc:
            problems.append((p, exc.strerror or type(exc).__name__))
    return problems


def _reachable(address: str, timeout: float) -> None:
    """A plain TCP connection to a tcp:// scheduler address, so that a closed port or an unknown
    host fails at once instead of after the client's retries; and a check that what answers there
    is a Dask scheduler. A Dask server writes its handshake as soon as a connection opens (its
    length, 8 bytes, then the message); a web server (the dashboard's port 8787) waits for a
    request, which the client's handshake is not: the client then waited for ever, and data from
    another kind of server was read as a length (an allocation of exabytes)."""
    from urllib.parse import urlsplit

    if not address.startswith("tcp://"):
        return
    try:
        parts = urlsplit(address)      # 'tcp://[::1' raises here: Invalid IPv6 URL
        port = parts.port
    except ValueError:
        raise ClusterError(f"--scheduler {address}: not a tcp://HOST:PORT address") from None
    if not parts.hostname or port is None:
        raise ClusterError(f"--scheduler {address}: not a tcp://HOST:PORT address")
    try:
        connection = socket.create_connection((parts.hostname, port), timeout=timeout)
    except OSError as exc:
        why = exc.strerror or type(exc).__name__
        raise ClusterError(f"cannot reach the Dask scheduler at {address} ({why}); start `dask scheduler` "
                           "there, or run without --scheduler") from None
    length = b""
    try:
        with connection:
            while len(length) < 8:
                chunk = connection.recv(8 - len(length))
                if not chunk:
                    break
                length += chunk
    except OSError:       # nothing within the timeout, or a reset
        pass
    hint = "give the scheduler's address (`dask scheduler` prints it, port 8786 by default; 8787 is its dashboard)"
    if not length:
        raise ClusterError(f"what listens at {address} sent no Dask handshake within {timeout:g} s: not a Dask "
                           f"scheduler, or one too busy to answer; {hint}")
    # the length in the server's byte order (struct 'Q'): small one way or the other
    if len(length) < 8 or min(int.from_bytes(length, "little"), int.from_bytes(length, "big")) > MAX_HANDSHAKE_BYTES:
        raise ClusterError(f"what answers at {address} is not a Dask scheduler (it sent other bytes than a Dask "
                           f"handshake); {hint}")


class _DaskSession:
    """A client on an existing scheduler, or on a LocalCluster of worker processes we own.
    Before any tile: the scheduler is reached within CONNECT_TIMEOUT, a worker joins within
    WORKER_TIMEOUT, every worker runs the client's environment and can read every input."""

    def __init__(self, workers: int | None, scheduler: str | None, log, inputs=(),
                 connect_timeout: float = CONNECT_TIMEOUT, worker_timeout: float = WORKER_TIMEOUT):
        from distributed import Client, LocalCluster

        self.cluster = None
        self.client = None
        if scheduler:
            _reachable(scheduler, connect_timeout)
            try:
                self.client = Client(scheduler, timeout=f"{connect_timeout}s")
            except (OSError, TimeoutError) as exc:
                raise ClusterError(f"cannot connect to the Dask scheduler at {scheduler} within "
                                   f"{connect_timeout:g} s ({type(exc).__name__}: {' '.join(str(exc).split())[:200]})"
                                   ) from None
            try:
                self.client.wait_for_workers(1, timeout=worker_timeout)
            except (OSError, TimeoutError):
                self.close()
                raise ClusterError(f"the Dask scheduler at {scheduler} has no worker after {worker_timeout:g} s; "
                                   f"start one with `dask worker {scheduler}`") from None
            self.kind = "scheduler"
        else:
            # the workers leave Ctrl-C to this process (worker_setup)
            self.cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                        dashboard_address=None, silence_logs=logging.WARNING,
                                        preload=["roadx_ti.tiling.worker_setup"])
            self.client = Client(self.cluster)
            self.kind = "local-cluster"
        try:
            self._check_workers(inputs)
        except BaseException:
            self.close()
            raise
        self.workers = max(1, len(self.client.scheduler_info().get("workers", {})))
        log.info("Dask %s at %s with %d worker(s)", self.kind, self.client.scheduler.address, self.workers)

    def _check_workers(self, inputs):
        mine = environment()
        theirs = self.client.run(environment, on_error="return")
        for worker, env in sorted(theirs.items()):
            if isinstance(env, BaseException):
                raise ClusterError(f"Dask worker {worker} cannot run roadx_ti ({type(env).__name__}: "
                                   f"{' '.join(str(env).split())[:200]}); install the client's roadx_ti "
                                   "environment on every worker")
            differ = [f"{k} {env.get(k)} (here {v})" for k, v in mine.items() if env.get(k) != v]
            if differ:
                raise ClusterError(f"Dask worker {worker} runs {', '.join(differ)}; every worker needs the "
                                   "client's environment (the same roadx_ti, Python and package versions)")
        if inputs:
            problems = self.client.run(unreadable, list(inputs), on_error="return")
            for worker, found in sorted(problems.items()):
                if isinstance(found, BaseException):
                    raise ClusterError(f"Dask worker {worker} cannot check the inputs ({type(found).__name__}: "
                                       f"{' '.join(str(found).split())[:200]})")
                if found:
                    path, why = found[0]
                    more = f" (and {len(found) - 1} more input(s))" if len(found) > 1 else ""
                    raise ClusterError(f"Dask worker {worker} cannot read {path} ({why}){more}; every input "
                                       "must be readable under the same absolute path on every worker")

    def close(self):
        # a run stopped mid-tile closes busy workers: Dask's "still alive after 4.0 seconds, killing"
        # and its other shutdown warnings say nothing to the user, who was told the run stopped
        with quieted(("distributed", "distributed.nanny", "distributed.worker"), logging.ERROR):
            self._close()

    def _close(self):
        if self.client is not None:
            with contextlib.suppress(Exception):
                self.client.close()
        if self.cluster is not None:
            with contextlib.suppress(Exception):
                self.cluster.close()
