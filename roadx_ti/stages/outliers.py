"""R2 statistical outlier removal (kernel: roadx_ti.kernels.outliers.sor_keep).

Isolated points (roadx_ti.isolation: a part of at most k points, more than 100 m from every other
point) are outliers whatever the statistics say: their k neighbourhood reaches across the gap. They
are removed and left out of mu and sigma, which a handful of points kilometres away would
otherwise inflate for the whole cloud (a cloud without them is filtered exactly as before).
"""
from __future__ import annotations

import inspect
from typing import Literal

import numpy as np
from pydantic import Field

from roadx_ti import isolation
from roadx_ti.cloud import Cloud
from roadx_ti.kernels.neighbors import MAX_K
from roadx_ti.kernels.outliers import CONVENTIONS, MODES, sor_keep
from roadx_ti.stages.base import MIN_BUFFER, Stage, StageContext, StageOptions, StageResult


_KERNEL = inspect.signature(sor_keep).parameters


class SorOptions(StageOptions):
    k: int = Field(20, ge=1, le=MAX_K, description="neighbours per point (paper k = 500; at most the "
                   "kNN kernel's MAX_K)")
    std_ratio: float = Field(1.0, gt=0, description="std multiplier (paper std = 1)")
    mode: Literal[MODES] = Field(  # type: ignore[valid-type]
        _KERNEL["mode"].default, description="two_sided: keep mu - s*sigma < d < mu + s*sigma (paper); "
        "upper: keep d < mu + s*sigma (PCL/Open3D)")
    # The kernel's own default is 'open3d' (a point-for-point Open3D drop-in for embedding, see
    # kernels/outliers.py); the pipeline stage follows the paper (METHODS.md R2).
    convention: Literal[CONVENTIONS] = Field(  # type: ignore[valid-type]
        "paper", description="paper: k neighbours excluding p, population sigma; open3d: p counts "
        "as one of the k, sample sigma, and d = 0 is dropped (point-for-point Open3D)")


class StatisticalOutlierRemoval(Stage):
    name = "sor"
    Options = SorOptions

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        return MIN_BUFFER     # a point's k nearest neighbours (mu and sigma are per cloud, not spatial)

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        o = self.options
        k = min(o.k, cloud.n - 1)
        if k < 1:
            return StageResult(info={"skipped": "fewer than 2 points"})
        if k < o.k:
            ctx.log.warning("sor: k = %d but only %d points: using k = %d", o.k, cloud.n, k)
        isolated = isolation.isolated_in(cloud.xyz, k, ctx)
        if isolated is None:
            keep = np.asarray(sor_keep(cloud.xyz, k, o.std_ratio, mode=o.mode, convention=o.convention), bool)
            return StageResult(keep=keep, info={"removed": int((~keep).sum()), "k": k})
        rest = np.flatnonzero(~isolated)
        keep = np.zeros(cloud.n, bool)
        k_rest = min(k, len(rest) - 1)
        if k_rest >= 1:
            keep[rest] = np.asarray(sor_keep(cloud.xyz[rest], k_rest, o.std_ratio, mode=o.mode,
                                             convention=o.convention), bool)
        return StageResult(keep=keep, info={"removed": int((~keep).sum()), "k": k,
                                            "isolated": int(isolated.sum())})
