"""Log lines kept from repeating: other libraries' loggers quiet for a while (their messages would
repeat ours), and the same warning of every tile said once."""
from __future__ import annotations

import contextlib
import logging
import threading

# logger levels are the process's: one quieting at a time, so that the last to end restores them
_LOCK = threading.RLock()


@contextlib.contextmanager
def quieted(names, level: int):
    """Inside, the loggers ``names`` say nothing below ``level``; their levels are restored after."""
    with _LOCK:
        loggers = [logging.getLogger(name) for name in names]
        levels = [logger.level for logger in loggers]
        for logger in loggers:
            logger.setLevel(level)
        try:
            yield
        finally:
            for logger, previous in zip(loggers, levels):
                logger.setLevel(previous)


def say_as_the_cli(level: int) -> logging.Logger:
    """The 'roadx_ti' logger writing 'roadx_ti: MESSAGE' lines to stderr from ``level`` on, and not
    through the root logger (the CLI's process and the Dask workers it starts)."""
    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter("roadx_ti: %(message)s"))
    ours = logging.getLogger("roadx_ti")
    ours.handlers[:] = [handler]
    ours.setLevel(level)
    ours.propagate = False
    return ours


class FirstOfEachWarning(logging.Filter):
    """Every tile runs the same stages, which warn of the same thing in each (no colour, k above the
    points): each warning's first occurrence only, whatever its numbers."""

    def __init__(self):
        super().__init__()
        self.seen = set()

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno != logging.WARNING:
            return True
        key = str(record.msg)          # the message's template: the same warning with other numbers
        if key in self.seen:
            return False
        self.seen.add(key)
        return True
