"""Loggers of other libraries kept quiet for a while (their messages would repeat ours)."""
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
