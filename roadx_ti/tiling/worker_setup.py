"""Preloaded in the Dask worker processes of a LocalCluster the CLI owns (tiling.cluster).

A terminal's Ctrl-C goes to the whole process group: the workers printed KeyboardInterrupt
tracebacks of their own while the CLI, which decides what an interrupt means (remove the scratch
records, keep the previous outputs, one line), closed the cluster. The workers leave SIGINT to it,
and Dask's logs only what is critical: a tile's failure reaches the CLI as the task's exception, and
a closed run's cancelled tasks and lost heartbeats (warnings and tracebacks) tell the user nothing.
The stages' own warnings are said as the CLI says them, each once per worker.
"""
from __future__ import annotations

import contextlib
import logging
import signal


def dask_setup(worker) -> None:
    logging.getLogger("distributed").setLevel(logging.CRITICAL)
    # the stages' warnings as the CLI says them ('roadx_ti: ...', each once per worker; they went
    # through Python's last-resort handler, unprefixed, once per tile)
    from roadx_ti.quiet_logs import FirstOfEachWarning, say_as_the_cli

    say_as_the_cli(logging.WARNING).addFilter(FirstOfEachWarning())
    with contextlib.suppress(ValueError):      # not the process's main thread: nothing to change
        signal.signal(signal.SIGINT, signal.SIG_IGN)
