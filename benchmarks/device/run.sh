#!/usr/bin/env bash
# The GPU machine's run: `python -m roadx_ti bench` on CUDA at 1 M and 4 M (offline cache fresh,
# then warm) and 16 M, and the road and roof CLIs on one scene on the CPU and on CUDA with their
# labels compared point by point (agreement.py). Run from the repository root:
#     bash benchmarks/device/run.sh OUTDIR
# On a machine without the project installed, wheels in .whl/ (if present) go to /tmp/site and the
# checkout is used as the package (roadx_ti.kernels is kernels/, as pyproject.toml maps it).
# With TESTS=1 the kernel tests (pytest -m kernel) run on CUDA first (not yet run there: ~130 tests,
# 18 s on this repository's CPU backend without the packages the device lacks).
# Time: SECONDS_TOTAL (default 450) for the whole script, counted from its start. Each step gets a
# share of what is left; a step is skipped when under a minute is left. The bench's --timeout
# limits each of its worker processes (a bench step with several workers can run longer), and
# the bench writes its JSON only at its end, so it is not killed from outside.
set -uo pipefail
out=${1:?usage: run.sh OUTDIR}
total=${SECONDS_TOTAL:-450}
start=$SECONDS
mkdir -p "$out"
exec > >(tee -a "$out/device.log") 2>&1
export PYTHONUNBUFFERED=1 PYTHONWARNINGS=ignore
if [ -d .whl ]; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
  export PYTHONPATH=/tmp/site:$PWD
fi
python3 -c 'import roadx_ti.kernels' 2>/dev/null || { ln -sfn ../kernels roadx_ti/kernels; export PYTHONPATH=${PYTHONPATH:-}:$PWD; }
stamp() { echo "== $(date -u +%H:%M:%S) +$((SECONDS - start)) s: $*"; }
left() { echo $((total - (SECONDS - start))); }
# seconds for a step: the smaller of $1 and what is left, at least 1 (timeout 0 would mean no limit)
cap() { local l; l=$(left); l=$(( l < $1 ? l : $1 )); echo $(( l > 1 ? l : 1 )); }
enough() { [ "$(left)" -ge 60 ] || { stamp "skipped ($(left) s left): $*"; return 1; }; }
stamp "machine"; nvidia-smi --query-gpu=name,driver_version,memory.total,compute_cap --format=csv; nproc; python3 -V
stamp "cuda sanity"
timeout 120 python3 - <<'PY' || { stamp "CUDA backend unavailable: stopping"; exit 3; }
from roadx_ti import backend
print("arch:", backend.init("cuda"))
PY
bench() { python3 -m roadx_ti bench --backends cuda --impls roadx_ti --budget 0.5 --rounds 1 --out "$out" \
          --results /tmp/roadx_results.md --plot /tmp/roadx_plot.png "$@"; }
if [ "${TESTS:-0}" = 1 ] && enough "kernel tests"; then
  stamp "kernel tests on CUDA"
  ROADX_TI_TEST_BACKENDS=cuda timeout "$(cap 200)" python3 -m pytest -q -m kernel -p no:cacheprovider \
    --continue-on-collection-errors --junitxml="$out/kernel-tests-cuda.xml" 2>&1 | tail -25
fi
enough "bench 1M,4M" && { stamp "bench 1M,4M"; bench --sizes 1M,4M --cache fresh --timeout "$(cap 110)"; }
enough "agreement" && stamp "agreement 1M cpu/cuda" &&
timeout "$(cap 100)" python3 benchmarks/device/agreement.py --points 1M --backends cpu,cuda --out "$out/agreement-1M.json"
# 16 M: the stages the CPU rows have at that size, the kernels of the road pipeline, and the pipeline
enough "bench 16M" && stamp "bench 16M" && bench --sizes 16M --cache default --timeout "$(cap $(( $(left) - 25 )))" \
  --stages voxel_hash,knn,voxel_downsample,sor,normals,ransac,grid_min,csf,road_pipeline
stamp "done"
