"""A whole process as a benchmark row: a command run as a child under GNU time (its wall time,
user + system CPU seconds and its own peak RSS), for the scripts in ``benchmarks/`` that time the
CLI or a peer's script end to end (commit_ab, road_anchor)."""
from __future__ import annotations

import subprocess
import tempfile


def timed_run(argv: list[str], cwd, env: dict | None = None) -> tuple[dict, str]:
    """({wall_s, cpu_s, peak_rss_mb}, stdout) of ``argv`` run in ``cwd``; a failed run ends the
    benchmark with its last stderr line."""
    with tempfile.NamedTemporaryFile("r", suffix=".time") as stats:
        proc = subprocess.run(["/usr/bin/time", "-o", stats.name, "-f", "%e %U %S %M", *map(str, argv)], cwd=cwd,
                              env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            raise SystemExit(f"{' '.join(map(str, argv[:4]))} failed in {cwd}: {proc.stderr.strip().splitlines()[-1:]}")
        wall, user, system, rss_kb = stats.read().split()[-4:]
    return {"wall_s": float(wall), "cpu_s": round(float(user) + float(system), 2),
            "peak_rss_mb": round(int(rss_kb) / 1024, 1)}, proc.stdout
