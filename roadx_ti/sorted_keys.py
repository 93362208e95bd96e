"""Lookups of integer keys in a sorted array of keys: the sparse grids of footprint, isolation,
the RANSAC stage and the tile plan keep only their occupied cells, by sorted cell key, and find a
cell's neighbours by searching for the neighbours' keys."""
from __future__ import annotations

import numpy as np


def find(sorted_keys: np.ndarray, query) -> tuple[np.ndarray, np.ndarray]:
    """(position, found) of every ``query`` key in ``sorted_keys`` (ascending): ``found`` where
    the key is there, at ``position``; elsewhere ``position`` is a valid index with no meaning."""
    query = np.asarray(query)
    if len(sorted_keys) == 0:
        return np.zeros(query.shape, np.int64), np.zeros(query.shape, bool)
    at = np.minimum(np.searchsorted(sorted_keys, query), len(sorted_keys) - 1)
    return at, sorted_keys[at] == query
