"""First call of the road CLI with a cold offline cache, then with that cache filled, at one
commit against another, alternating rounds (each round a fresh TI_OFFLINE_CACHE_FILE_PATH).

    python benchmarks/commit_ab/first_call.py --base-tree DIR SCENE.laz [--rounds 2]

``--base-tree``: a checkout of the base commit with its own ``.venv`` (``./dev setup`` there); this
checkout is the other side. Wall times from GNU time, as in run.py. Prints the wall times per
round, the medians and base / new per round.
"""
import argparse
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from run import run_cli     # this folder's A/B runner (the CLI in a tree's own .venv, under GNU time)

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
                        row = run_cli(tree, "configs/road_uav.yaml", a.scene.resolve(), Path(tmp) / f"{side}.laz",
                                      env=env)
                        rows[side][kind].append(row["wall_s"])
                print(side, rows[side], flush=True)
    print(json.dumps({s: {k: float(np.median(v)) for k, v in d.items()} for s, d in rows.items()}))
    for kind in ("cold", "cached"):
        print(f"base / new {kind} per round", [round(b / n, 3) for b, n in zip(rows["base"][kind], rows["new"][kind])])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
