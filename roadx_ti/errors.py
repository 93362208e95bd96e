"""Errors meant for the user, one line each, that the CLI turns into exit codes without a
traceback: DataError (exit 1) for a problem of the data or of the machine it runs on (an extent
no structure can be built over, memory, an unreachable cluster), as io.InputError is for a file."""
from __future__ import annotations


class DataError(Exception):
    """A data mistake (exit 1); the message is one line."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))
