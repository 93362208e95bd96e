"""First call of the road CLI with a cold offline cache, then with that cache filled, at one
commit against another, alternating rounds (each round a fresh TI_OFFLINE_CACHE_FILE_PATH).

    python benchmarks/commit_ab/first_call.py --base-tree DIR SCENE.laz [--rounds 2]

``--base-tree``: a checkout of the base commit with its own ``.venv`` (``./dev setup`` there); this
checkout is the other side. Prints the wall times per round, the medians and base / new per round.
"""
import argparse
import json
import os
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--base-tree", required=True, type=Path)
    p.add_argument("scene", type=Path)
    p.add_argument("--rounds", type=int, default=2)
    a = p.parse_args()
    trees = {"base": a.base_tree.resolve(), "new": REPO}
    rows = {k: {"cold": [], "cached": []} for k in trees}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(a.rounds):
            for side, tree in trees.items():
                with tempfile.TemporaryDirectory() as cache:
                    env = dict(os.environ, TI_OFFLINE_CACHE_FILE_PATH=cache)
                    for kind in ("cold", "cached"):
                        t = time.perf_counter()
                        proc = subprocess.run([str(tree / ".venv" / "bin" / "python"), "-m", "roadx_ti", "run",
                                               "configs/road_uav.yaml", "--input", str(a.scene.resolve()),
                                               "--output", str(Path(tmp) / f"{side}.laz"), "--quiet"],
                                              cwd=tree, env=env, capture_output=True, text=True)
                        if proc.returncode != 0:
                            raise SystemExit(f"run in {tree} failed: {proc.stderr.strip().splitlines()[-1:]}")
                        rows[side][kind].append(round(time.perf_counter() - t, 2))
                print(side, rows[side], flush=True)
    print(json.dumps({s: {k: float(np.median(v)) for k, v in d.items()} for s, d in rows.items()}))
    for kind in ("cold", "cached"):
        print(f"base / new {kind} per round", [round(b / n, 3) for b, n in zip(rows["base"][kind], rows["new"][kind])])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
