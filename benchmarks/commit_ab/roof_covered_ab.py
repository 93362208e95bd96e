"""python benchmarks/commit_ab/roof_covered_ab.py POINTS ROUNDS

A/B of roof_growing's covered test (issue 16, commit 30a3f4e) on the bench's roof_pipeline case:
roof_growing.covered_clearance 1.0 (new) against 0 (off: the stage as before that commit), through
roof_option_ab.py (one process, alternating rounds after a warm-up each; medians and per-round
ratios)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from roof_option_ab import main  # noqa: E402

if __name__ == "__main__":
    main(sys.argv[1:3] + ["stages.roof_growing.covered_clearance=0.0", "stages.roof_growing.covered_clearance=1.0"])
