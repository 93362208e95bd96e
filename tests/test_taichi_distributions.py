"""taichi and taichi-forge give the same labels: the demo's road pipeline run under this
interpreter's Taichi and under another interpreter's (``ROADX_TI_COMPARE_PYTHON``, set by
``./dev test`` for its taichi-forge run) on the same scene, compared point for point."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from roadx_ti.kernels import taichi_compat

OTHER_PYTHON = os.environ.get("ROADX_TI_COMPARE_PYTHON")

RUN = """
import json, sys
import numpy as np
from roadx_ti import backend, config, pipelines, synthetic
from roadx_ti.kernels import taichi_compat
backend.init("cpu")
cfg = config.load("configs/demo.yaml")
cloud = synthetic.generate("uav-road", int(sys.argv[1]), seed=0)
result = pipelines.run(cloud, pipelines.build_stages(cfg.stage_list()))
np.save(sys.argv[2], result.classification)
print(json.dumps({"taichi": taichi_compat.description()}))
"""


def _labels(python, points, path):
    # each interpreter takes the Taichi its venv has (auto), whatever this process was asked for
    env = {k: v for k, v in os.environ.items() if k != taichi_compat.ENVIRONMENT_VARIABLE}
    proc = subprocess.run([python, "-c", RUN, str(points), str(path)], capture_output=True, text=True,
                          timeout=600, cwd=os.path.dirname(os.path.dirname(__file__)), env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])["taichi"], np.load(path)


def test_distribution_is_reported():
    assert taichi_compat.DISTRIBUTION in taichi_compat.DISTRIBUTIONS
    assert taichi_compat.description().startswith(taichi_compat.DISTRIBUTION + " ")


@pytest.mark.kernel
@pytest.mark.skipif(not OTHER_PYTHON, reason="ROADX_TI_COMPARE_PYTHON (another venv's python) not set; "
                    "./dev test sets it for its taichi-forge run")
def test_demo_labels_agree_between_distributions(tmp_path):
    mine, ours = _labels(sys.executable, 300_000, tmp_path / "mine.npy")
    theirs, other = _labels(OTHER_PYTHON, 300_000, tmp_path / "other.npy")
    assert mine != theirs, f"both interpreters run {mine}: nothing compared"
    differ = int((ours != other).sum())
    assert differ == 0, f"{mine} and {theirs} label {differ} of {len(ours)} points differently"
