"""Preloaded in the Dask worker processes of a LocalCluster the CLI owns (tiling.cluster).

A terminal's Ctrl-C goes to the whole process group: the workers printed KeyboardInterrupt
tracebacks of their own while the CLI, which decides what an interrupt means (remove the scratch
records, keep the previous outputs, one line), closed the cluster. The workers leave SIGINT to it,
and log only what is critical: a tile's failure reaches the CLI as the task's exception, and a
closed run's cancelled tasks and lost heartbeats (warnings and tracebacks) tell the user nothing.
"""
from __future__ import annotations

import contextlib
import logging
import signal


def dask_setup(worker) -> None:
    logging.getLogger("distributed").setLevel(logging.CRITICAL)
    with contextlib.suppress(ValueError):      # not the process's main thread: nothing to change
        signal.signal(signal.SIGINT, signal.SIG_IGN)
