"""The two ways a tiled run fails."""
from __future__ import annotations

from roadx_ti.errors import DataError


class TileError(RuntimeError):
    """A tile failed (after its retries); the message names it by its bounds. Nothing was written."""


class ClusterError(DataError):
    """The Dask cluster cannot run the tiles (unreachable scheduler, no workers, workers with
    another environment or without the inputs); one line, raised before any tile runs."""
