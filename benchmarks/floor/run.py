"""The kernels against the machine's floor (issue 17, item 3): what each costs per point, and what
fraction of this machine's memory bandwidth or arithmetic rate it reaches.

    python benchmarks/floor/run.py [--points 4M] [--repeats 5]

One process, CPU backend, on the bench's uav-road scene (seed 0). First the machine's rates,
measured by Taichi kernels of this file on the same threads as the kernels: a copy (read and write
bandwidth, bytes read + written), a sum (read bandwidth) and independent FMA chains (the scalar
arithmetic rate Taichi code reaches); numpy's copy (memcpy, one thread) beside them. Then each kernel as its bench case calls it (one warm-up
call, the median of ``--repeats``), with:

- compulsory bytes per point: the input coordinates read once plus every array the call returns
  written once (the least traffic any implementation of that call needs), and the bandwidth that
  traffic implies at the measured time, as a fraction of the copy bandwidth;
- work per point where the kernel's work is countable: for the kNN family the points in the
  3 x 3 x 3 cells around each query (the first pass's candidates, counted on the kernel's own grid;
  an upper bound on the distances evaluated, since cells beyond the current k-th bound are
  skipped), for RANSAC the point-plane tests, for the cloth the particles times iterations; and
  the rate that work implies in flops (8 per candidate distance: 3 subtractions, 3 products, 2
  sums; 6 per point-plane test) as a fraction of the FMA rate (2 flops per FMA).

Writes ``floor-<points>.json`` beside this file and prints the markdown table that
benchmarks/RESULTS.md quotes.
"""

import argparse  # no "from __future__ import annotations": Taichi reads the kernels' annotations
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(REPO))

from roadx_ti import backend  # noqa: E402  (the repository first on the path)

FLOPS_PER_DISTANCE = 8      # d = p - q (3), d . d (3 products, 2 sums)
FLOPS_PER_PLANE_TEST = 6    # a x + b y + c z + d: 3 products, 3 sums
RATE_ELEMENTS = 1 << 26     # 256 MB float32 arrays: far beyond every cache
FMA_CHAINS = 16             # independent chains per task: more than FMA latency x pipes


def median_seconds(fn, repeats: int) -> float:
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def machine_rates(repeats: int) -> dict:
    from roadx_ti.kernels.taichi_compat import ti

    # range-for loops: LLVM vectorises them (a struct-for over the ndarray, 'for i in a', is not, and
    # copies at about a tenth of the rate here)
    @ti.kernel
    def copy(a: ti.types.ndarray(dtype=ti.f32, ndim=1), b: ti.types.ndarray(dtype=ti.f32, ndim=1)):
        for i in range(a.shape[0]):
            b[i] = a[i]

    @ti.kernel
    def total(a: ti.types.ndarray(dtype=ti.f32, ndim=1)) -> ti.f32:
        s = 0.0
        for i in range(a.shape[0]):
            s += a[i]
        return s

    @ti.kernel
    def fma_chains(out: ti.types.ndarray(dtype=ti.f32, ndim=1), steps: ti.i32):
        for t in out:
            x = ti.Vector([ti.cast(t + j, ti.f32) * 1e-6 for j in ti.static(range(FMA_CHAINS))])
            for _ in range(steps):
                for j in ti.static(range(FMA_CHAINS)):
                    x[j] = x[j] * 0.9999999 + 1e-7
            out[t] = x.sum()

    a = np.random.default_rng(0).random(RATE_ELEMENTS, dtype=np.float32)
    b = np.empty_like(a)
    copy_s = median_seconds(lambda: copy(a, b), repeats)
    numpy_copy_s = median_seconds(lambda: np.copyto(b, a), repeats)     # one thread: memcpy
    sum_s = median_seconds(lambda: total(a), repeats)
    tasks, steps = 1024, 1 << 16
    out = np.empty(tasks, np.float32)
    fma_s = median_seconds(lambda: fma_chains(out, steps), repeats)
    return {"copy_GBps": round(2 * a.nbytes / copy_s / 1e9, 2), "read_GBps": round(a.nbytes / sum_s / 1e9, 2),
            "numpy_copy_GBps": round(2 * a.nbytes / numpy_copy_s / 1e9, 2),
            "fma_GFLOPs": round(2 * tasks * steps * FMA_CHAINS / fma_s / 1e9, 2)}


def returned_bytes(value) -> int:
    """Bytes of every numpy array in a call's result (tuples, lists, dataclasses walked)."""
    if isinstance(value, np.ndarray):
        return value.nbytes
    if isinstance(value, (tuple, list)):
        return sum(returned_bytes(v) for v in value)
    if hasattr(value, "__dataclass_fields__"):
        return sum(returned_bytes(getattr(value, f)) for f in value.__dataclass_fields__)
    return 0


def cube_candidates(xyz: np.ndarray, k: int) -> float:
    """Mean number of points in the 3 x 3 x 3 cells around each query, on the grid knn() builds."""
    from roadx_ti.kernels.common import to_numpy
    from roadx_ti.kernels.grid import build_grid_into
    from roadx_ti.kernels.neighbors import default_points_per_cell

    grid = build_grid_into(xyz, None, default_points_per_cell(k), private=True)
    cells = to_numpy(grid.sorted_cell).astype(np.int64)
    span = cells.max(axis=0) + 3          # +1 margin each side: neighbours of border cells exist
    key = lambda c: ((c[:, 2] + 1) * span[1] + (c[:, 1] + 1)) * span[0] + (c[:, 0] + 1)  # noqa: E731
    occupied, count = np.unique(key(cells), return_counts=True)
    coords = np.stack(np.unravel_index(occupied, (span[2], span[1], span[0]))[::-1], axis=1) - 1
    around = np.zeros(len(occupied), np.int64)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                other = key(coords + np.array([dx, dy, dz]))
                at = np.searchsorted(occupied, other)
                hit = (at < len(occupied)) & (occupied[np.minimum(at, len(occupied) - 1)] == other)
                around[hit] += count[at[hit]]
    return float((around * count).sum() / count.sum())


def cases(scene):
    """(name, bench case, variant params, work per point function or None, flops per work item)."""
    from roadx_ti.kernels.ransac import FINALISTS, SAMPLE_SIZE

    n = len(scene.xyz)
    return [
        ("kNN k=16", "knn", {"k": 16}, lambda: cube_candidates(scene.xyz, 16), FLOPS_PER_DISTANCE),
        ("SOR k=20", "sor", {"k": 20, "std_ratio": 2.0}, lambda: cube_candidates(scene.xyz, 20), FLOPS_PER_DISTANCE),
        ("normals k=20", "normals", {"k": 20}, lambda: cube_candidates(scene.xyz, 20), FLOPS_PER_DISTANCE),
        ("voxel downsampling 0.25 m", "voxel_downsample", {"voxel_size": 0.25}, None, 0),
        ("grid minimum 0.5 m", "grid_min", {"step": 0.5, "slope_max": 0.1, "dh_max": 1.0}, None, 0),
        # preemptive pass over the sample, the finalists over all points, the inliers twice
        ("RANSAC 1000 hypotheses", "ransac", {"distance_threshold": 0.1, "hypotheses": 1000},
         lambda: (1000 * min(n, SAMPLE_SIZE) + (FINALISTS + 2) * n) / n, FLOPS_PER_PLANE_TEST),
        ("CSF 0.5 m", "csf", {"cloth_resolution": 0.5, "rigidness": 3, "time_step": 0.65, "iterations": 500,
                              "class_threshold": 0.5, "slope_smooth": False}, None, 0),
    ]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--points", default="4M")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    from roadx_ti.config import parse_point_count

    n = parse_point_count(args.points)
    backend.init("cpu")
    from roadx_ti.bench.cases import load_case, make_scene

    rates = machine_rates(args.repeats)
    print(f"machine (Taichi CPU kernels): copy {rates['copy_GBps']} GB/s, read {rates['read_GBps']} GB/s, "
          f"FMA {rates['fma_GFLOPs']} GFLOP/s; numpy copy (one thread) {rates['numpy_copy_GBps']} GB/s")
    scene = make_scene("uav-road", n, 0)
    rows = []
    for name, stage, params, work_of, flops in cases(scene):
        call = load_case(stage).IMPLS["roadx_ti"](scene, **params)
        result = call()
        seconds = median_seconds(call, args.repeats)
        per_point = (scene.xyz.nbytes + returned_bytes(result)) / n
        row = {"kernel": name, "median_s": round(seconds, 4), "ns_per_point": round(1e9 * seconds / n, 1),
               "compulsory_B_per_point": round(per_point, 1),
               "compulsory_GBps": round(per_point * n / seconds / 1e9, 3)}
        row["bandwidth_share"] = round(row["compulsory_GBps"] / rates["copy_GBps"], 4)
        if stage == "csf":
            cols, rows_ = result.shape[1], result.shape[0]
            row["work"] = f"{rows_ * cols} particles x {result.iterations} iterations"
        if work_of is not None:
            work = work_of()
            row["work_per_point"] = round(work, 1)
            row["GFLOPs"] = round(work * flops * n / seconds / 1e9, 2)
            row["flop_share"] = round(row["GFLOPs"] / rates["fma_GFLOPs"], 3)
        rows.append(row)
        print(json.dumps(row), flush=True)
    out = HERE / f"floor-{args.points}.json"
    out.write_text(json.dumps({"points": n, "machine": rates, "rows": rows}, indent=1) + "\n")
    print(f"\nwrote {out.relative_to(REPO)}\n")
    print("| kernel | median s | ns / point | compulsory B / point | GB/s | of copy bandwidth | work / point | GFLOP/s | of FMA rate |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        work = r.get("work_per_point", r.get("work", "-"))
        flop_share = f"{100 * r['flop_share']:.1f} %" if "flop_share" in r else "-"
        print(f"| {r['kernel']} | {r['median_s']} | {r['ns_per_point']} | {r['compulsory_B_per_point']} | "
              f"{r['compulsory_GBps']} | {100 * r['bandwidth_share']:.1f} % | {work} | {r.get('GFLOPs', '-')} | "
              f"{flop_share} |")


if __name__ == "__main__":
    main()
