"""Accuracy report: both pipelines on the real labelled tiles and on synthetic scenes.

    python -m roadx_ti accuracy [--task road|roof|all] [--out benchmarks/accuracy] [--roof-sizes 300k,1M,4M] [--roof-seeds 0-9] [--road-sizes ...]

Writes ``ACCURACY.md`` (type I / II / total error and kappa per dataset, and per stage how many
target and non-target points it removed), ``accuracy.json`` and one truth / prediction / error PNG
per dataset into the output folder. A run of one task keeps the other task's rows from the folder's
earlier ``accuracy.json`` (the report's first line says which command produced which section).
"""
from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"
log = logging.getLogger("roadx_ti")

# Published or measured reference rows quoted in the report (not computed here).
REFERENCE_ROWS = {
    "road": [
        ("paper (R), own 80 M-point UAV data", {"type1": 0.0497, "type2": 0.0114}),
        ("Vo-SmoG (Che et al. 2021), as quoted by R", {"type1": 0.0932, "type2": 0.0289}),
    ],
    "roof": [
        ("patent (P), Estonian ALS test areas", {"total": "< 0.02", "kappa": "~0.97"}),
        ("existing tools (CSF + 2.5 m + Open3D planes + DBSCAN 50+), ign_870000_6618000", {"kappa": 0.72}),
        ("existing tools, ign_874000_6617000_reviewed", {"kappa": 0.97}),
    ],
}


# Facts about a dataset or a result that the numbers alone do not show (measured; see the
# session notes of the commit that wrote them).
NOTES = {
    "road": [
        "road_uav.yaml runs R6 as `road_regions` (region-level merging by mean colour over thresholds "
        "scaled by the measured colour noise, never across kerbs; road chosen by one minimum cut over "
        "the region graph): every threshold follows the estimates listed per scene below. The earlier "
        "point-to-point `color_growing` (Q_t 10) found no road on the uav-road scenes at all: E1 97-100 % "
        "(2026-12-01).",
        "Failure modes seen in the pictures and single runs (2026-12-01): kerbs hidden behind parked "
        "cars or under canopies let sidewalk or shadowed lot join the road (E2), and road pieces cut off "
        "by parked cars or deep shadow are dropped (E1); these are whole regions, so a scene's figures "
        "move by several points between near-identical deliveries (tests/test_invariance.py: 93.7-99.2 % "
        "label agreement for 1 mm / 1 cm LAZ and half density; shuffled and 8-bit colour exact; "
        "99.07-99.43 % on 2026-12-03 with slope smoothing, 99.14-99.45 % with the surface test, 98.31-98.51 % "
        "with R4's supported cell reference, whose in-memory run takes a sidewalk piece into the road "
        "that the deliveries leave out; tests/test_invariance.py records the current figures).",
        "Tiled against untiled (4 M seed 0 through its LAZ, `--tile-size 50`, 16 tiles, 30 m buffers): "
        "99.62 % of the labels agree, tiled E1 3.33 % against 1.07 % untiled; most of the difference is "
        "one road corner of ~60 m2 that the tile's own cut leaves out (its colour model is learnt from "
        "the kerbs inside the tile window) (2026-12-01).",
        "The same at `--tile-size 100` (9 tiles, 30 m buffers; commit 5a6b8c5, 2026-12-04): 99.897 % "
        "agree (4,118 points; tiled E1 1.41 / E2 0.47 %, untiled 1.08 / 0.44 %). 3,383 of the "
        "disagreements lie more than 20 m inside a core, so no buffer closes them; with the untiled "
        "run's height and colour noise forced into every tile (`--set "
        "stages.road_regions.height_noise=0.0231 --set stages.road_regions.colour_noise=1.747`) 99.901 "
        "%, and with the merge levels run to the end (`settle` 1e-9, both runs) 99.903 %: the per-tile "
        "estimates and the settle cut-off are minor; what differs is the road selection, learnt and cut "
        "per tile window (2,430 points the untiled run calls road are lost, mostly one ~2,000-point "
        "patch of a few regions 20-30 m from two borders). Neither the learnt colour term (`--set "
        "stages.road_regions.weights.colour=0` in both runs: 99.901 %) nor the component rules "
        "(`weights.keep_area=0`, `keep_area_kerb=0`, `min_area=0`: 99.884 %) is the cause on its own "
        "(commit 2884d59). The likely cause (inferred, not isolated by a measurement): the cut is one "
        "minimum cut over the tile's region graph, and regions that reach across the window edge (a "
        "street is one region over many tiles) enter it with other sizes and mean colours than in the "
        "whole run, which moves ambiguous pieces far from any border; closing that takes regions "
        "reconciled across tiles, not a buffer.",
        "Tiled against untiled after this session's R3 / R4 / R6 changes (a7bba10, 4 M seed 0 through its LAZ, "
        "`--tile-size 100` and `50`, 30 m buffers; 2026-12-04): 99.945 % agree at 100 m (2,196 points; tiled "
        "E1 0.90 / E2 0.35 %, untiled 1.01 / 0.32 %), 99.631 % at 50 m (14,770 points; tiled E1 3.15 %): "
        "the road corner that a 50 m tile's own cut leaves out, as before; at a537f39 (the rules after "
        "review) 99.950 % at 100 m (2,013 points).",
        "A vegetation cue by excess green of region mean colours (a257b4f; unchanged by shadow) took "
        "shaded lawns continuous with the road out of it: 4 M seed 3 E2 12.09 -> 2.91 %, 300 k seed 2 "
        "0.95 -> 0.78 %; 6 of 31 synthetic scenes still break a bound (2026-12-03).",
        "300 k seed 1 (E2 9.62 %): the false road is the sidewalk along ~20 m of road (a 5-6 % slope, "
        "an 11 cm kerb in the generator's surface), whole clean regions, not mixed ones; the scene's "
        "height noise is 3.9 cm (+-30 % over the scene) and along that stretch the boundary edges' "
        "filtered steps do not resolve the kerb (mean kerb posterior of road-sidewalk point edges 0.03 "
        "there against 0.31 where the sidewalk stays out). A pair-level step between the two regions' "
        "own plane fits as a second kerb reading (not adopted) moved it to 7.58 % but 300 k seed 3 E1 "
        "2.21 -> 4.06 %: medians 300 k 1.66 / 1.00 -> 1.70 / 0.95 %, 1 M 2.10 / 0.81 -> 2.18 / 0.78 %, "
        "failing scenes unchanged (2026-12-03).",
        "4 M seed 8 (E1 7.84 %): a 25 m side street of its own darker asphalt (grey 73.6 against "
        "85-87 of the other streets in the generator) is left out whole: the scene's one colour "
        "model, learnt from all kerbs, places its colour nearer the sidewalks (llr -0.67), and "
        "being below its kerbs (1 per kerb edge) does not outweigh that. The colour model learnt "
        "block by block (`weights.colour_block=40`, kerb samples of the 3 x 3 blocks of 40 m around "
        "each region, a quarter of the scene's model mixed in) finds it (E1 2.49 %) and leaves no 4 M scene failing (worst 4.13 / 2.78 %), but is "
        "noisier where blocks hold few kerbs: 4 M median E1 2.29 -> 2.56 % (seed 0 1.77 -> 3.89 %), "
        "1 M seeds 2 / 7 E1 2.27 -> 4.10 %, E2 0.46 -> 1.53 %; 300 k scenes unchanged (one block "
        "neighbourhood covers them). Kept off by default (2026-12-03).",
        "The block model's densities mixed with the scene's in proportion to their kerb samples "
        "(shrinkage towards the scene's model, prior 0.1-2 typical blocks' samples) instead of a fixed "
        "share: at 0.25, 1 M seed 2 is back to 2.27 % and 4 M seed 8 still found (2.49 %), but 1 M "
        "seed 7 E2 0.46 -> 1.53 % and 4 M seed 0 E1 1.77 -> 3.88 % stay (a road piece at the scene's "
        "corner whose blocks see sidewalk of its grey), 4 M median E1 2.53 %; from a prior of 1 seed 8 "
        "is lost again (7.36 %). Not adopted (2026-12-03).",
        "R5 with the CSF package's slope smoothing (`cloth_smooth.slope_smooth`, 1c6faae): on a sloped "
        "street the cloth stayed more than C_t off the ground along the survey's upslope edge, and a "
        "band of road there was dropped (300 k seed 4: 4,711 road points within 3.5 m of the edge, E1 "
        "5.48 -> 2.11 %, E2 1.68 -> 2.11 %). Elsewhere it moves scenes by knife-edge flips of the cut "
        "(1 M seed 4 E2 0.82 -> 2.07 %: a sidewalk piece, changed by 100 of the cut's input points) "
        "(2026-12-03).",
        "1 M seed 9 (E2 3.50 % at 1c6faae): the false road was a paved yard (grey 156, about 19 k "
        "points in 59 regions, truth class 2) apart from the street network, its whole boundary "
        "continuous (2,017 of 2,018 edges), its colour mildly road-like (llr 0.16), kept by its area "
        "alone. Since abf0624 a large component stays only with kerbs below it along 1 % of its "
        "boundary, or as the largest component: 0.43 %, no other scene changed (2026-12-03).",
        "Surface test (`road_regions.surface_tol`, 27ad7ea): in 300 k seed 2 a third of the false road "
        "(605 of 1,656 points) was the lowest parts of parked cars, within the cloth's 0.3 m of the road "
        "(median 0.11 m above the local road plane). A road point more than 4 x the measured height "
        "noise (at least kerb_min) above the median slope-corrected height of its 32 nearest road points in plan now leaves "
        "the road: E2 down on all 30 scenes of 300 k / 1 M / 4 M (by 0.01-0.38 points), E1 up by at most "
        "0.03; 3 x the noise took road too (300 k seeds 0 / 2 / 4 / 6 E1 +1.1-1.3 points); AHN3 E1 6.80 "
        "-> 7.14 %, E2 1.50 -> 1.38 %; the 4 M road pipeline 8.92 -> 9.15 s (medians of 3 alternating "
        "rounds, in process) (2026-12-04).",
        "R3 with `xy_removal` (2026-12-04): the infinite plane's slab of a horizontal roof also crossed "
        "sloped streets where they climb to the roof's height (4 M seed 0: 1,067 road points). First "
        "(`point`, 89e49b8) only the inliers standing above dh_max themselves were removed: 4 M E1 lower "
        "on 9 of 10 scenes (seed 0 1.81 -> 1.17 %), AHN3 E2 1.38 -> 1.10 %; but the middle of a roof "
        "wider than about 30 m sees no ground in its 3 x 3 reference cells and stayed (a review found "
        "it). Now (`part`) the inliers are split into connected parts (touching 1 m cells), each classed "
        "by its own median height: AHN3 E2 0.67 %, kappa 0.9377.",
        "R4 with `cell_reference: supported`: a cell's lowest point is not its reference when it lies "
        "more than the noise allowance (4 x the height noise) under the second lowest and the third "
        "follows the second within it. Low outliers that SOR keeps (1 M seed 5: 155 of 1,981 class-7 "
        "points reach R4, 0.3-0.9 m under the surface) made every point of their cells high: 488 of the "
        "559 road points R4 removed there. A first rule (the lowest of the three lowest that the others "
        "follow, 874e457) also lifted the reference onto a car or wall in cells with two ground points, "
        "and its changed R6 input flipped two sidewalk pieces in the cut (300 k seed 2 E2 0.67 -> 2.02 %, "
        "4 M seed 3 2.86 -> 5.03 %); with the single-outlier rule 4 M seed 3 is at 2.80 %, 300 k seed 2 "
        "stays at 2.02 %. A gap floor of 0.2 or 0.3 m moved other scenes by other flips (2026-12-04).",
        "Surface test, R3 by parts and R4's supported reference together (2026-12-04), against the start "
        "of the day: uav-road-v1 1 M seeds 0-3 E1 1.24 / 0.75 / 1.14 / 1.10 -> 0.71 / 0.50 / 0.80 / 0.43 "
        "% (E2 0.46 / 0.44 / 0.38 / 0.41 -> 0.35 / 0.33 / 0.28 / 0.33 %), uav-road 1 M seeds 20-23 E1 "
        "2.58 / 3.25 / 1.15 / 4.00 -> 2.50 / 3.12 / 0.82 / 3.90 %, E2 0.93 / 3.33 / 0.43 / 0.54 -> "
        "1.58 / 3.22 / 0.35 / 0.47 % (scenes not in the matrix).",
        "What the invariance test's disagreements are (300 k seed 2 in memory against its 1 mm LAZ, "
        "2026-12-04): 93 % lie within 0.5 m of the road's boundary (median 0.14 m, about one point "
        "spacing), about half on points both runs processed; the 1 mm delivery changes which points "
        "the hashed R1 sample keeps for about 5 % of them (a 1 cm hash cell against coordinates moved "
        "by up to 0.5 mm). So the gap to 99.5 % is jitter of the road's edge by about a point spacing "
        "(and a few region flips of 100-300 points), not whole streets.",
        "Where the invariance gap comes from (2026-12-06, at 1984a59, 300 k seed 2): R6 alone, given its "
        "own working set (127,320 points) and the same set with coordinates rounded to 1 mm (same points, "
        "same order), agrees on 99.74 % of its labels (1 cm: 99.44 %), run to run on the same input 100 %; "
        "its region partition differs for 9 % of the points (a region's best match in the other run), "
        "the cut on them agrees on 99.72 %, boundary votes and the surface test add nothing (off: 1 mm / "
        "1 cm / half density 99.41 / 99.24 / 99.20 % against 99.43 / 99.27 / 99.27 % with them). Run the "
        "merge levels to the end (`settle` 0.001 / 0.0002: 99.46 / 99.31 / 99.30 %) or merge small regions "
        "(min_region_points 30: 98.83 % at 1 mm) did not help: the region merge itself, most similar pairs "
        "first over a kNN graph and step evidence that move with millimetres, is where the jitter starts; "
        "whole-pipeline disagreements are 104-153 small clusters (median region 18-37 points), 15-23 "
        "whole-region flips.",
        "300 k seed 7 (E1 5.26 %): most of the missed road is a lighter repair patch in the parking "
        "lane (region grey 62-68 against the road's 51) at the road's height with no kerb between it "
        "and the road; the scene's colour model (its kerb samples include lawns) gives it llr -0.79 per "
        "point, which outweighs its continuous boundary with the road, and its not-road group runs on "
        "into the whole not-road area (143,898 points), so the enclosure rule does not take it (2026-12-04).",
        "Kerbs in noisy scenes (2026-12-04, in-memory matrix of 300 k / 1 M / 4 M seeds 0-9): on graph edges "
        "that cross the true road / sidewalk line the raw slope-corrected steps have a median of 6-7 cm, but "
        "after the edge-preserving height filter only 2 cm where the height noise is 3.9 cm (300 k seeds 1, "
        "3; 14 % of those edges get a kerb posterior above 0.5, against 44 % at 300 k seed 0 with 1.8 cm "
        "noise): the filter starts from its neighbourhood's median, which at a kerb lies between the two "
        "surfaces, and a window of 2.5 x the noise then spans both, so an 8-16 cm kerb becomes a ramp of "
        "small steps. Sharper filters move the failing scenes without removing them: starting from the "
        "point's own height (6 steps) 300 k seed 1 E2 9.73 -> 2.04 % but matrix median E1 1.62 -> 1.91 % and "
        "four scenes out of bounds (300 k seed 2 E2 4.34, seeds 5 / 9 E1 5.87 / 5.07, 4 M seed 8 E1 5.67); "
        "filter_width 1.5 or 2.0: E2 down, E1 up to 3-5.7 % on 300 k seed 3 and 1 M seed 5 (false kerbs "
        "around occluded road under crowns); road_regions.k 20 / 28 with graph_k 12: mixed. Not adopted; a "
        "per-pair step (median over a region pair's boundary edges) separates road / sidewalk pairs "
        "(road-road pairs: > 99 % of edges below 3 cm) but most sidewalk pieces the cut takes lie at lowered "
        "kerbs with no step at all.",
        "R3 ground reference on steep streets (`ransac_planes.ground_slope` 0.15, 2026-12-04): the reference "
        "is the lowest point of the 3 x 3 cells of 10 m around a point's cell; on a street climbing at 15 % "
        "that point lies 15-20 m downhill, ~3 m under the street, so the street's own plane (median height "
        "2.92 m) was classed XY and removed as a roof: uav-road 1 M seed 42 (outside the matrix) lost 7 % of "
        "its road there, E1 10.90 %. A neighbouring cell's minimum now counts raised by 0.15 x the distance "
        "between the cells (a cone-limited lower envelope): 1 M seed 42 E1 1.85 %; matrix medians unchanged "
        "(in memory E1 1.62, E2 0.65 %), AHN3 unchanged.",
        "Held-out seeds (2026-12-04; never looked at before that day): "
        "benchmarks/accuracy/heldout/ACCURACY.md (`accuracy --task road --road-sizes 1M,2M --road-seeds 40-49 "
        "--road-large '' --out benchmarks/accuracy/heldout`, at 35d417c): median E1 2.19 %, E2 1.37 %, 7 of "
        "20 scenes out of the per-scene bounds (worst E1 8.52, E2 11.33 %). Earlier, in memory, uav-road 1 M "
        "seeds 40-49, 2 M seeds 32-37 and 500 k seeds 50-53 in memory with road_uav.yaml at 35d417c: median "
        "E1 1.99 %, E2 1.35 %, 5 of 20 out of the per-scene bounds (1 M 41 E2 11.33, 1 M 42 E2 4.03, 1 M 48 "
        "E1 5.76, 2 M 33 E2 3.09, 2 M 37 E1 19.38 %) against median 1.62 / 0.65 % and 3 of 30 on the matrix "
        "seeds 0-9, which earlier sessions examined: the matrix flatters the configuration. Every remaining "
        "loss there is R6's (the deciding-stage breakdown): a street of a second asphalt shade whose colour "
        "sits among the scene's sidewalk samples (2 M 37: road grey ~135 bluish, sidewalks 130-150; llr -0.15 "
        "to -0.44) and sidewalk strips joined over smeared kerbs. Halving the colour term (`weights.colour` "
        "0.5): matrix 3 -> 1 scene out of bounds, held-out E2 median 1.35 -> 0.92 %, but AHN3 E1 7.16 -> "
        "13.67 % and 2 M seed 31 E1 12.4 -> 30.3 %; 0.35 and 0.7, a colour weight by the square root of the "
        "region size, lower_road 3 and bright_floor 1.0 were no better: not adopted.",
        "Enclosed not-road groups (`_absorb_enclosed`, 2026-12-04): in uav-road 2 M seed 44 lighter road "
        "patches (grey 114-128 against the road's 105; llr -0.25 to -0.63) are not road after the cut, and "
        "their not-road group is the whole not-road area of the scene (283,137 points, 90 % of its boundary "
        "on road), joined through small contacts, so the enclosure rule cannot take them. Linking a group "
        "only over pairs whose shared edges are at least 25 % of the smaller region's boundary: 2 M seed 44 "
        "E1 8.52 -> 4.93 %, held-out (1 M / 2 M seeds 40-49) mean E1 2.73 -> 2.37 %, 7 -> 5 scenes out of "
        "bounds; but the split groups fall under the 60 % share elsewhere (2 M seed 41 E1 1.14 -> 2.51 %) and "
        "matrix 1 M seed 1 E2 3.54 -> 4.40 %: not adopted.",
        "Boundary kerb test (2026-12-05, not adopted): a region pair counted as a full kerb when the median raw "
        "(unfiltered, slope-corrected) height step over all graph edges of its shared boundary lies within "
        "[kerb_min, kerb_max] and at least z standard errors of a median (1.2533 x sqrt 2 x the height noise / "
        "sqrt(edges)) from zero. z 4, E1 / E2 before -> after: 300 k seed 1 0.77 / 9.74 -> 5.47 / 2.23 %, 1 M "
        "seed 1 1.26 / 3.54 -> 2.18 / 3.76 %, 2 M seed 41 1.14 / 4.15 -> 1.34 / 4.25 %, 2 M seed 42 1.41 / "
        "4.41 -> 4.32 / 2.00 %, 2 M seed 48 2.77 / 3.30 -> 3.55 / 3.32 %, 1 M seed 41 0.80 / 11.33 -> 0.98 / "
        "12.12 %; z 8: within 0.7 points of the base. Why it does not reach 1 M seed 41 (sidewalks taken as "
        "road, E2 11.3 %): its sidewalks are regions of 400-800 points whose boundary with the road runs "
        "through a strip of regions of 8-20 points along the kerb (lighter kerb stones, kerb-face points at "
        "intermediate heights), so the step is split over two boundaries and the direct sidewalk-road pairs "
        "show median raw steps of 0-1 cm (e.g. 37 edges); over the edges that cross the true road edge the "
        "raw step is 6 cm (median; filtered 1.9 cm) at a height noise of 2.05 cm, kerb posterior mean 0.34. "
        "A kerb test has to look across such strips, not only at direct neighbours. Tried next (same day): "
        "pairs of regions of at least 50 points up to 4 graph edge lengths apart (kNN, k 32, among those "
        "regions' points; strip regions left out), direct and across-strip pairs marked by the same median "
        "test with the effective count capped by the smaller region's points (tiny regions formed by the "
        "step veto are selected for being low: with 8-17 points and 22-64 edges they passed z 4 as kerbs "
        "under road pieces and cut them off), across-strip pairs added to the cut as kerb-only pairs. 1 M "
        "seed 41 E2 11.33 -> 6.27 %, 2 M seed 42 4.41 -> 1.80 %, 2 M seed 48 3.30 -> 2.48 %; but the matrix "
        "(seeds 0-9 at 300 k / 1 M / 4 M) median E1 1.62 -> 1.79 %, 3 -> 5 scenes out of bounds (4 M seed 4 E1 "
        "3.53 -> 6.12 %, 300 k seed 7 4.97 -> 5.09 %), AHN3 E2 0.67 -> 1.88 %; held-out (1 M / 2 M seeds 40-49) "
        "mean E2 2.13 -> 1.62 % but mean E1 2.73 -> 2.97 % (2 M seed 44 8.52 -> 10.46 %), 7 -> 6 out of bounds; "
        "4 M wall time about +20 % (the second kNN): not adopted. More kerbs trade sidewalks taken as road "
        "for road pieces cut off, as every colour and kerb weight measured before did.",
        "Two-sided kerb steps (2026-12-05, not adopted): per graph edge, the median slope-corrected height "
        "of the end points' neighbours on b's side of the edge's bisector minus that on a's side, in place "
        "of the filtered heights' difference. 300 k seed 1, edges crossing the road / not-road line: median "
        "oriented step 5.6 cm against 2.3 cm filtered (6.0 cm raw), but the spread over all edges 2.5 cm "
        "(neighbourhoods of k 12) or 2.0 cm (k 32) against 1.1 cm: z about 2.2-2.8 either way. Run in place "
        "of the filtered steps (k 12), 300 k seeds 1 / 2 / 3 E2 9.74 / 2.02 / 2.33 -> 14.08 / 11.00 / "
        "21.59 %. A region test, the median height of a road region's points above the other road regions' "
        "points within 1 m in plan, removes nothing in 300 k seed 1: the false sidewalk is itself many "
        "regions whose 1 m neighbourhoods are mostly other sidewalk regions (medians 0.001-0.011 m).",
        'Photometric changes and lower densities (2026-12-05, road_uav.yaml, in memory, not used to '
        'choose anything): the whole orthophoto darker (RGB x 0.7), brighter in its mid-tones (gamma '
        '0.7) or tinted (R +8 %, B -8 %), E1 / E2 in %: 300 k seed 0 0.78 / 1.25 (as is) -> 1.15 / '
        '1.24, 1.22 / 1.30, 0.69 / 1.28; 300 k seed 3 1.65 / 2.33 -> 1.72 / 1.41, 1.34 / 2.85, 1.54 /'
        ' 2.49; 1 M seed 2 1.95 / 0.38 -> 0.52 / 0.38, 2.08 / 0.31, 1.95 / 0.38 (labels agree on '
        '98.6-99.95 % with the unchanged colours; tests/test_invariance.py keeps this on 300 k seed '
        '2). Random thinning of 1 M seeds 2 and 4 (measured density 110 and 224 points/m2) to 1/2, '
        '1/4 and 1/10: seed 2 2.04 / 0.27, 4.05 / 0.33, 8.17 / 0.51 (at 55, 28 and 11 points/m2); '
        'seed 4 1.26 / 1.57, 1.43 / 1.02, 9.88 / 0.61 (at 113, 57 and 23 points/m2). Within the '
        "issue's 50-300 points/m2 the bounds hold; below about 30 points/m2 road is lost in R6 alone "
        '(1 M seed 4 at 1/10: 2,577 of 26,213 road points, the earlier stages 14): patches of another'
        ' shade inside the carriageway (parking lanes, shadows) stay regions of their own and are not'
        ' selected. Not addressed.',
        "Held-out streets made without the project's generator (benchmarks/heldout_streets, 21 scenes by two "
        "other sessions, 2026-12-05): a country lane without kerbs was missed whole (E1 100 % at 30 and 120 "
        "points/m2: no kerb, so the cut learnt no road colour and kept nothing) and a street cut into a hillside "
        "too (E1 99.5 %: R3's reference lay down the bank below it, 5.9 m under the street's plane). "
        "road_graph.kerbless_road (only when the cut keeps no road) and ransac_planes.at_grade_share 0.5: "
        "3.89 / 2.73 % and 2.02 %. On the matrix (seeds 0-9 at 300 k / 1 M / 4 M, in memory) every scene's "
        "E1 / E2 unchanged by at_grade_share; AHN3 E1 7.16 -> 6.75 %, E2 0.67 % unchanged. 16 of 21 held-out "
        "scenes within the bounds; the others in benchmarks/heldout_streets/RESULTS.md.",
        "Label transfer by height (2026-12-05, pipelines.TRANSFER_Z_SCALE 4): a point R1 skipped took the "
        "result of the processed point nearest in 3D, which at a kerb is often on the other surface (a "
        "12 cm step against a processed spacing of about 0.14-0.26 m); with heights counted 4 times it "
        "takes its own surface's. This table against the previous one: every synthetic scene's E1 and E2 "
        "equal or lower (e.g. 1 M seed 0 0.80 / 0.62 -> 0.72 / 0.56 %, 16 M 0.74 / 0.48 -> 0.66 / 0.45 %), "
        "AHN3 unchanged by it (no point skipped; its E1 7.16 -> 6.75 % is at_grade_share's, above); "
        "held-out streets E1 lower on 14 of 21 scenes, higher on one (rural_nokerb_dense120 2.73 -> "
        "2.86 %). The failing scenes are the same.",
        "Colour against kerbs (2026-12-05, road_graph.Weights.colour 0.24 at 60 points/m2, scaled by "
        "(60 / density)^1.5; before: 1.0 x (60 / density)^0.5). The cut weighed each point's colour log "
        "ratio, one value per region, against kerbs per edge: a region's colour counted as many times as "
        "it has points. Three of the four failing matrix scenes were colour outweighing kerbs (300 k seed "
        "1: a sidewalk of mildly road-like colour along a noisy kerb; 4 M seed 8: a side street of its "
        "own darker asphalt; 300 k seed 7: a lighter repair patch). Measured in memory with road_uav.yaml "
        "(E1 / E2 medians, worst, scenes out of the per-scene bounds): matrix seeds 0-9 at 300 k / 1 M / "
        "4 M, before 1.60 / 0.63 %, worst 6.87 / 9.67 %, 3 out (300 k s1, 1 M s1, 4 M s8); a flat 0.3 "
        "x sqrt: 1 out (4 M s8 5.69 %); 0.1: 300 k seed 1 E1 11.9 %; 0.5: 1 M seed 1 E2 3.29 %. But "
        "0.3 lost road on sparse data: AHN3 (13 points/m2 at R6) E1 6.75 -> 13.52 % (0.5: 12.89, 0.7: "
        "12.53 %), held-out street sparse_noisy_20ppm 2.53 -> 4.13 %. With the weight growing as "
        "(60 / density)^1.5 below the reference (0.33 at 48 points/m2, 1.3 at 20, 2.3 at 13): matrix "
        "1.70 / 0.63 %, worst 5.67 / 2.46 %, 1 out (4 M seed 8 E1 6.87 -> 5.67 %); held-out seeds 40-49 "
        "at 1 M and 2 M (not used to choose) 2.17 / 1.31 -> 2.26 / 0.79 %, 7 -> 3 out (1 M s42 E1 1.85 "
        "-> 6.05 %: a lane and its sidewalk swap across a kerb; 1 M s48 5.76 -> 5.96 %; 2 M s43 3.85 -> "
        "6.67 %); held-out streets 16 -> 18 of 21 within the bounds (rural_curved_kerb12 E2 3.79 -> "
        "0.11 %, dark_sidewalk_cycletrack 3.91 -> 0.62 %; sparse_noisy_20ppm E1 2.53 -> 2.97 %); AHN3 "
        "6.75 / 0.67 -> 6.88 / 1.10 %. The two numbers were chosen on the matrix and AHN3; the exponent "
        "has no derivation beyond that sparse ground needed more colour on both sparse files measured. "
        "Seeds nobody had looked at (uav-road 1 M and 3 M, seeds 60-69, in memory, run once after the "
        "choice): before 9 of 20 out, medians 1.88 / 1.39 %; now 6 of 20 out, medians 1.78 / 0.71 % "
        "(1 M seed 63 E1 6.43 -> 18.29 %: the western arm of a street, 28 x 14 m, left whole; 1 M / 3 M "
        "seed 67 E2 13.9 / 17.9 -> 12.1 / 13.6 %). The matrix (1 of 31 out) flatters the configuration: "
        "about a third of unseen scenes still break a per-scene bound. 2 M seed 31, which an earlier "
        "halving of the colour term had broken (notes above: 12.4 -> 30.3 %), E1 15.42 -> 38.91 %: two "
        "streets at the scene's edge in deep shadow (region grey 42-46 against 117 in sun; colour log ratio "
        "0.07-0.44, the samples being sunlit), whose 10.5 cm kerbs under 4.6 cm of height noise the filtered "
        "steps resolve on a few percent of their edges, follow their shadowed sidewalks (same brightness, "
        "full smoothness) rather than the sunlit road (a brightness step weakens that link to 0.39) once "
        "colour weighs less; letting no smoothness act across pairs whose mean raw step is a kerb at z 4 "
        "gave 30.2 %. The scenes the new weights lose have kerbs low against the noise (kerb / noise 2.3 "
        "to 3.1: 2 M s31, 1 M s63, s42); those they win are where colour misled (4 M s8 4.6, 300 k s7 "
        "4.1, 300 k / 1 M s1 3.0). The colour weight raised with the measured height noise ((noise / "
        "2.5 cm)^2 above it) brought 2 M s31 to 12.25 % and 1 M s63 to 5.66 %, but 300 k seed 1 back to "
        "E2 7.58 % and 1 M seed 1 to 3.54 %: not a rule. What decides these scenes is a kerb resolved at "
        "low contrast (1 M seed 67: kerbs of 8.6 cm under 3.6 cm of noise, every sidewalk taken, E2 12 %; "
        "its road / sidewalk region pairs have a median 0.9 % of stepping edges); a pair-level test on "
        "the mean raw step of a pair's boundary (z 4 or 6) left seed 67 at E2 11-12 % and lost road "
        "elsewhere (1 M seed 63 E1 24.8-29.5 %).",
        "The colour model learnt block by block (`weights.colour_block=40`, 2026-12-05, with the weights "
        "above; first measured alone, then adopted with the kerbless trigger below): 4 M seed 8 E1 5.67 -> 1.03 % (its side street found), no matrix scene out "
        "(4 M median E1 1.79 -> 1.90 %, seed 0 0.83 -> 2.98 %), held-out seeds 40-49 3 -> 2 out (medians "
        "2.26 / 0.79 -> 1.94 / 0.73 %), AHN3 unchanged, tiled against untiled at 100 m (4 M seed 0 through "
        "its LAZ) 99.970 % agree against 99.920 %; but held-out street rural_curved_nokerb E1 3.89 -> "
        "77.0 %: the block models let the cut keep 9,450 points of road, so the kerbless fallback, which "
        "runs only when the cut keeps none, did not run. Its blocks are now cut in world coordinates (a "
        "tile's or a file's local origin no longer shifts them).",
        "Kerbless trigger and the block colour model adopted (2026-12-06): the kerbless fallback now also "
        "runs when kerbs bound less than 5 % of the outline of the road the cut keeps "
        "(`road_kerb_share` in the summary, `weights.kerbless_below`; measured with the block model on "
        "every scene at hand: kerbed synthetic scenes 0.19-0.81, kerbed held-out streets 0.14-0.81, AHN3 "
        "0.42; the kerbless lane 0.008), and `colour_block` is 40 m by default. Against the weights alone: "
        "matrix 1 -> 0 scenes out (4 M s8 E1 5.67 -> 1.03 %, 1 M s7 4.25 -> 1.59 %, 4 M s0 0.83 -> 2.98 %), "
        "held-out seeds 40-49 3 -> 2 out (medians 2.26 / 0.79 -> 1.94 / 0.73 %), unseen seeds 60-69 "
        "6 -> 4 of 20 out (3 M s60 E2 3.01 -> 2.91 %, 3 M s63 3.94 -> 2.60 %; medians 1.78 / 0.71 -> "
        "1.96 / 0.64 %; those seeds had been run once before, with the weights), held-out streets 18 "
        "of 21 either way (rural_curved_nokerb 3.89 % again), AHN3 unchanged (one block neighbourhood "
        "covers it), tiled at 100 m against untiled 99.920 -> 99.970 %; 4 M road_regions 4.45 -> 4.47 s.",
        "Unseen seeds at 300 k (2026-12-06, c052c91, in memory, each run once): seeds 60-69 5 of 10 out "
        "(60 E2 11.0 %, 62 E2 5.7 %, 63 E1 5.15 %, 67 E1 / E2 5.4 / 8.1 %, 69 E1 7.5 %), seeds 70-79 4 of "
        "10 out (71 E1 5.5 %, 73 E1 55.6 %, 75 E1 24.3 %, 76 E2 14.7 %); medians 1.64 / 1.39 % over the "
        "20, against 0 of 10 out on the matrix seeds 0-9 (1.70 / 0.74 %). Six of the nine have kerbs under "
        "2.5 x their height noise (60: 9.4 cm under 4.8, 67: 8.6 / 3.6, 73: 9.3 / 4.6, 75: 8.1 / 3.8, "
        "76: 8.5 / 4.8, 62: 10.9 / 4.1), where the mode filter's window (2.5 noise sigmas, wider than "
        "the kerb) blurs the kerb over the neighbourhood: on 300 k seed 60 the road / sidewalk region "
        "pairs' mean filtered step is 2.4 cm (median; raw heights 4.7 cm) for a 9.4 cm kerb. On 300 k "
        "seed 73 the clear kerbs the colour model learns from are mostly noise steps between non-road "
        "regions (lower sides 465 non-road against 172 road), so the model separates nothing (colour log "
        "ratio 0.22 on the road it kept, 0.18 on the two street arms it lost). Measured, not adopted: "
        "filtered heights from a matched step filter (per point, the mean of its own side of the "
        "strongest of 16 step lines through its neighbourhood when the two sides differ by 4 standard "
        "errors, else the neighbourhood mean): seeds 60-69 5 -> 3 out (63, 69 in) but 67 E2 8.1 -> 60 % "
        "(every lawn and yard taken) and 62 5.7 -> 10.6 %; at 5 standard errors 7 out; with 24 plan "
        "neighbours 4 out (67 E2 17.5 %): the cut's calibration rests on the mode filter's step "
        "statistics. Steps across each edge from the mean heights of its two half-neighbourhoods: 8 of "
        "10 out. A pair-level kerb from the mean raw step of a region pair's boundary (t 3 or 4, here at "
        "300 k; the note above measured it at 1 M): 8 and 5 of 10 out, road lost where camber and noise "
        "make raw steps between road regions. The mode filter's window at 1.0 or 1.5 sigmas: road lost "
        "(6 and 5 of 10 out, E1 up to 99 %). lower_road 2 / 4 (the reward of a kerb's lower side being "
        "road): invariance on 300 k seeds 2 and 0 no better (99.32-99.38 % through LAZ at 1 mm), E2 of seed "
        "0 up to 3.4 %. Over the 30 seeds 0-9 and 60-79 at 300 k (9 out as configured): the matched "
        "filter's evidence for the cut only (the merge's partition unchanged) 13 out, road lost on the "
        "matrix seeds too (median E1 1.70 -> 3.29 %: choosing the strongest of 16 lines biases each side's "
        "mean apart, so flat ground steps); the pair-level raw step with its magnitude at least kerb_min "
        "and t 4: 10 out (median E1 2.68 %); colour samples from pairs of which neither side is green: 9 "
        "out (73 E1 55.6 -> 83.7 %); R1's target density 300 (every point of these scenes kept): 9 out, "
        "other ones (62 E1 65 %, 67 E2 35 %: the cut's balance is set at 60 points/m2).",
        "Invariance (2026-12-06, 300 k seed 2, the test's scene; c052c91): in memory against 1 mm LAZ, "
        "1 cm LAZ and half density 99.43 / 99.27 / 99.27 % of labels agree (seed 0: 98.62 / 99.29 / 98.55 "
        "%). The disagreeing points reach R6 in both runs (R1-R5 send 4.4 % of the points to other stages "
        "but none of them changes a label); R6 alone on its own input, coordinates rounded to 1 mm, "
        "changes 0.26 % of its labels (jitter of 0.3 mm: 0.27 %; of 0.01 mm: 0.005 %): the kNN rows, "
        "median colours and the greedy merge order amplify sub-millimetre changes into another "
        "partition, and the cut then decides flush, kerbless pieces differently: on seed 0 a lowered "
        "kerb's sidewalk (2,052 points of small grey regions with no kerb edge between them and the "
        "road), on seed 2 a 1-2 m piece of road at the foot of a kerb and a sidewalk under a tree's "
        "shade; 35-45 % of the disagreements lie within 0.2 m of the road's edge. Measured, not "
        "adopted: a kerb-line field (kerb edges gathered in 0.5 m cells with their up-directions, each "
        "point voting by its side of the cells' lines within 2 m across and a Gaussian of 4 m along, the "
        "vote summed per region into the cut; weight 0.3 / 1.0): 99.41-99.45 / 99.28-99.32 / 99.20-99.26 "
        "% on seed 2, seed 0's sidewalk still flips (its 10 m of lowered kerb has no kerb cell at all; "
        "the sidewalk / lawn step makes the sidewalk the lower side); the boundary vote over 12, 24 or "
        "32 neighbours in plan instead of 12 in 3D: no change; the measured height noise held fixed "
        "across deliveries: no change; fewer merge levels (one or two): worse (98.9 / 98.8 / 98.6 % on "
        "seed 2).",
        "Segmentations that vote (`road_regions.ensemble`, 2026-12-06, on a562a32; measured, not the "
        "default): the road choice of one segmentation flips small pieces of road or sidewalk with any "
        "small change of the input. On 300 k seed 2 the processed points of the in-memory scene and of its "
        "1 mm LAZ differ by 3.6 % (R1's hashed sample on 1 cm cells: a coordinate within 0.25 mm of a cell "
        "boundary changes cell under rounding, 2.5 % per axis); with 10 cm hash cells only 0.42 % differ, "
        "yet labels agree on 99.46 % against 99.43 %: about 900 processed points in some hundred pieces of "
        "1-180 points flip whatever the size of the change, while RANSAC's seed (0, 1, 2) moves 4-33 points "
        "into or out of R6 and no piece. With `ensemble: [0.7, 0.85, 1.0, 1.15, 1.3]` the first colour "
        "level runs once over the points, the later levels run from its regions at each scale (the merge's "
        "branches, rounds over regions as nodes; a branch equals the whole schedule at its scale), each is "
        "cut, and a point is road when three say so. Agreement in memory against 1 mm / 1 cm / half "
        "density 99.43 / 99.27 / 99.27 -> 99.57 / 99.48 / 99.39 % (three scales 0.7 / 1 / 1.3: 99.54 / "
        "99.48 / 99.36; seven 0.7-1.3: 99.58 / 99.44 / 99.41; nine 0.6-1.4: 99.58 / 99.51 / 99.41; all "
        "three levels scaled: 99.52 / 99.51 / 99.42; the size pass before the branches: 99.30 / 99.14 / "
        "99.12); 85-87 % of the disagreements left lie within 0.3 m of the road's edge, and a 5-nearest "
        "majority for the points R1 skipped (PDAL's neighborclassifier rule) lifted 1 cm to 99.53 % but "
        "half density only to 99.41 %. The road report with the five (`accuracy --task road`, E1 / E2 "
        "medians, one -> five): 300 k 1.70 / 0.74 -> 1.61 / 0.73 %, 1 M 1.42 / 0.57 -> 1.21 / 0.52 %, "
        "4 M 1.90 / 0.43 -> 1.90 / 0.42 %, 16 M 0.65 / 0.43 -> 0.61 / 0.41 %, every synthetic scene "
        "within the bounds; unseen 300 k seeds 60-79 9 -> 6 out (63, 69, 71 within); held-out streets 18 "
        "of 21 either way; but AHN3 E1 6.88 -> 11.70 % (the bound is 10 %): a 735-point piece of road at "
        "the tile's corner that every scale but 1.0 leaves out (0.7 / 0.85 / 1.15 / 1.3 alone: E1 11.52 / "
        "11.30 / 12.16 / 13.41 %), and the road CLI on uav-road 4 M seed 0 (3 alternating rounds against "
        "5121b6f) 12.4 s for 5121b6f against 16.8 s (a562a32: 12.6 against 12.9 s), R6 4.9 -> 8.8 s: the "
        "road issue's AHN3 and time bounds rule it out as the default. Three scales: 1 M seed 1 E2 3.02 %; "
        "nine: 300 k seed 70 E2 3.61 %. The scenes the single segmentation passes it partly passes by luck: "
        "on 4 M seed 3 the scales 0.7 / 0.85 / 1.15 / 1.3 alone gave E2 3.95 / 3.52 / 3.99 / 4.24 % "
        "(against 1.54 % at 1.0): a 70 k-point lawn beside a shadowed sidewalk, enclosed by road, was "
        "absorbed (`_absorb_enclosed`). Now a not-road group a tenth of whose points are vegetation (green "
        "the largest chromatic coordinate by 0.05; excess green alone calls yellow paint green) is not "
        "absorbed (the default's results: 4 M seed 3 unchanged, 2.82 / 1.54 %; with the five 3.60 -> "
        "1.43 %); keeping vegetation regions out of the groups instead split lawn-joined sidewalks into "
        "small groups that were absorbed (300 k seed 67 E2 8.1 -> 22.7 %). Measured on the same seeds and "
        "not adopted: R1's kept points at the mean height of the input points they represent (the skipped "
        "points nearest to them in plan, within 4 x the height noise), heights at the noise of the full "
        "density: 300 k seeds 0-9 and 60-79 9 -> 10 out (63, 69, 71, 75 within; 0, 61, 70, 78, 79 out): "
        "the cut's flips reshuffled, not fewer.",
        "Point-level stabilisers of the road's outline (2026-12-06, at c841c61, prototypes not committed; 300"
        " k seed 2 in memory against 1 mm LAZ / 1 cm LAZ / half density, % of labels that agree, as "
        "configured 99.43 / 99.27 / 99.27 %, E1 / E2 1.34 / 0.63 %): what disagrees there now is thin strips "
        "along the kerbs (134 clusters of 2 to 355 points on 1 cm, most of them road in the truth that one "
        "run leaves out). (1) A majority vote over the plan neighbours within 1.5 / 2.5 / 3.5 point spacings "
        "after R6: 99.40 / 99.25 / 99.17, 99.49 / 99.31 / 99.26, 99.52 / 99.34 / 99.31 %, E1 / E2 up to 1.56 "
        "/ 0.83 %. (2) The road's outline re-cut at point level (an exact minimum cut over the kNN graph's "
        "edges within 1.5 m of the outline: cutting a continuous edge costs 1, a kerb edge nothing by its "
        "kerb probability, upper side road and lower not 32 per kerb edge, each point 0.6 for leaving its "
        "region's label): 99.62 / 99.51 / 99.34 % on seed 2, seed 0 98.62 / 99.29 / 98.55 -> 98.75 / 99.31 / "
        "98.59 %, seed 5 99.12 / 99.24 / 98.78 -> 99.39 / 99.36 / 98.92 % (with the five-scale vote too: seed"
        " 2 99.65 / 99.57 / 99.40, seed 0 98.75 / 99.19 / 98.77, seed 5 99.49 / 99.35 / 98.60 %: the half "
        "density and seed 0's sidewalk piece at a lowered kerb stay under 99.5 %); AHN3 E1 / E2 6.88 / 1.10 "
        "-> 3.94 / 0.82 %, but over 300 k seeds 0-9 and 60-79 10 out of the bounds instead of 9 and the "
        "median E1 1.72 -> 1.93 %: the cut's shrinking bias takes the thin road between parked cars (300 k "
        "seed 7 E1 2.01 -> 3.48 %: 812 road points lost, 77 % of them road in the truth); 1.0 per point: seed"
        " 7 2.88 %, AHN3 4.95 %; kerb edges thresholded at probability 0.5, or 8 instead of 32: no change. "
        "Cost at 4 M seed 0: 0.57 s of cut over a 117 k-point band. Not adopted: no variant made the three "
        "deliveries pass on even one scene without losing road elsewhere.",
        "The point-level cut of the note above allowed to add road only (no road point leaves the road; "
        "2026-12-06, prototype not committed): over 300 k seeds 0-9 and 60-79 9 out of the bounds either way "
        "(63 and 71 in, 61 and 79 out), median E1 1.72 -> 1.17 %, median E2 1.22 -> 1.44 % (the kerb faces "
        "and the foot of lowered kerbs join), AHN3 6.88 / 1.10 -> 3.23 / 1.62 %; invariance on seed 2 99.52 /"
        " 99.41 / 99.37 %. With the colour difference across an edge weakening its smoothness (3 or 6 colour-"
        "noise sigmas) the gains and losses both shrink (E2 of seeds 1 / 61 / 79 2.45-2.48 / 3.05-3.09 / "
        "2.54-2.64 %, AHN3 E1 4.5-5.0 %); points the growth adds that stand over the road's local surface by "
        "more than 1-2 noise sigmas taken out again: E2 3.52-3.89 % on seed 61. Not adopted.",
        "Denser than the generator's 50-300 points/m2 (2026-12-06, at b4683b3, not used to choose anything): "
        "uav-road 1 M points at 800 points/m2 (`synthetic.generate(..., density=800)`: a 35 m scene), seeds 0"
        " / 1 / 2: E1 / E2 0.92 / 2.68, 3.80 / 1.34, 1.59 / 2.73 %, within the per-scene bounds (R1 thins to "
        "its 60 points/m2).",
        "Below the generator's 50 points/m2 (2026-12-06, at b4683b3, `synthetic.generate('uav-road', 500_000,"
        " seed, density=)`, not addressed): seeds 0-4 at 40 points/m2 E1 / E2 2.53 / 0.52, 1.90 / 0.92, 10.41"
        " / 0.39, 8.78 / 2.71, 34.91 / 0.65 %; at 20 points/m2 5.32 / 0.63, 3.15 / 1.70, 10.36 / 0.58, 10.92 "
        "/ 1.45, 21.32 / 0.83 %. The same layouts at 100 points/m2 (1.25 M points): seed 2 1.02 / 0.38, seed "
        "3 1.86 / 2.31, seed 4 24.58 / 0.55 %: seeds 2 and 3 lose streets to the density (seed 2: a side "
        "street under tree crowns and their shadows, found at 100), seed 4 to its look at any density (a "
        "lighter north-south street beside a dark east-west one, 4.4 cm height noise: its 8-11 cm kerbs blur,"
        " road_regions warns). Not the colour balance: colour off, seed 2 9.69 %, seed 3 8.07 / 6.06 %; "
        "`colour_density_power` 1.0 instead of 1.5: seeds 0-4 at 40 no better (seed 4 37.90 %), AHN3 E1 6.88 "
        "-> 12.89 %. Not the component rules (keep_area and keep_area_kerb 0: unchanged); the filters' k 16 "
        "instead of 12: seed 3 42.70 %. Seed 2's side street at 40 points/m2: its 55 regions (5,702 points) "
        "have no pair with a road region (the junction's regions went to not road) and kerbs along 646 of "
        "their 2,090 boundary edges to not-road regions (contrast-weighted smoothness 1,308, internal kerb-"
        "like pairs 66 edges): not road is cheaper; at 100 points/m2 kerbs along 1,237 of 1,603 such edges "
        "and 663 edges to road regions: road. Kerb detection along the street fell with the density.",
        "Held-out streets that still fail (2026-12-06, at 51602af, nothing adopted): parked_bumper2bumper E1 "
        "/ E2 4.43 / 4.21 %: its light sidewalks and driveways (grey 120-160) read road-like to the colour "
        "model (log ratio +0.93, median) because raised lawns step up from them: the lower sides of lawn "
        "edges are sidewalks, and the road kerbs' upper sides hide behind the parked cars (clear kerbs' lower"
        " sides at grey 120-160: 1,179 kerb edges, upper sides 560). Leaving pairs whose upper side is green "
        "out of the colour samples: 4.63 / 2.08 %, but roads lined by verges lose their only kerbs: "
        "rural_curved_nokerb E1 3.89 -> 76.95 %, rural_curved_kerb12 2.07 -> 5.33 %, oldtown_alley_gardens "
        "0.85 -> 41.34 %, 300 k seed 67 5.41 -> 11.13 %, seed 73 55.6 -> 83.7 %; weighting those pairs down "
        "by the scene's share of paved / paved kerbs did not tell the cases apart (seeds 67 / 73 read 0.90 / "
        "0.94 paved / paved and still lost their road: there the paved kerbs are noise steps and the verge "
        "kerbs the road's); leaving out lower sides that are upper sides elsewhere (a middle tier): no scene "
        "better. oldtown_alley (E2 33.71 %): an alley of setts flush with stone-slab courtyards, no kerb; the"
        " slabs in shadow are taken, those in sun are not: setts and slabs differ in brightness only "
        "(chromatic coordinates 0.357 / 0.336 / 0.307 against 0.36 / 0.34 / 0.30), which the shadow takes "
        "away. Rotated by 30 / 45 degrees, uav-road 300 k seeds 0-2: labels agree on 96.3-99.1 % (seed 1 at "
        "45 degrees E2 2.31 -> 3.39 %), the cut's flips under any small change of the input. Corridor surveys"
        " (only the points within 8 m of the road, 1 M seeds 0-2): E1 / E2 0.80 / 1.27, 2.28 / 3.35, 0.69 / "
        "0.80 % against 0.70 / 0.81, 1.80 / 2.45, 0.49 / 0.37 % for the whole scenes.",
        "Height noise per block as the default, measured and not adopted (2026-12-06, at f2ec330; "
        "`road_regions.noise_block`, off by default): two uav-road 4 M scenes side by side in one survey "
        "(seeds 0 and 1, R6 noise 2.3 and 3.9 cm alone; `benchmarks/paper_scale/run.py`'s `build_survey` "
        "with 8 M points in 2 files) run untiled through the CLI lose street sections with one noise for "
        "the whole run: E1 / E2 12.08 / 0.48 % (each scene alone about 3.0 and 2.4 % E1); `noise_block: "
        "40` 4.83 / 0.78 %, 80 m 7.05 / 0.82 %; tiled at 150 m (each tile measures its own window) 6.19 / "
        "0.50 %. On the matrix with 40 m blocks: 4 M seed 4 E1 4.00 -> 6.71 % (out of bounds), 1 M seed 3 "
        "2.26 -> 4.63 %, 4 M median E1 1.91 -> 2.07 %, all synthetic 1.65 / 0.63 -> 1.67 / 0.60 %; AHN3 "
        "6.88 / 1.10 -> 7.83 / 0.67 %; unseen 300 k seeds 60-79 the same 9 out of bounds (each scene one "
        "or two blocks); with 80 m blocks 4 M seed 4 7.82 %, 1 M seed 7 1.59 -> 4.15 %. Seed 4 (R6 noise "
        "4.3 cm, one of the noisiest) loses road with any per-block noise, though its 24 blocks read "
        "4.03-4.73 cm against 4.26 cm for the whole (filtered-step spread 1.11-1.39 against 1.25 cm): "
        "11,233 road points of one street section (two neighbouring blocks) go and 848 come, so a 10 % "
        "change of the filter's window flips that street: a scene the one-noise configuration passes at a "
        "knife edge (its kerbs under 2.5 noise sigmas), not a fault of the block estimates. Blocks "
        "measured on their smoother edges instead (each block's 25th percentile of |step|, brought to the "
        "median's scale by the whole cloud's ratio): the two-scene survey 5.00 / 0.73 %, 4 M seed 4 6.71 "
        "% again, 1 M seed 3 2.64 %, AHN3 6.19 / 0.68 %. Held-out streets with 40 m blocks "
        "(`benchmarks/heldout_streets/run.py --config` a copy of road_uav.yaml with `noise_block: 40`, "
        "every scene named): 17 of 21 within the bounds against 18: photogrammetry_artefacts E1 1.49 -> "
        "24.99 % (not traced), crossfall_curve_red E2 1.11 -> 2.54 %, parked_bumper2bumper E2 4.21 -> "
        "3.58 %, the rest within 0.4 points. A survey whose noise varies along it (flight strips, two "
        "missions) is the phenomenon left open.",
        "Kerb lines from the surface in plan (2026-12-07, prototype not committed; 300 k seeds 0-9 and "
        "60-79 in memory with road_uav.yaml, 9 of the 30 out of the per-scene bounds as configured): R6's"
        " heights on a raster of half its point spacing, the 2 m surface taken out, a derivative of a "
        "Gaussian 0.4 m across and 1 m along a line at 12 orientations (the raster rotated, a separable "
        "filter), thinned to its line (non-maximum suppression across it): a 9.4 cm kerb under 4.6 cm of "
        "height noise (300 k seed 60, where the mode filter's steps across it are 2.4 cm, median) reads "
        "8-10 cm against 1.5-2 cm of the filter's own spread. Added to the edges' kerb evidence (the "
        "larger of the two probabilities) on edges between paved points (neither chromatic nor green) "
        "that cross a line: 13 out; 60 E2 11.03 -> 2.83 %, 62 E2 5.71 -> 2.56 %, 71 E1 5.54 -> 0.60 %, 67"
        " E2 8.05 -> 4.09 %, but E2 up on eleven scenes (0: 1.71 -> 4.13 %, 4: 1.35 -> 4.69 %): the "
        "lowered sidewalks at crossings, whose 0.8 m ramps read as steps at that scale, became the lower "
        "sides of kerbs and joined the road; 76 E1 4.05 -> 98.97 %: its road lies in 11,044 regions (the "
        "largest 1,084 points) held apart by pockets of 6-20 points that count as kerbs along their whole"
        " boundary. Only where the mode filter cannot resolve a 10 cm kerb (2.5 noise sigmas above 10 cm,"
        " the stage's warning): 8 out (60 and 62 within, the matrix scene 300 k seed 4 out by its "
        "crossings). Every edge near a line rather than those crossing it: 15 out (edges beside a kerb on"
        " its road side took its step: on seed 9 3,117 road / road line kerbs against 3,957 road / not "
        "road); 0.25 m across: 15 out; in the merge's veto only, the cut's evidence unchanged: 10 out. "
        "Small regions (under 0.5 or 2 m2) with 70 % of their boundary on one neighbour counted as no "
        "kerb, alone: 9 out (73 E1 55.6 -> 25.9 %, 75 24.3 -> 40.2 %, 67 E2 8.05 -> 11.58 %). The line "
        "detector finds the noisy kerbs; what the cut lacks to use them is the road outline's own shape "
        "(a lowered crossing told from a kerb by the straight kerb line running on across it), not "
        "adopted.",
        "Kerb lines as an option (2026-12-07, `road_regions.kerb_lines`, off by default; "
        "roadx_ti/kerb_lines.py, tests/test_kerb_lines.py): the step filter of the note above at 0.2 m "
        "across and 2 m along a line (a lowered crossing's ramp, a smoothstep over 0.8 m, reads as a step"
        " at any across scale of 0.2-0.4 m; what keeps crossings out is their shortness: 2 m along reads "
        "their 3 m sides at about half their height, 1 m along as kerbs), run only where the filtered "
        "heights blur a 10 cm kerb (2.5 noise sigmas above 10 cm; fully from 10 % above that, not at all "
        "10 % below); edges between paved points that cross a line take the larger of the two kerb "
        "probabilities, and the regions on the two sides of each line cell of kerb probability above 0.5,"
        " sampled 0.2 m plus half a point spacing from it (past the slivers that lie along the line), "
        "become a kerb pair of the cut, its strength the line's length times the graph edges that cross a"
        " metre of line. Measured in memory with road_uav.yaml, kerb_lines on against off: 300 k seeds "
        "0-9 and 60-79 9 -> 8 out of the per-scene bounds (60 E2 11.03 -> 1.10 %, 62 5.71 -> 0.81 %, 73 "
        "E1 55.6 -> 24.7 %, 75 24.3 / 2.95 -> 21.6 / 4.93 %, 300 k seed 1 E2 2.31 -> 1.06 %; 68 E1 2.66 "
        "-> 5.15 % out, 76 E1 4.05 -> 65.5 %: its second street, kerbs of about 8 cm under 4.65 cm, reads"
        " too weak); the matrix (`accuracy --task road`, the 11 scenes it runs on) every scene within the"
        " bounds (1 M seed 9 E1 3.08 -> 1.67 %, 1 M seed 1 E2 2.45 -> 1.60 %, 4 M seed 3 1.54 -> 0.53 %, "
        "4 M seed 4 E1 4.00 -> 4.21 %; medians 1.65 / 0.63 -> 1.59 / 0.63 %, worst 4.00 / 2.45 -> 4.21 / "
        "1.71 %); held-out 1 M and 2 M seeds 40-49 2 -> 3 of 20 out (1 M seed 42 E1 6.13 -> 3.75 % in, 1 "
        "M seed 49 2.91 -> 22.00 %: a street section between two crossings lost, 2 M seed 48 4.54 -> 5.36"
        " %; medians 1.94 / 0.73 -> 2.08 / 0.62 %); held-out streets 18 of 21 either way (E1 of its four "
        "noisy scenes up 0.03-1.6 points: rural_curved_kerb12 2.07 -> 3.71 %, sparse_noisy_20ppm 3.02 -> "
        "3.83 %); AHN3 and 16 M unchanged (not noisy). Lines between a paved point and a verge made a "
        "kerbless lane a kerbed road (rural_curved_nokerb E1 3.89 -> 77.0 %: the kerbless fallback no "
        "longer ran), hence paved points only; line cells of probability 0.05 instead of 0.5: 7 of 30 out"
        " at 300 k but rural_curved_kerb12 E1 7.84 %. R6's time on a noisy scene about doubles "
        "(rural_curved_kerb12, 1 M points at 30 points/m2: 6.4 -> 11.6 s with the orientations filtered "
        "one at a time; two at a time on threads, the same field, 1.3x faster). Not the default: on "
        "scenes made by other means than the generator it gains nothing, and it loses a street on one "
        "held-out generator scene.",
        "Why the unseen 300 k scenes fail (2026-12-07, at 4a74818, in memory with road_uav.yaml; nothing "
        "adopted): the five worst (seeds 60, 67, 73, 75, 76) are the generator's draws with kerbs at or "
        "under 2.4 height-noise sigmas (8.1-9.4 cm kerbs under 3.6-4.8 cm of noise; seeds 0-9 of the "
        "matrix all draw 2.65 sigmas or more). There R6's kerb evidence is mostly noise: of the kerb "
        "edges the cut sees, the share on pairs whose lower side is road and upper side not is 0.13-0.47 "
        "(seeds 76, 60, 73, 75) against 0.59-0.72 on matrix seeds 0, 2 and 3, and region pairs of road "
        "over not-road have a median stepping share of 0.009 on seed 73 (0.39 on seed 2): the "
        "edge-preserving filter's window (2.5 sigmas, 11 cm) swallows a 9 cm kerb, and a narrower one "
        "(1.5 sigmas, alone or with k 24) makes terraces of the noise (seeds 73 / 75 / 60 E1 84-100 %). "
        "The cut then decides on false kerbs: on seed 73 the 45,196-point street it drops would cost "
        "10,172 more as road, of which 3,721 are 744 kerb edges inside it (both sides road, 6 per edge "
        "against 1 both not road) and 3,680 are 115 edges where it reads as the upper side. Measured, not"
        " adopted: a pair counted as a kerb only for its stepping edges beyond the scene's own background"
        " rate (mean edge probability, here 0.6 %) plus 2 binomial sds: 73 / 75 E1 55.6 / 24.3 -> 19.4 / "
        "2.2 % but E2 3.4 / 10.5 %, 76 and 60 unchanged (E2 14.7, 11.1 %): without the false kerbs the "
        "undetected true ones let sidewalks of the road's grey in. Per-edge steps between one-sided "
        "neighbourhood means (k 24, the half behind each end) read a 9 cm kerb at 3.9 of their own sigmas"
        " but flag as many flat edges as they gain kerb edges (34 % of road / ground edges over 5 cm "
        "against 5 % of same-class ones on seed 73; the mode filter 16 % against 2 %); steps between the "
        "two regions' own plane fits at their shared boundary: same-class pairs over 5 cm 15 % on seed "
        "73. Plan-view kNN majority smoothing of the final labels (k 16, for the invariance test on 300 k"
        " seed 2): 1 mm 99.43 -> 99.58 %, 1 cm 99.26 -> 99.40 %, half density 99.27 -> 99.14 %, E1 1.34 "
        "-> 4.61 % (road under crowns takes their label).",
        "The seconds column is wall time in process on the shared 2-core machine; the 2026-12-01 run "
        "shared it with two other jobs, so its times are inflated (benchmarks/RESULTS.md has the timed "
        "A/B).",
    ],
    "roof": [
        "IGN ign_870000_6618000: a 15 x 14 m gabled building south-west of the centre (2,414 points "
        "at 6-9 m, 92 % single returns, grey roof) carries class 1 in the truth; the pipeline finds "
        "it, and it counts as 2,414 false positives of the 3,173 above. Scored with that building as "
        "roof: kappa 0.933, total error 1.56 %; with its points left out: kappa 0.914 (2026-11-22).",
        "The six IGN tiles have no colour: roof growing uses their LiDAR returns as the vegetation "
        "cue (`roof_growing.use_returns`); with it off, kappa was 0.829 / 0.765 / 0.949 / 0.732 / "
        "0.838 / 0.810 on them (2026-11-22).",
        "Synthetic seed 1's missed roof is mostly its garden sheds (1.6-3.2 m square, 2-2.7 m high): "
        "roof_filter drops them by area and width, as it drops vans (2 x 6 m) and hedges. A rule "
        "keeping near-square small segments (plan aspect <= 2, >= 1.2 m wide, >= 4 m2) lifts the "
        "synthetic seeds 0-5 to 0.970 / 0.953 / 0.963 / 0.946 / 0.969 / 0.963 but costs the real "
        "data: reviewed tile 0.9975 -> 0.982, merged IGN block 0.871 -> 0.844, ign_870000 0.762 -> "
        "0.757. In the IGN truth most such segments (low, square, 2-10 m2) are not building, so the "
        "rule is not used (2026-11-22).",
        "Edge completion (`roof_filter.edge_growth`, issue 16), kappa at b45b7e8 -> with it "
        "(and NDVI): reviewed tile 0.9975 -> 0.9980; ign_870000 0.7618 -> 0.7616; "
        "six IGN tiles 0.857 / 0.888 / 0.941 / 0.870 / 0.860 / 0.836 -> 0.853 / 0.889 / 0.942 / "
        "0.870 / 0.862 / 0.840, merged 0.8713 -> 0.8714; the IGN block thinned to 2 / 3 / 5 points/m2 "
        "(hash thinning, scored on the kept points) 0.874 / 0.874 / 0.876 -> 0.879 / 0.878 / 0.875; "
        "the reviewed tile thinned 0.992 / 0.993 / 0.997 -> 0.993 / 0.995 / 0.998. On the dense tiles "
        "footprint completion already added most rims; the gain is at low density. The misses left on "
        "the dense IGN tiles are whole low or narrow buildings the height / width tests drop "
        "(e.g. a 26 m2 roof of median height 1.8 m, an 11 m2 roof 2.5 m wide) (2026-12-01).",
        "NDVI (`roof_growing.use_nir`): of the shared files only the reviewed tile has NIR values "
        "that vary; NDVI > 0.25 marks 12,898 of its points, 1,521 more vegetation-coloured points than "
        "COM alone, with the same roof segments and kappa (2026-12-01).",
        "2026-12-02, three changes, kappa before -> after each (`python -m roadx_ti accuracy --task roof` "
        "at each commit): (1) footprint completion's cell from the measured pulse spacing (3 spacings, "
        "at least 0.5 m) with walls within one cell of a roof's cells (a fixed 1 m cell and 1 m wall "
        "reach took the hedges and bushes along walls): six IGN tiles 0.853 / 0.889 / 0.942 / 0.870 / "
        "0.863 / 0.840 -> 0.861 / 0.921 / 0.952 / 0.898 / 0.877 / 0.870, merged 0.871 -> 0.891, "
        "thinned block 0.878 -> 0.873, reviewed thinned 0.995 -> 0.990, synthetic within 0.002; "
        "(2) `low_noise` (extended local minimum, PDAL filters.elm's rule) before the cloth: "
        "synthetic 300 k seed 6 0.866 -> 0.951 (its low returns held the cloth 1.5-3 m under a lot, "
        "whose ground became roof), real tiles within 0.0001; (3) returns-only foliage within 1.5 m of "
        "a roof surface and among solid neighbours joins the roof (chimney and roof-unit edges): "
        "tiles 0.866 / 0.922 / 0.956 / 0.898 / 0.877 / 0.872, merged 0.893, thinned 0.880, files with "
        "colour unchanged. Held out (not used to choose): synthetic als-roof 300 k seeds 4 / 7 / 12 "
        "with their colour removed 0.951 / 0.913 / 0.930 -> 0.956 / 0.921 / 0.940.",
        "Small buildings (issue 16 point 6), what the shared truth does: ign_870000's truth labels "
        "two detached sheds of about 6 and 3 m2 (42 and 15 points, not at the tile's edge) as "
        "building, next to two low structures of 22-24 m2; the six-tile block's truth has no building "
        "component under 30 m2 away from the block's edge; the reviewed tile's rejected candidates "
        "(class 20) are 20-23 m2 of trees and hedges. The data do not support a single under-10 m2 "
        "rule either way, so the generator's sheds stay roof and min_roof_area stays 10 m2 with "
        "annexes (2026-12-02).",
        "Small buildings (issue 16 point 6), the convention chosen (2026-12-04): structures under "
        "about 10 m2 on their own are not buildings. In ign_870000 the isolated small raised "
        "structures that are not foliage (single returns) are class 1 twice (4.2 and 2.5 m2, white, "
        "1.6-1.8 m above ground) against the two class-6 sheds above; a semi-transparent 9.5 m2 "
        "structure against a house (1 % single returns) is class 1 too; the roof pipeline's rule "
        "that keeps small square segments lost on every real file (above), and the issue reports "
        "IGN's reviewers mostly not counting them. So the generator follows: `als-roof` labels its "
        "garden sheds (2.6-10.2 m2) class 1, `als-roof-v1` keeps them building (bit for bit the "
        "earlier scenes). Synthetic kappa at 300 k / 1 M / 4 M seeds 0-9, v1 truth -> new truth "
        "(same labels from the pipeline): median 0.952 -> 0.965, scenes below 0.95 7 -> 1.",
        "Remaining errors on the six tiles (pictures): crowns and hedges touching a roof kept as "
        "annexes (a segment dropped only by area or width next to a kept roof; a planarity test "
        "against the roofs' own plane noise gained 0.004-0.009 on the merged block but lost on two "
        "tiles, not adopted), low buildings under the 2 m height test, and buildings cut by a tile's "
        "edge (2026-12-02).",
        "Where the merged six-tile block's errors come from (2026-12-05, at d41802f, roof_filter's rules "
        "traced point by point): of 11,218 false roof points 2,132 are in segments kept on their own (tree "
        "crowns with flat single-return patches 11-20 m up), 2,579 in annexes (hedges 2-3 m high along "
        "houses, 90-100 % single returns), 2,830 added by edge growth and 3,677 by footprint completion; "
        "true / false points each rule adds: own 78,547 / 2,132, annex 7,069 / 2,579, edge 7,005 / 2,830, "
        "footprint 10,664 / 3,677, so every rule is net positive. Of 6,070 missed roof points 1,824 are in "
        "dropped segments (a low building of median height 1.77 m above a cloth raised at the block's edge, "
        "a 245-point part of a building cut by the edge), 3,450 in no segment and 796 classed ground. The "
        "annexes' single-plane residual (MAD) separates only at its top: every annex above 0.12 m is not "
        "building (792 points), but building annexes reach 0.120 m, an absolute margin of 7 mm on one "
        "sensor. LiDAR intensity is no transferable cue either: single-return vegetation against roof "
        "medians per tile 1032 / 904, 1107 / 1318, 1131 / 914, 1137 / 1309, 1121 / 1225, 1146 / 1290 "
        "(roofs brighter on four tiles, darker on two).",
        "Split-pulse superstructures (2026-12-05): footprint completion let a point that only the returns "
        "cue calls foliage join within 1.5 m of the roof surface only when at most half of its kNN neighbours "
        "were foliage returns; on a small vent or chimney top most neighbours are split returns too, and "
        "the 17 m apartment roofs of the six tiles kept dozens of such clusters out. Now such a point is in "
        "foliage (kept off) only when every neighbour is a foliage return: one solid neighbour means it "
        "stands at the edge of something solid. Merged block kappa 0.8934 -> 0.8986 (964 roof points "
        "gained, 168 foliage points, class 4 / 5, by roof edges taken), tiles 0.8655 / 0.9219 / 0.9561 / "
        "0.8983 / 0.8771 / 0.8721 -> 0.8762 / 0.9194 / 0.9644 / 0.9013 / 0.8785 / 0.8765, ign_870000 0.7664 "
        "-> 0.7658, thinned block 0.8802 -> 0.8804, reviewed tile, its thinned copy and sample_c unchanged; "
        "the synthetic als-roof scenes carry no returns and do not move. The share of foliage neighbours "
        "that makes a point in foliage, measured on the merged block: half (before) 0.8934, 75 % 0.8977, "
        "90 % 0.8985, all 0.8986, no test 0.8986; the majority test applied only to points above the roof "
        "points among their neighbours 0.8947. The cost is a crown's fringe touching a roof "
        "(tests/test_roof_growing.py: 0.075 of a low crown over a roof's corner against 0.033).",
        "Roofs under crowns (2026-12-05, 30a3f4e): in the synthetic als-roof scenes about half of the missed "
        "roof points (300 k seeds 9 / 1 / 3: 1,237 / 911 / 1,206 of 2,094 / 1,788 / 2,234) lie under a crown "
        "(vegetation points more than 0.3 m above within 0.7 m in plan), carry its orthophoto colour "
        "and are kept off edge completion by the colour cue; about a third are wall points below 1 m above "
        "the ground (attach_min_height). A vegetation-coloured point that the highest point of its plan cell "
        "(the footprint cell) overtops by more than 1 m (at least one cell edge) is now covered, and its "
        "colour does not keep it off edge completion (roof_growing.covered_clearance): 300 k seeds 0-9 "
        "kappa mean 0.9631 -> 0.9649, every seed up; the real tiles unchanged to four decimals "
        "(ign_870000: 9 more edge points). Measured and not adopted: the same exemption in roof growing "
        "itself (mean 0.9651, three seeds down), more edge rounds (8: seeds 9 / 1 / 3 +0.002 more, but "
        "6 rounds cost the six IGN tiles earlier), a support test that ignores the neighbours above the "
        "plane (no change: under a dense crown the kNN graph itself no longer links the roof points), "
        "covered lowest points on the nearest segment's plane within 3 m (the nearest segment's plane is "
        "often the wrong facet: 199 roof against 1,222 other candidates, kappa down), and "
        "attach_min_height 0.3 m for the low walls (merged IGN block 0.8986 -> 0.8992 but ign_870000 "
        "0.7658 -> 0.7501). ign_870000 scored with its unlabelled building as roof is 0.9447 now (the "
        "issue's bound 0.95): its remaining misses are two structures of 1.3-1.5 m that the truth calls "
        "building (244 points, under the 2 m height test) while a 2.4 m structure nearby is class 1 "
        "(205 false points): conventions the height test cannot both follow.",
        'AHN3 as a roof dataset (2026-12-05, first scored at ef0725b; no roof setting was chosen on '
        'it, so it is a held-out tile of another country, sensor and labeller): the Amsterdam street '
        'block of the road rows, class 6 (building, walls included) as truth, returns as the '
        'vegetation cue (no colour). Kappa 0.9463, type I 7.39 %, type II 0.09 %. Of its 886 missed '
        'building points (traced against the kept roofs in plan): 230 lie away from every kept roof, '
        "mostly a low building cut by the tile's edge (median 2.5 m above the ground, dropped by the "
        'area test); 297 stand 1 m or more above the nearest kept roof point, within 0.5 m of it in '
        'plan (the edges of a higher roof level and of roof structures; 85 % of them split returns, '
        "which the returns cue keeps off except near a roof's surface); 191 are walls below a roof's "
        "edge and 168 lie at a roof's level beside it (half to two thirds split returns). The few "
        'false points (0.09 %) suggest that the returns rules err on the safe side on this city '
        "block; the walls that IGN's truth rarely has are part of the misses here.",
        "Half density on the real tiles (2026-12-05, at ef0725b; the roof invariance test's thinning,"
        ' every other point of a seeded permutation): full / half kappa and agreement on the shared '
        'points, six IGN tiles 0.8762 / 0.8624 (97.51 %), 0.9194 / 0.9221 (99.61 %), 0.9644 / 0.9541 '
        '(98.93 %), 0.9013 / 0.8632 (97.35 %), 0.8785 / 0.9022 (98.49 %), 0.8765 / 0.8691 (97.98 %); '
        'reviewed tile 99.99 %, ign_870000 99.84 %. On 77055_627760 the half-density run keeps 555 '
        "more high-vegetation points as roof: hedges 2-3.5 m high whose segments sit at the tests' "
        'thresholds at both densities (full: 10.0 m2, 1.75 m wide, 2.13 m high, dropped; half: 11.6 '
        'm2, 3.11 m wide, 2.11 m high, kept), grown wider at half density (k = 10 neighbours span '
        '1.4x the radius, normals are smoother, and a sparse point links pieces up to 3 m apart; a '
        'curved 30 m hedge became one 66 m2 segment 9.9 m "wide" by its plan covariance). Measured '
        'and not adopted: k from a fixed neighbourhood radius (k = density x pi r0^2, 10 to 32): r0 '
        '0.5 m, six tiles full / half mean kappa 0.9027 / 0.8955 -> 0.9044 / 0.8968, agreement 98.31 '
        '-> 98.67 % (77055_627760 97.35 -> 97.16 %); r0 0.7 m 0.8952 / 0.8941, 98.53 %: the scale of '
        'the neighbourhood is not what decides these hedges.',
        "Roofs cut by the data's edge (2026-12-05, roof_filter.edge_cut): a tile's boundary cuts buildings, "
        "and what is left of one inside can be narrower than min_roof_width: on IGN tile 77060_627755 "
        "building parts along the east edge, 1.5-2.5 m deep inside the data and 3.3-4.2 m along it (245, "
        "336 and 135 points), were dropped by the width test. A segment with points in the data's edge "
        "cells (footprint.data_edge: occupied cells of the density cell with two empty cells in a row "
        "beside them, so a sampling gap is no edge) is now as wide as its cut is long, when it is at least "
        "a third of min_roof_width across (a fence or wall top along the edge stays narrow). Kappa: "
        "77060_627755 0.8785 -> 0.8990, merged block 0.8986 -> 0.9025, synthetic 1 M seed 4 0.9717 -> "
        "0.9722; every other real file and synthetic scene unchanged to four decimals. Left: the largest "
        "cut part there (630 points at a median 1.77 m) stays under the 2 m height test. Measured and not "
        "adopted: the edge as the edge cells and their neighbours (a band of up to two cells): AHN3 0.9463 "
        "-> 0.9577 (its cut building stops a rim short of the edge), but 77060_627760 0.8765 -> 0.8552 "
        "(a 2 m hedge or wall within two cells of the edge taken); the cut segments' area test is "
        "unchanged (AHN3's cut low building stays dropped by it). Crops of the real files (the merged "
        "block, ign_870000, the reviewed tile, AHN3, sample_c; windows cut buildings anywhere), edge_cut "
        "off -> on: 40 m windows every 25 m, 40 crops, 4 up (+0.009 to +0.052) and 1 down (-0.027), pooled "
        "kappa 0.8695 -> 0.8721; 30 m every 17 m, 71 crops, 4 up (a building cut to a sliver: 0 -> 0.998 "
        "and 0 -> 0.78) and 2 down (-0.058, -0.026), pooled 0.8599 -> 0.8587; 50 m every 30 m, 27 crops, "
        "1 up (+0.039) and 3 down (-0.0005 to -0.0043), pooled 0.8730 -> 0.8743. Every loss is a hedge "
        "(class 5, 99-100 % single returns, 2.1-2.2 m, 1.5-1.65 m wide) running along the window's "
        "edge, which the width test dropped: across a cut, a hedge along the edge and a building's "
        "remaining strip look alike in plan. Tiled runs see each tile's own window as the edge: the six "
        "tiles as one folder, tiled at 60 m against untiled, agree on 99.926 % of the points with edge_cut "
        "and 99.931 % without it.",
        "Returns share of whole roof components (2026-12-05, measured, not adopted): the false roof of the "
        "six-tile block, full density and thinned to 3 points/m2, is mostly high vegetation (class 5: 9,968 "
        "of 11,399 and 1,098 of 1,363 points), whose pulses split more often than a roof's (earlier returns "
        "of multi-return pulses: 27 % of the false roof points against 9-10 % of the true ones, both "
        "densities). Grouped into connected components of the predicted roof (plan links of 0.5 m, 1.2 m "
        "thinned, heights within 1.5 m), components whose points are 30-40 % earlier returns hold 3,356 "
        "false and 1,018 true roof points at full density (420 / 124 thinned), but those of 40-50 % hold "
        "mostly roof (357 / 1,127; thinned 113 / 105) and above 50 % too (362 / 2,314: small pieces of roof "
        "rims and superstructures, whose pulses split at the edges): no threshold on the share separates "
        "crowns from roofs, so no component rule was made of it.",
        "Seen through (2026-12-06, f01433a, `roof_filter.see_through_depth` 2 m, `max_see_through` 0.1; "
        "files with multi-return pulses only): the largest false roof of the six-tile block was one tall "
        "tree on tile 77050_627755 (x 4-10 m, y 33-41 m: ten flat patches of its crown 6-20 m up, 2,800 "
        "points, each passing the area test). Pulses pass such patches down to the branches (later "
        "returns below), a roof stops them; a segment is dropped when later returns in no segment lie "
        "more than 2 m under its top in its interior footprint cells (the rim left out: eaves split "
        "pulses onto walls), as many as a tenth of its own points there. Kappa 77050_627755 0.8762 -> "
        "0.9133, merged block 0.9025 -> 0.9103, AHN3 0.9463 -> 0.9458 (7 points of a roof), every other "
        "file and the synthetic scenes (no multi-return pulses) unchanged. Measured and not adopted: every "
        "point under a segment rather than later returns only (AHN3 0.9369: facades under mansard rims); "
        "the vegetation cue's points instead (no gain: the branches below are later returns, which the "
        "returns cue does not flag); shares of cells instead of points (the share depends on the cell: "
        "0.25 / 0.3 / 0.5 m cells gave merged 0.9034 / 0.9097 / 0.9061); no erosion of the rim (merged "
        "0.9126, AHN3 0.9365); depth 1-1.5 m (77050_627760 0.9194 -> 0.9307, merged 0.9109, but AHN3 "
        "0.9458 -> 0.940: see-through structures about 2 m over flat roofs there, pergolas or glass, "
        "that its truth calls building). Hedges (the other large false roof, 2-3.5 m high) are not "
        "caught: they are dense (few later returns under them), and neither segment curvature nor the "
        "inscribed width separates them from the low roofs of the same tiles.",
        "Superstructures up to a storey (2026-12-06, 1984a59, `roof_filter.superstructure_height` 1.5 -> "
        "3 m): after the seen-through rule, 1,185 of the merged block's missed roof points lay 5 m or "
        "more above the ground in no segment, within 0.07 m (median) in plan of a kept roof and 2.6 m "
        "(median) above it, 92 % of them earlier returns of split pulses: the sides and rims of stair "
        "and lift housings and of higher roof levels, which the returns cue takes for foliage and "
        "footprint completion let join only within 1.5 m of the roof surface. Within a storey (3 m), "
        "kappa: merged block 0.9103 -> 0.9122, 77050_627755 0.9133 -> 0.9144, 77055_627755 0.9644 -> "
        "0.9674, 77055_627760 0.9013 -> 0.9042, 77060_627755 0.8990 -> 0.9011, 77060_627760 0.8765 -> "
        "0.8800, but 77050_627760 0.9194 -> 0.9155 (42 more false points: crown fringes over a roof with "
        "a solid neighbour); AHN3 0.9458 -> 0.9502, thinned block 0.8804 -> 0.8823, ign_870000 0.7658 -> "
        "0.7656, the reviewed tile and the synthetic scenes (no multi-return pulses) unchanged. 2.5 m "
        "gave merged 0.9122 too, 3.5 m 0.9124 (77050_627760 0.9152). Measured and not adopted: low walls "
        "0.5-1 m above the ground joining where attached wall points lie within 0.1-0.3 m in plan above "
        "them (merged block: +317 / -140 to +604 / -441 true / false points, about +0.002).",
        "Other densities than the report's (2026-12-06; `accuracy.thin_to_density`, scored on the kept "
        "points; kappa at full / 10 / 5 / 2 points/m2), at bb71fa4 -> after the seen-through and storey "
        "rules (1984a59) -> with `roof_seeds.r_max: auto` (the default since that day): merged IGN block "
        "0.9025 / 0.9133 / 0.8885 / 0.8873 -> 0.9122 / 0.9152 / 0.8901 / 0.8891 -> 0.9122 / 0.9150 / "
        "0.8911 / 0.8913; AHN3 0.9463 / 0.9171 / 0.8599 / 0.8499 -> 0.9502 / 0.9159 / 0.8663 / 0.8542 -> "
        "0.9502 / 0.9159 / 0.9048 / 0.8584; the reviewed tile 0.9994 / 0.9986 / 1.0000 / 0.9921 throughout, "
        "then 0.9566 at 2 points/m2 with auto (one rejected candidate of 34 points, class 20, becomes roof: "
        "a fixed 2.6 or 3 m takes it too); ign_870000 within 0.0003. The fixed 2 m r_max lost the narrow "
        "roofs of the sparse AHN3 city block (k = 10 neighbours of a 5 points/m2 facet reach past 2 m); "
        "auto is 4 radii of the k-neighbourhood at the measured first-return spacing (about 1.3 m at "
        "IGN's 30 points/m2, where nothing changes, 3.2 m at 5). AHN3 still falls from 0.95 to 0.86-0.90 "
        "below 10 points/m2: sparse ALS (issue 16's point 2) is not solved. On the synthetic matrix "
        "(about 15 points/m2, auto 1.8-1.9 m against 2 m) every scene loses 0.0001-0.0020 (medians "
        "300 k / 1 M / 4 M 0.9676 / 0.9661 / 0.9662 -> 0.9665 / 0.9650 / 0.9655, worst 1 M seed 1 0.9529 "
        "-> 0.9517); the report's thinned IGN block 0.8823 -> 0.8855.",
        "Split-pulse walls (2026-12-06, measured, not adopted): footprint completion's wall rule (points "
        "below a kept roof's edge) takes only points no vegetation cue flags; letting the returns-only "
        "ones with a solid neighbour join there too (as on the roof surface) raised AHN3, whose truth "
        "labels walls, at full / 10 / 5 / 2 points/m2 0.9502 / 0.9159 / 0.9048 / 0.8584 -> 0.9586 / "
        "0.9273 / 0.9201 / 0.8811, but cost every IGN tile but one (merged block 0.9122 -> 0.9101: 438 "
        "wall points gained, 844 hedge and crown points by walls taken; ign_870000 0.7656 -> 0.7636): "
        "the two truths' wall conventions pull apart.",
        "roof_seeds.k (2026-12-06, measured, kept at 10): k 6 / 8 / 10 / 12, merged block 0.9343 / 0.9198 / "
        "0.9122 / 0.9173, 77050_627755 0.9736 / 0.8997 / 0.9143 / 0.9123 (one tall tree's crown patches "
        "in and out), thinned block 0.8887 / 0.8992 / 0.8855 / 0.8945, reviewed tile thinned to 3 "
        "points/m2 0.9564 / 0.9504 / 0.9899 / 0.9899, AHN3 0.9487 / 0.9570 / 0.9502 / 0.9580; at 10 / 5 / "
        "2 points/m2 k 12 against 10 moves the merged block -0.009 / +0.001 / +0.014, AHN3 -0.008 / "
        "+0.014 / -0.012, ign_870000 at 2 points/m2 -0.022. Not monotonic in k and of either sign per "
        "file: single objects flip, so no k was chosen from these. The seen-through rule counting later "
        "returns in other segments too (stacked crown patches): merged block 0.9122 -> 0.9145, ign_870000 "
        "0.7656 -> 0.7685, but AHN3 0.9502 -> 0.9463 (the flat roofs under its see-through structures are "
        "segments), not adopted; with k 8 the same gave merged 0.9359 and 77050_627755 0.9751 (its tall "
        "tree caught) but AHN3 0.9424 and the thinned reviewed tile 0.9504: a combination picked on these "
        "files, not taken.",
        "Roofs under crowns again (2026-12-06, c052c91): 1,083 of the 1,940 missed roof points of 300 k "
        "seed 9 (kappa 0.9449, the matrix's lowest) lie under a crown, most of them on the plane of a kept "
        "facet that runs on under it (a 4 x 8 m piece of a gable roof's slope). Measured, not adopted: "
        "after edge completion, more rounds of it for covered points only (overtopped in their footprint "
        "cell by more than 1 m; eaves and rims not covered keep the three rounds): 6 rounds: the ten 300 k "
        "scenes mean 0.9643 -> 0.9654, seed 9 0.9449 -> 0.9465 (still under 0.95), but the merged IGN "
        "block 0.9122 -> 0.9117, 77050_627755 0.9143 -> 0.9133, 77055_627760 0.9042 -> 0.9030, AHN3 "
        "0.9502 -> 0.9506; 12 rounds: seed 9 0.9428 (the growth creeps into the crowns' lowest points).",
        "Hedges judged, not assumed (2026-12-06, issue 16's point 4; three rules, all from the data's own "
        "geometry): after the rules above, 8,805 of the merged block's 10,225 false roof points were high "
        "vegetation, mostly hedges and shrubs 2-3.5 m high against houses: kept as annexes (2,114 "
        "points), grown into a low roof's segment (one 1,250-point segment, 404 of them hedge), or taken "
        "around those by edge and footprint completion. (1) `roof_growing.low_expand_curvature_max` 0.02 "
        "(the seeds' c_t) under `low_height` 4.5 m: a low point passes growth on only when planar, so a "
        "roof no longer grows through a hedge touching its eaves (above 4.5 m the 0.05 stays: AHN3's "
        "rough roof parts at 8-17 m need it; 0.02 everywhere gave merged 0.9436 but AHN3 0.9390 and "
        "0.8469 thinned). (2) `roof_filter.low_min_planar` 0.15: a segment under narrow_max_height with "
        "fewer than 15 % planar points (curvature < 0.005) is neither roof nor annex (hedge segments 0-12 "
        "%, low roofs 19-94 % on the merged block); judged only for segments of at least 3 k points (at 2 "
        "points/m2 an 18-point AHN3 annex roof read 11 %). (3) annexes by exact plan distances between "
        "points (annex_reach 1 m plus two pulse spacings, the sampling's gap; the old square window of "
        "footprint cells reached up to about 2 m) and lying along the roof: at least `annex_min_contact` "
        "0.2 of their points that close (judged for 3 k points or more): a hedge running 20 m from a "
        "house's corner touched it at one end (3.5 % of its points). Kappa at 233cab5 -> after: six tiles "
        "0.9143 / 0.9155 / 0.9674 / 0.9042 / 0.9011 / 0.8800 -> 0.9257 / 0.9184 / 0.9695 / 0.9380 / "
        "0.9290 / 0.9019, merged 0.9122 -> 0.9376, thinned block 0.8855 -> 0.9039, AHN3 0.9502 -> 0.9500 "
        "(thinned 0.8710 -> 0.8706), ign_870000 0.7656 -> 0.7662, reviewed tile, its thinning and "
        "sample_c unchanged; at 10 / 5 / 2 points/m2: merged 0.9150 / 0.8911 / 0.8913 -> 0.9198 / 0.9089 "
        "/ 0.8943, AHN3 0.9159 / 0.9048 / 0.8584 -> 0.9161 / 0.9038 / 0.8574, ign_870000 0.7646 / 0.7656 "
        "/ 0.7736 -> 0.7652 / 0.7670 / 0.7634; synthetic medians 300 k / 1 M / 4 M 0.9665 / 0.9650 / "
        "0.9655 -> 0.9677 / 0.9645 / 0.9648. Held out (not looked at while choosing): synthetic 300 k "
        "seeds 10-14 0.9624 / 0.9611 / 0.9630 / 0.9653 / 0.9538 -> 0.9622 / 0.9609 / 0.9626 / 0.9652 / "
        "0.9537, seeds 4 / 7 / 12 with colour removed 0.9658 / 0.9339 / 0.9485 -> 0.9662 / 0.9339 / "
        "0.9485. Each rule alone is needed: without (1) merged 0.9281, without (2) 0.9362; contact 0.1 / "
        "0.2 / 0.3 gave merged 0.9376 / 0.9376 / 0.9357 (without the 3 k guard 0.1 cost AHN3 at 2 "
        "points/m2 0.019: a 14-point annex with one point near its roof). Left: the half-density "
        "invariance of tests/test_roof_invariance.py on tile 77055_627760 went 97.32 -> 96.24 % "
        "(synthetic 99.24 -> 99.31 %): at half density that tile's hedges and low annex still flip. "
        "Measured, not adopted: planarity as the plane residual sqrt(l0) against the seeds' median "
        "(density-free in metres: roof 1.5-1.8 cm at full, half and quarter density): thinned block 0.912 "
        "but AHN3 at 10 / 5 / 2 points/m2 0.902 / 0.892 / 0.845; growth edges only between points within "
        "3 noise sigmas of each other's plane: merged 0.926, AHN3 0.942; a minimum roof height of 1.5 / "
        "1.8 m (finds a 2 m outbuilding on 77060_627755 but takes terraces: merged 0.919 / 0.921); walls "
        "joining within 3-4 pulse spacings of a kept roof's points instead of one footprint cell: IGN "
        "+0.006, AHN3 -0.004 to -0.008 (its truth labels walls).",
        "ign_870000 with its unlabelled building as roof, a report row (2026-12-06): the row amends the "
        "truth with the building's class-1 points (`accuracy.with_unlabelled_building`: the box of its "
        "roof and walls, x 870214.0-870230.6, y 6617089.4-6617106.0, nothing but class 1 in it, more than "
        "2 m above the box's lowest point: 2,698 points); the pipeline reads no input class. Kappa 0.9499 "
        "at 233cab5, 0.9506 at f698568 (issue 16's bound 0.95). The 0.9447 quoted above scored another "
        "point set of the same building, not recorded; this row's definition is the one to follow. Left: "
        "377 missed points (the 1.3-1.5 m structures under the 2 m height test, rims) and 448 false ones "
        "(the 2.4 m structure at the west edge that the truth leaves in class 1, crown patches on the "
        "north-west house).",
        "Crowns hanging over low roofs (2026-12-06, `roof_filter.over_roof_reach` 3 m): footprint "
        "completion lets a point that no vegetation cue flags join anywhere inside a roof's footprint, "
        "whatever its height; on tile 77060_627760, 332 false points did so 5-9 m (median 6.8 m) above a "
        "3 m roof, 4.5-9.8 m (10-90 %, 3D) from the nearest roof point: a tall crown over a low building. "
        "True points more than a storey over their cell's roof (merged block 254, AHN3 117: upper levels' "
        "walls and structures on roofs) lie 0.4-3.0 m from a roof point. Such points now join only within "
        "a storey (3 m, 3D) of a roof point (`roof_filter.over_roofs`; the cell is footprint "
        "completion's, the height superstructure_height). Kappa before -> after: six tiles 0.9257 / "
        "0.9184 / 0.9695 / 0.9380 / 0.9290 / 0.9019 -> 0.9253 / 0.9189 / 0.9695 / 0.9380 / 0.9286 / "
        "0.9146, merged 0.9376 -> 0.9395, thinned block 0.9039 unchanged, AHN3 0.9500 -> 0.9496 (thinned "
        "0.8706 -> 0.8699), ign_870000 and the reviewed tile unchanged; at 10 / 5 / 2 points/m2 merged "
        "0.9198 / 0.9089 / 0.8943 -> 0.9199 / 0.9096 / 0.8949, AHN3 0.9161 / 0.9038 / 0.8574 -> 0.9160 / "
        "0.9036 / 0.8574; synthetic medians 300 k / 1 M / 4 M 0.9677 / 0.9645 / 0.9648 -> 0.9687 / 0.9651 "
        "/ 0.9655 (worst 0.9445 -> 0.9453). Held out: synthetic 300 k seeds 4 / 7 / 12 without colour "
        "0.9662 / 0.9339 / 0.9485 -> 0.9705 / 0.9403 / 0.9523, seeds 10-14 with colour 0.9622 / 0.9609 / "
        "0.9626 / 0.9652 / 0.9537 -> 0.9625 / 0.9611 / 0.9636 / 0.9658 / 0.9544. Reach 2 / 3 / 4 m: "
        "merged 0.9392 / 0.9395 / 0.9394, 77060_627760 0.9146 / 0.9146 / 0.9140, AHN3 0.9492 / 0.9496 / "
        "0.9500. Measured, not adopted: the height over the roof point nearest in plan instead of the "
        "cell's (also tests points outside roof cells): AHN3 0.9490, thinned 0.8661 (walls of a taller "
        "neighbour); a wall rule only for non-horizontal normals (|n_z| < 0.8 or 0.9: bush tops under "
        "eaves are horizontal): IGN +0.001 to +0.009 per tile but AHN3 0.9396-0.9426 (its gutters and "
        "eaves below roof edges); a cap of 2-4 m on any point above its roof: AHN3 and 77050_627755 lose "
        "76-269 true points.",
        "Bush tops under the eaves (2026-12-06, `roof_filter.wall_max_normal_z` 0.8): footprint "
        "completion's wall rule (a point under a roof edge, outside the roof's cells, within one cell of "
        "them) took, on the merged block, 1,178 false points (median 1.9 m above the ground, |normal z| "
        "median 0.90: level) against 931 true ones (3.1 m, 0.66); on AHN3 309 true (11.1 m, 0.24: walls) "
        "against 12 false. Points lower than narrow_max_height (4.5 m, the band of hedges and vehicles) "
        "now join there only on steep surfaces (|n_z| < 0.8, about 37 degrees; kernels.seeds INSIDE_ONLY: "
        "such a point still joins inside a footprint). Kappa before -> after: six tiles 0.9253 / 0.9189 / "
        "0.9695 / 0.9380 / 0.9286 / 0.9146 -> 0.9276 / 0.9248 / 0.9739 / 0.9387 / 0.9278 / 0.9191, merged "
        "0.9395 -> 0.9418, thinned block 0.9039 -> 0.9064, reviewed tile thinned 0.9899 -> 0.9954, "
        "ign_870000 0.7662 -> 0.7670 (with its building as roof 0.9506 -> 0.9515), AHN3 0.9496 -> 0.9498 "
        "(thinned 0.8699 -> 0.8696); at 10 / 5 / 2 points/m2 merged 0.9199 / 0.9096 / 0.8949 -> 0.9215 / "
        "0.9118 / 0.8943, AHN3 0.9160 / 0.9036 / 0.8574 -> 0.9160 / 0.9035 / 0.8568, ign_870000 0.7652 / "
        "0.7670 / 0.7634 -> 0.7657 / 0.7679 / 0.7685; synthetic 300 k seeds 0-9 within 0.0003, held-out "
        "synthetic (seeds 4 / 7 / 12 without colour, 10-14 with) within 0.0005. Without the height band "
        "(every level point): AHN3 0.9464 and at 10 / 5 / 2 points/m2 0.9137 / 0.8977 / 0.8467 (balconies "
        "and eaves below roof edges, which its truth calls building), so the band. Left: tile "
        "77060_627760 at 0.9191, the one of the six under issue 16's 0.92.",
        "Small low buildings dropped by the width test (2026-12-06, measured, not adopted): of the merged "
        "block's remaining misses, three low buildings (2.2-2.3 m high, 12.6-24.5 m2 by convex hull, "
        "151-326 points, 72-74 % planar) are dropped by the width test (sqrt(12 l_min) of the segment's "
        "core: 2.35 / 2.83 / 3.00 m, rims not in the core), not by the area test (the local-density area "
        "is within 0.85-1.47x the hull area for 80 % of the block's segments; a hull-area test kept the "
        "same segments). min_roof_width 2.8 m (legal vehicle width 2.55 m): AHN3 0.9498 -> 0.9612, "
        "77055_627760 0.9387 -> 0.9460, merged 0.9418 -> 0.9428, but the thinned block 0.9064 -> 0.9029, "
        "merged at 5 points/m2 0.9118 -> 0.9051, synthetic 300 k seed 2 0.9691 -> 0.9662 (its garden "
        "sheds, 2.7-3.0 m wide and class 1 by the small-structure convention, pass); 2.6 m also cost "
        "seeds 6 and 8 0.003. The width test cannot tell a 3 m garage from a 3 m shed; left at 3 m.",
        "Roof under crowns, covered completion (2026-12-06, `roof_filter.covered_clearance` 1 m): in "
        "synthetic 300 k seed 9 (the matrix's lowest, 0.9453), 1,213 of 1,642 missed roof points were "
        "covered (overtopped in their plan cell by more than 1 m), their kNN 80 % roof (median), 0.9 m "
        "(median) from a kept roof, but rough (curvature median 0.064: crown points in their "
        "neighbourhoods) and crown-coloured: no seed, no growth, beyond edge growth's three rounds (six "
        "or twelve rounds along local planes crept into the crowns, c052c91's note). After edge growth, "
        "covered points now join a kept roof round by round through the kNN graph when they lie on the "
        "roof segment's fitted plane (least squares over its points before edge growth, edge_noise "
        "sigmas; segments whose plane RMS exceeds twice the noise grow nothing), with edge_support of "
        "their neighbours on it and at most a fifth under it (a roof hides what is below it; a crown's "
        "slab crossing the plane has half the crown beneath it: without that rule one crown point more "
        "joined in tests/test_roof_growing.py's crown over an eave). Kappa: synthetic medians 300 k / 1 M "
        "/ 4 M 0.9688 / 0.9650 / 0.9654 -> 0.9695 / 0.9662 / 0.9667, worst 0.9453 / 0.9521 / 0.9628 -> "
        "0.9497 / 0.9531 / 0.9643 (seed 9 still under 0.95: with the support test alone 0.9505, with no "
        "point under the plane allowed 0.9467); every real file within 0.0003 (merged 0.9418, AHN3 0.9498 "
        "-> 0.9499, 77060_627760 0.9191). Held out: synthetic 300 k seeds 10-14 0.9625 / 0.9611 / 0.9636 "
        "/ 0.9658 / 0.9544 -> 0.9658 / 0.9636 / 0.9641 / 0.9674 / 0.9594, colourless seeds 4 / 7 / 12 "
        "within 0.0001. Cost at 4 M: 0.2-0.5 s in roof_filter (242 k covered points wait; 18 rounds).",
        "Denser surveys (2026-12-06, issue 16's held-out densities; synthetic als-roof on one 100 m block, "
        "`synthetic.generate(..., density=)`, 3 cm height noise): at c5bcb13 kappa fell with density, seeds "
        "0-9 at 15 points/m2 (150 k) 0.96-0.98, at 40 (400 k) 0.9101 / 0.9556 / 0.8821 / 0.9363 / 0.8544 / "
        "0.9533 / 0.9434 / 0.8420 / 0.9232 / 0.9364, at 80 (800 k) 0.8572 / 0.8988 / 0.8652 / 0.9306 / 0.7978"
        " / 0.9292 / 0.9372 / 0.8359 / 0.9093 / 0.8622: whole low houses and roof parts lost (seed 0 at 80: "
        "208 k of the 250 k non-ground points failed the seeds' planarity, against 22 k of 47 k at 15), "
        "because curvature over k = 10 neighbours grows as (noise / neighbourhood radius)^2. Two changes: (1)"
        " `uniform_downsample` (hashed, `target_density: 30`) first in configs/roof_als.yaml, denser surveys "
        "thinned to 30 points/m2, the skipped points labelled by their nearest processed point, and the "
        "stages' spacings (`stages.base.survey_spacing`: r_max auto, edge growth, footprint cells, annex gap)"
        " taken at the kept density (`SAMPLED_SHARE`); (2) the low-and-rough test's planar bound is the "
        "seeds' median curvature where that exceeds a quarter of c_t (`roof_filter.low_planar_bound`; seed 4 "
        "at 40 points/m2: low houses with 10-14 % of their points under 0.005, the seeds' median 0.0076 "
        "against 0.0046 at 15). After: at 40 0.9745 / 0.9589 / 0.9628 / 0.9563 / 0.9760 / 0.9629 / 0.9652 / "
        "0.9674 / 0.9559 / 0.9518, at 80 0.9776 / 0.9600 / 0.9614 / 0.9541 / 0.9784 / 0.9612 / 0.9645 / "
        "0.9674 / 0.9608 / 0.9484. Each alone: the bound alone 0.9539-0.9792 at 40 but 0.8393-0.9621 at 80; "
        "the downsampling alone at 80, seeds 0-9, 0.8519-0.9689 (seeds 4 and 7 0.8519 / 0.8798: the bound's "
        "low houses). The target: 20 points/m2 cost the densest IGN tile (77050_627755, 35 points/m2 over all"
        " returns) 0.9279 -> 0.8692; 30 gives it 0.9389 and 77060_627755 (33) 0.9278 -> 0.9280; every other "
        "real row is not denser than 30 and its labels are unchanged, and so is the matrix at 15 (300 k seeds"
        " 0-9 the same kappa; the real files' seeds have median curvatures 0.0002-0.0047, under the bound's "
        "0.005). Chosen on the IGN tiles and synthetic seeds 0-2; seeds 3-9 were not looked at for the target"
        " (seed 4 was traced for the bound). A noise-derived target was measured and not adopted: plane "
        "residuals over 16 neighbours do not tell IGN's roofs from the synthetic's (median on truth roofs "
        "0.019-0.034 m against 0.025 m), though IGN's tiles at 22-35 points/m2 lose nothing at full density. "
        "Held out further (measured after the choice): 200 points/m2 (2 M points on the block, seed 0, UAV "
        "LiDAR's density) 0.6670 -> 0.9766.",
        "Other held-out looks of the synthetic suburb (2026-12-06, at b4683b3, 300 k seeds 0-2, nothing "
        "chosen on them): the whole cloud rotated by 30 / 45 degrees about its centre: kappa 0.9746 / 0.9613 "
        "/ 0.9699 -> 0.9732 / 0.9608 / 0.9697 and 0.9733 / 0.9583 / 0.9666, labels agreeing on 99.61-99.82 % "
        "(the footprint cells and the cloth's grid are axis-aligned; a rotation moves the roofs against them "
        "by a fraction of a cell). Gaussian height noise added to the scene's 3 cm: +2 cm 0.9690 / 0.9550 / "
        "0.9699, +4 cm 0.9621 / 0.9520 / 0.9222 (seed 2: low houses dropped by the low-and-rough test, whose "
        "bound rose to the seeds' median 0.0087 but whose roofs lie rougher than the seeds; with that test "
        "off 0.9691). The synthetic hedges are not separable from low roofs by planar share at any bound "
        "(0.04-0.72 against 0.00-0.94 of points under the seeds' median), so the test's noise behaviour is "
        "left as the real tiles set it. Without returns and colour (x, y, z only): IGN tiles 0.8621 / 0.8922 "
        "/ 0.9801 / 0.8883 / 0.9295 / 0.9204, merged 0.9205, AHN3 0.9574 (its truth counts the walls the "
        "returns cue keeps out); synthetic without colour 0.9590 / 0.9366 (seeds 0, 3).",
        "Hilly towns (2026-12-06, `accuracy.tilted`: the scene's heights raised by a grade along x, verticals"
        " kept): the roof config at 8ed8ad0 on 300 k seeds 0-2 at a 10 / 20 / 30 % grade: 0.9736 / 0.9731 / "
        "0.6756, 0.9609 / 0.9585 / 0.7124, 0.9696 / 0.9678 / 0.9646 (flat 0.9746 / 0.9613 / 0.9699); at 30 % "
        "planar hillside became roof (E2 14.0 and 8.6 %): the rigid cloth (rigidness 3) stayed more than the "
        "class threshold off the ground. `cloth_ground.slope_smooth: true` (the CSF package's bSloopSmooth, "
        "as the road config has it): 30 % 0.9528 / 0.9523 / 0.9668, held-out seeds 3-5 0.6779 / 0.9743 / "
        "0.7055 -> 0.9512 / 0.9762 / 0.9640; flat scenes and real files within 0.0015 (ign_870000 0.7670 -> "
        "0.7684, with its building 0.9515 -> 0.9523, the reviewed tile 0.9994 -> 0.9989, thinned 0.9954 -> "
        "0.9963, 77050_627760 0.9248 -> 0.9242, 77060_627760 0.9191 -> 0.9189, merged 0.9418 -> 0.9417, AHN3 "
        "0.9499 -> 0.9498; 300 k seeds 0-9 within 0.0007), 4 M seed 0 the same kappa, cloth_ground 0.53-0.77 "
        "s either way. Steeper, it still fails: 40 % 0.3794 / 0.7207 / 0.9169, 50 % 0.2157 / 0.2371 / 0.3129 "
        "(rigidness 3 is the urban setting; CSF's authors use 1 on steep slopes, where a rigid cloth's sag "
        "into large flat roofs is the risk; not measured).",
        "Rigidness from the terrain (2026-12-06, after the note above): the survey estimates carry "
        "`terrain_grade` (median grade between the lowest points of 10 m cells, each lowered to the lowest of"
        " its 5 x 5 cells so that houses and crowns filling cells do not raise it; real files 0.000-0.029, "
        "flat synthetic 300 k seeds 0-5 0.000-0.031, the same tilted 10 / 20 / 30 / 40 %: 0.03-0.10 / "
        "0.12-0.20 / 0.20-0.29 / 0.32-0.40), and configs/roof_als.yaml's cloth takes `rigidness: auto`: 1 "
        "(CSF's steep-slope setting) above `steep_grade` 0.15, else 3. Rigidness 1 everywhere was measured "
        "first: flat synthetic within 0.0002, but real flat tiles lost up to 0.0036 (77060_627760 0.9189 -> "
        "0.9153, merged 0.9417 -> 0.9410). With auto, seeds 0-5, kappa at 30 % 0.9735 / 0.9584 / 0.9680 / "
        "0.9582 / 0.9771 / 0.9693 (slope_smooth alone 0.9528 / 0.9523 / 0.9668 / 0.9512 / 0.9762 / 0.9640), "
        "at 40 % 0.9643 / 0.9080 / 0.9677 / 0.9584 / 0.9737 / 0.9677 (0.3794 / 0.7207 / 0.9169 for seeds 0-2 "
        "with rigidness 3), at 50 % still 0.6196 / 0.5995 / 0.7456 / 0.6087 / 0.6464 / 0.5937; every real "
        "file and the flat matrix read under 0.15 and keep rigidness 3 (labels as before). The 15 % sits "
        "between the flat and 30 % readings; 20 % scenes go either way, where both rigidities measured within"
        " 0.003.",
        "The low-and-rough test is the roof pipeline's most fragile rule (2026-12-06, at a137799, measured, "
        "not changed): flight-strip misalignment (half the points of one half of the scene raised by 3 / 6 / "
        "10 cm, as a second strip with an offset) on 300 k seeds 0-2: 0.9744 / 0.9738 / 0.9670, 0.9616 / "
        "0.9618 / 0.9318, 0.9699 / 0.9259 / 0.9168 (as delivered 0.9746 / 0.9620 / 0.9699); with "
        "`low_min_planar` 0: 0.9744 / 0.9738 / 0.9725, 0.9616 / 0.9618 / 0.9565, 0.9699 / 0.9688 / 0.9522; +4"
        " cm of height noise on seed 2 0.9222 against 0.9691 without it. Its gain on the real files: "
        "77060_627760 +0.0057, 77055_627760 +0.0004, merged +0.0009, every other row 0. Under noise and strip"
        " offsets all roofs lose planar points together: the median planar share of the judged segments over "
        "4.5 m (mostly roofs) fell from 0.56 / 0.70 (seeds 0 / 2) to 0.39 / 0.47 with +4 cm and to 0.36 / "
        "0.59 with a 6 cm strip offset (ign_870000: 0.93), so a test relative to that median (a low segment "
        "rough under a fraction of the high segments' share) would follow the survey; not built or measured "
        "on the real hedges yet.",
        "The low-and-rough test follows the survey's own roofs (2026-12-06, after the note above): "
        "`roof_filter.low_planar_reference` 0.55: low_min_planar scales by min(1, roof planar share / 0.55), "
        "the roof planar share being the point-weighted planar share (under the test's bound) of the kept "
        "segments over narrow_max_height, which the test itself does not judge. Measured shares: real files "
        "0.45-0.91 (merged block 0.55, the block the 15 % was set on), synthetic 300 k seeds 0-2 as delivered"
        " 0.50 / 0.70 / 0.53, with +4 cm of noise 0.25 / 0.40 / 0.27, with a 6 / 10 cm strip offset 0.33-0.49"
        " / 0.20-0.36. Kappa: every real file and 300 k seeds 0-9 as before; +4 cm noise seeds 0-2 0.9621 / "
        "0.9525 / 0.9221 -> 0.9739 / 0.9525 / 0.9685; strip offsets unchanged (seed 2 at 6 cm 0.9259, at 10 "
        "cm 0.9169: the offset half's low houses are rough against roofs that are mostly smooth; a local "
        "reference would be the next step). A point-weighted median over all segments over 4.5 m, kept or "
        "not, was no reference: on the colourless IGN tiles the crowns' segments outnumber the roofs "
        "(0.05-0.27).",
        "Very large flat buildings (2026-12-06; a plain test scene: flat or gently rolling ground with 3 cm "
        "noise and a 12 m high flat roof, walls sparse): a 60 x 40 m and a 150 x 100 m building in 300 m "
        "scenes at 15 points/m2 kept (kappa 0.9970 / 0.9995); a 250 x 150 m one (a logistics hall, a mall) "
        "went to ground whole at eb945c3: kappa 0.0285-0.0538 at 4-15 points/m2, 95.7-97.5 % of its roof "
        "classed ground (CSF's inverted cloth, rigidness 3 at 1 m, sinks into a pit that wide). Now "
        "cloth_ground lowers raised plateaus (roadx_ti.plateaus, `raised_plateaus`, default on): ground cut "
        "off from the ground around it by a step down of at least `plateau_step` 2 m (min_roof_height) on "
        "at least 75 % of its outline, with ground beside it (within the cloth's 30 m reach) on at least 75 "
        "% of the outline, gets the cloth of the plane fitted to the lower ground around it, and the points "
        "are classified against that. After, one run each (tests/test_plateaus.py has the 4 points/m2 "
        "case): 250 x 150 m at 4 / 8 / 15 points/m2 0.9996-0.9999, 200 x 130 m (the cloth sank there too) "
        "0.9998, 400 x 200 m at 3 points/m2 (8 m high) 0.9993, 4 m high 0.9989, on an 8 % / 20 % grade "
        "0.9996 / 0.9993, with a 60 x 40 m tower on it 0.9995, reaching the data's edge on one side 0.9996, "
        "with a 100 x 50 m courtyard 0.9997 (there the cloth did not sink). An earth platform 6 m high with "
        "1:2 banks (no building) stays ground, and so do (tests) a terrace behind a retaining wall across "
        "the scene, a 6 m cutting, a hill and a sunken courtyard. No plateau is found on any real file or "
        "synthetic scene of the report (their labels unchanged). Left: in tiled runs a hall cut by the "
        "window's edge is judged on what the window holds (buffers 30 m).",
        "Steep terrain (2026-12-06, issue 16's held-out terrain): at f41bb5a a town on a 50 % grade scored "
        "0.6196 / 0.5995 / 0.7456 (300 k seeds 0-2): even the steep-slope cloth (rigidness 1, slope_smooth) "
        "stayed off the hillside, whose planar parts passed for roof. Two changes. (1) terrain_grade leaves "
        "out each 10 m cell's lowest 1 % (low noise): the synthetic scenes' 80-130 class 7 points, each "
        "spread over 5 x 5 cells by the lowering, made a 40 % ridge read 0.11-0.24 and a 30 % grade "
        "0.18-0.35 (now 0.34-0.38 and 0.30-0.36). (2) cloth_ground `detrend: auto` "
        "(roadx_ti.terrain_trend): where terrain_grade exceeds steep_grade (15 %) the cloth runs on heights "
        "above the terrain's trend (10 m cell lows, empty cells filled from the nearest, grey opening over "
        "5 x 5 cells, Gaussian of 1.5 cells, the lattice padded by point reflection so a plane stays a "
        "plane to the edges; a second pass on the heights above the first takes out the cells' downhill "
        "bias) and the trend is added back to the cloth. Flat scenes and every real file read under 15 % "
        "and are unchanged. After, 300 k seeds 0-2: 30 % 0.9735 / 0.9584 / 0.9680 -> 0.9749 / 0.9592 / "
        "0.9685, 50 % 0.9742 / 0.9594 / 0.9663; other terrain shapes, seeds 0 / 1 before -> after: a valley "
        "of 50 % sides 0.1339 / 0.0988 -> 0.9742 / 0.9600, a 40 % ridge 0.6909 / 0.7420 -> 0.9659 / 0.9365 "
        "(the opening cuts the crest), waves of 15 m amplitude, 190 m long, 0.9106 / 0.7288 -> 0.9746 / 0.9596, a "
        "bowl (up to about 80 % at its corners) 0.3987 / 0.1711 -> 0.9742 / 0.9582, 45 % diagonally 0.9640 "
        "/ 0.9507 -> 0.9752 / 0.9588. Held out (not looked at while building it): seeds 3-6 at 50 % 0.9593 "
        "/ 0.9768 / 0.9669 / 0.9678 and at 60 % 0.9615 / 0.9778 / 0.9678 / 0.9685; seeds 2 / 3 valley "
        "0.9637 / 0.9574, ridge 0.9627 / 0.9507, waves 0.9642 / 0.9573, bowl 0.9615 / 0.9430, diagonal "
        "0.9696 / 0.9592. configs/ground.yaml (class 2 kappa, seeds 0-2): 0.57-0.69 at 30, 40 and 50 % with "
        "the trend, 0.58-0.68 / 0.55-0.65 / 0.46-0.58 without; counting roads and low vegetation as ground "
        "too the trend costs at 30 % (0.979-0.988 -> 0.950-0.969: the level cloth misses what it misses on "
        "flat ground, 0.842-0.968 there) and gains at 50 % (0.666-0.856 -> 0.949-0.969).",
        "Embankments and dikes (2026-12-06, at fb6058e; a test scene of flat ground, one 12 x 10 m house "
        "and a ridge across 200 m at 10 points/m2): a dike with banks of 1:2 (5 / 10 / 20 m crown, 4-8 m "
        "high) stays ground, but a railway-like embankment with 1:1.5 banks (10 m crown, 7 m high) or a 1:1 "
        "one (3 m, 5 m) was taken as roof whole (55,829 of 61,915 / 22,855 of 25,931 points; kappa of the "
        "scene 0.035 / 0.088): a ridge that narrow and steep is a trench in the cloth's inverted frame that "
        "the stiff cloth does not follow into, so crown and banks stand metres over it, planar and wide. "
        "roof_filter's at-grade test (`max_at_grade_outline` 0.5, `at_grade_height` 1 m): a segment whose "
        "outline cells (plan cells of its non-vertical points, |n_z| >= 0.5, sized to hold 8 points on "
        "average, lacking a 4-neighbour) have their lowest point under 1 m over the ground on more than "
        "half of them is terrain; a roof's outline is its eaves. Measured before choosing the 0.5: the "
        "dikes 0.84 / 0.94, kept true roofs of every real file at hand 0-0.13 (77060_627760: a 63-point "
        "segment at 0.125), synthetic roofs flat and on 30 / 50 % grades 0-0.02. After: 0 embankment points "
        "as roof, house kappa 1.0; an overpass on embankments with abutments (12 m deck 7 m up, 1:2 banks) "
        "0.5576 -> 0.9503 (its bank slices by the abutments were roof); every real file and synthetic row "
        "of the report unchanged; other terrain shapes (seeds 0 / 1): a 40 % ridge 0.9659 / 0.9365 -> "
        "0.9659 / 0.9558 (crest segments the detrended cloth left), a valley 0.9742 / 0.9600 -> 0.9742 / "
        "0.9590; large halls, roof panels, sawtooth roofs and roof units unchanged.",
        "Terraces and halls on slopes (2026-12-06, at 91c1a17; test scenes of terraces behind vertical "
        "retaining walls, 10 points/m2, four 12 x 10 m houses, 6 m high, each on a terrace): walls 3 m "
        "every 30 m, 4 m every 20 m, 6 m every 40 m: kappa 1.0 / 1.0 / 0.9993; 2.5 m every 12 m (median "
        "grade 0.25, so the cloth runs on the trend) 0.2373: the top terrace, at the survey's edge, stepped "
        "down on every side that had ground within the plateau test's 30 m (its uphill side is the data's "
        "edge, 12 m from the terrace below), was taken for a raised plateau and lowered, and 28,887 of its "
        "points became roof. Now an outline cell counts only with points beside it outside the plateau "
        "(within 2 cells: a wall, the cloth's ring, ground); the survey's edge is no evidence: 0.9989, "
        "every hall of the note above still found (250 x 150 m at the data's edge too). Left: the trend "
        "(opened over 50 m) rises onto a flat roof wider than that, so a 250 x 150 m hall on a 20 % grade "
        "scores 0.4688 with the detrended cloth (0.9993 with the steep-slope cloth alone, which the plateau "
        "test completes). Gating the trend at a median grade of 30 % kept the hall but lost a bowl and "
        "waves (seeds 0 / 1: 0.3987 / 0.1711 and 0.9248 / 0.8707, median grades under 30 %, steep parts); a "
        "90th-percentile gate reads 2.45 on sample_c (one large building fills its cells), so it would "
        "detrend flat towns with large blocks. detrend_grade stays 0.15 (option). On a levelled platform "
        "(the hall 12 m over a pad cut into the slope, 10 m round it, 1:1.5 banks) halls of 250 x 150 and "
        "120 x 80 m on 15 / 20 / 30 % grades score 0.9995-1.0 (the plateau test finds them on the restored "
        "cloth): the loss needs a hall standing on the slope itself.",
        "Noisy surveys (2026-12-06, at 4dffa58; Gaussian height noise added to whole scenes): synthetic 300 "
        "k seeds 0-2 at +4 / +7 / +10 cm 0.9739 / 0.9091 / 0.4032, 0.9525 / 0.9251 / 0.7784, 0.9685 / "
        "0.8703 / 0.4448 (E1 up to 71 %): curvature over k = 10 neighbours grows as (noise / their "
        "radius)^2 and roofs had no seeds. The survey's height_noise_m cannot tell: wooded IGN tiles read "
        "4-8 cm with their foliage, even on their flattest tenth; their ground reads 0.7-1.9 cm (AHN3 1.0, "
        "the synthetic 2.1, +4 / +7 / +10 cm 3.9 / 6.1 / 8.1, sample_c at 2.3 points/m2 4.4). Now "
        "cloth_ground measures the noise of its ground points (`ground_noise_m`, where the survey's "
        "estimate exceeds 3 cm) and roof_seeds (`denoise: auto`, `denoise_above` 3.5 cm) computes the "
        "features on heights moved onto the least-squares plane of k = 2 (noise / 2.5 cm)^2 neighbours "
        "(kernels.features.plane_heights; walls keep theirs). After: +4 / +7 / +10 cm seeds 0-2 0.9756 / "
        "0.9754 / 0.9742, 0.9604 / 0.9578 / 0.9540, 0.9655 / 0.9652 / 0.9621; held out seeds 3-5 at +4 cm "
        "0.9432 / 0.9270 / 0.9601 -> 0.9606 / 0.9787 / 0.9685, at +7 / +10 cm 0.9585 / 0.9605, 0.9792 / "
        "0.9780, 0.9658 / 0.9632. Real files with +8 cm of noise, without / with: IGN merged 0.3774 / "
        "0.8217, AHN3 0.9057 / 0.9419, the reviewed tile 0.8925 / 0.9463, ign_870000 with its building "
        "0.9461 / 0.9349 (+5 cm: ground under 3.5 cm, not denoised). Every real file and synthetic row of "
        "the report unchanged (none denoised). Measured, not adopted: denoising on the survey-wide estimate "
        "(gate 4 cm) took the IGN tiles' foliage into planes: merged 0.9417 -> 0.8237; the gate per 25 m "
        "block of ground (flight strips that disagree are local): half a scene's points 10 cm up, seeds 1 "
        "/ 2, 0.9318 / 0.9169 -> 0.9535 / 0.9391, at 6 cm unchanged, but +4 cm everywhere 0.9604 / 0.9655 "
        "-> 0.9546 / 0.9611 (blocks either side of the gate: patchy). Forced on, strip offsets of 6 / 10 "
        "cm score 0.960-0.966 on seeds 1-2 (0.9169-0.9618 without), the clean scenes 0.004 lower. Report "
        "rows: 300 k with 7 cm more height noise, seeds 0-2 (0.9755 / 0.9571 / 0.9643; denoise off 0.8815 / "
        "0.9155 / 0.8704).",
        "Half density on the IGN tile of tests/test_roof_invariance.py (77055_627760, every other point of a "
        "seeded permutation; 2026-12-06 at 51602af): labels agree on 96.22 %, kappa 0.9387 -> 0.8985; 1,099 "
        "points are roof only at half density (750 class 5, 32 class 4, 317 roof), 47 only at full. Not the "
        "curvature: the largest piece (500 points, 41 % roof, 3.3 m over the ground) has median curvature "
        "0.0046 at full density and 0.0047 at half (85 / 82 % under 0.02). At full density roof_growing "
        "leaves it in two segments (398 and 326 points) that each fail the width test (under 3 m wide and 4.5"
        " m high); at half density it grows as one segment of 395 points that passes: the kNN graph reaches "
        "sqrt 2 further in metres and joins what full density keeps apart. The next pieces alike (168 points "
        "failing area, width and the low-and-rough test at full density; 136 passing at half). A growth reach"
        " in metres rather than in neighbours would keep them apart, but reaches follow the measured spacing "
        "on purpose (sparse surveys lose narrow roofs otherwise: r_max's note). Sparser than the report's "
        "rows (accuracy.thin_to_density): at 1 / 0.5 points/m2 AHN3 0.8328 / 0.7907, the IGN block 0.8857 / "
        "0.8488, the reviewed tile 0.9583 / 0.9333: type I grows, nothing breaks.",
        "Rim colour (2026-12-07, `roof_growing.edge_colour_cue`, default false): in synthetic 300 k seed 9 "
        "(0.9497, the matrix's lowest) 1,142 of the 1,377 missed roof points that reached the roof stages "
        "were vegetation-coloured: 403 of 565 wall points, 426 of 461 under crowns and 313 of 351 open rim "
        "points (0.43 m median from a kept roof, in no segment). The generator's orthophoto leans each "
        "building, as any orthophoto that is not a true one does, so a rim's points take the colour of the "
        "lawn or crown beside the roof, and the colour cue kept them off edge completion, whose plane test "
        "(the roof's own plane within the height noise) keeps crowns off by itself. Edge completion now "
        "ignores colour (foliage returns and isolation still count; growth, annex and footprint rules keep "
        "the colour cue): every synthetic row up, 300 k seeds 0-9 by 0.0009-0.0046 (seed 9 0.9497 -> "
        "0.9543), 1 M by 0.0019-0.0028 (worst 0.9531 -> 0.9554), 4 M by 0.0018-0.0026, the graded, noisier "
        "and denser rows by 0.0002-0.0029; held out (not used to choose): 300 k seeds 10-29 all 20 up "
        "(mean 0.9672 -> 0.9695, +0.0013 to +0.0033) and 100 m blocks at 15 / 40 / 80 points/m2 seeds 3-6 "
        "all 12 up (+0.0005 to +0.0044), 300 k seeds 3-5 with 4 cm more height noise or on a 10 / 20 % "
        "grade all 9 up (+0.0010 to +0.0036). The real files with colour: ign_870000 0.7684 -> 0.7678, "
        "with its building 0.9523 -> 0.9517, the reviewed tile 0.9989 -> 0.9991, it thinned to 3 points/m2 "
        "0.9963 -> 0.9945 (type II 0.07 -> 0.11 %: a few points), sample_c 0.9200 unchanged; files without "
        "colour do not move. With the cue (`edge_colour_cue: true`, the behaviour before) covered points "
        "stay exempt from it (covered_clearance).",
        "Curved and angled segments (2026-12-07, on 55c231b; `roof_filter.width_measure`, default bent): "
        "the width test's covariance width is exact for a straight strip but reads a hedge along a bend "
        "or round a corner several times its width (the half-density run of "
        "tests/test_roof_invariance.py's tile grew one curved hedge into a 395-point segment 9.98 m "
        "\"wide\", 47 % roof). The inscribed width (twice the largest distance from the segment's plan "
        "footprint, on cells of half its own point spacing, closed over a spacing and with its holes "
        "filled, to its outline) reads strips 1.75-6 m wide within 0.1-0.3 m at 2-17 points/m2 whatever "
        "their shape. Taken where it is under 0.6 of the covariance width (a straight strip reads "
        "0.9-1.0, a disc 1.15): the six IGN tiles, their merged block, AHN3, ign_870000 and the reviewed "
        "tile at full density, AHN3 and the reviewed tile thinned to 3 points/m2, sample_c and every "
        "synthetic row of the evaluation script unchanged; the merged IGN block thinned to 3 points/m2 "
        "0.9065 -> 0.9191; held out (not looked at while choosing): the merged block at 10 / 5 / 2 "
        "points/m2 0.9214 / 0.9118 / 0.8934 -> 0.9263 / 0.9146 / 0.8948, AHN3 and ign_870000 at those "
        "densities and synthetic 300 k seeds 10-17 unchanged; in `accuracy --task roof` four of the 40 "
        "synthetic rows lose 0.0002-0.0013 (1 M seeds 6 / 8 0.9714 / 0.9653 -> 0.9705 / 0.9640, 4 M seeds"
        " 2 / 6). Not adopted: the inscribed width for every low segment (`inscribed`): the same real "
        "gains and half-density agreement on 77055_627760 96.22 -> 96.69 %, but small synthetic roofs "
        "3.0-3.7 m wide read 2.3-2.9 m (their segments lack the rims edge growth adds later; seed 9 "
        "0.9543 -> 0.9465, 800 k seed 0 0.9779 -> 0.9750); the survey's spacing estimate as the cell "
        "instead of each segment's own (thinned files: the closing then bridges nothing and every roof "
        "reads narrow; the reviewed tile thinned 0.9945 -> 0). The tile's half-density agreement stays "
        "96.22 % (its flips are straight hedge pieces at the area and width thresholds, see the note "
        "above).",
        "Hedges joined to low roofs, two shape rules measured and not adopted (2026-12-07, at 4959d9c; "
        "the kept segments under narrow_max_height of the six IGN tiles, the merged and thinned blocks, "
        "the reviewed tile, ign_870000, sample_c, AHN3 and synthetic 300 k seeds 0-2 and 9, scored point "
        "by point against the truth): (1) parts of a segment's plan footprint that an opening by a disc "
        "of min_roof_width leaves out (cells of half the spacing, components of at least 3 m2): every "
        "piece cut on the real files was roof (truth share 0.95-1.00: narrow wings, porches and eaves of "
        "garages), 0.97-1.00 on the synthetic ones, and the half-density tile 77055_627760, whose flip is"
        " a hedge grown into a 2.2 m shed roof, has no such piece (the union is a blob, not a roof with "
        "an arm); (2) points more than max(0.3 m, 6 sigma) above the segment's robust plane (least "
        "squares, refitted 4 times on |r| < 3 MAD sigmas): only 15 and 45 points, all not roof, on two "
        "IGN tiles; the 829 + 322 point roof-and-hedge segment of 77060_627760 has its hedge points at "
        "-0.29 / 0.05 / 0.88 m from the roof plane (5th / 50th / 95th percentile) and the roof's own "
        "points down to -0.47 m, so no height cut separates them (their multi-return shares 0.39 against "
        "0.19, curvature 0.0097 against 0.0049: no clean cue either). Tile 77060_627760 stays at 0.9189.",
    ],
}


# the road matrix (issue: adaptive road extraction): every seed at every size, one larger scene
ROAD_SIZES = (300_000, 1_000_000, 4_000_000)
ROAD_SEEDS = tuple(range(10))
ROAD_LARGE = (16_000_000, 0)        # points, seed
ROOF_SIZES = (300_000, 1_000_000, 4_000_000)
ROOF_SEEDS = tuple(range(10))
PICTURED_SEEDS = (0,)               # PNGs of these seeds only (31 pictures would be noise)


def _size_name(points: int) -> str:
    # exact: 1,500 points is "1.5 k" (it was "1 k", the name of another scene)
    for unit, name in ((1_000_000, "M"), (1000, "k")):
        if points >= unit:
            return f"{points / unit:g} {name}" if points % (unit // 1000) == 0 else f"{points:,}"
    return f"{points:,}"


def road_datasets(sizes=ROAD_SIZES, seeds=ROAD_SEEDS, large=ROAD_LARGE):
    """The road matrix: (name, loader, truth classes, config, group, picture?) rows."""
    from roadx_ti import io, synthetic

    rows = []
    for points in sizes:
        for seed in seeds:
            rows.append((f"synthetic uav-road {_size_name(points)} seed {seed}",
                         lambda n=points, s=seed: synthetic.generate("uav-road", n, s), [11], "road_uav.yaml",
                         _size_name(points), seed in PICTURED_SEEDS))
    if large:
        n, seed = large
        rows.append((f"synthetic uav-road {_size_name(n)} seed {seed}", lambda: synthetic.generate("uav-road", n, seed),
                     [11], "road_uav.yaml", _size_name(n), True))
    rows.append(("AHN3 ahn3_2386_9702_roads (no colour)",
                 lambda: io.read(SHARED_DATA / "road" / "ahn3_2386_9702_roads.laz"), [11], "road_uav.yaml",
                 "AHN3", True))
    return rows


def roof_datasets(sizes=ROOF_SIZES, seeds=ROOF_SEEDS):
    """The roof rows: (name, loader, truth classes, config, group, picture?); the group of a
    synthetic scene is its size ('300 k', ...), None for real data; pictures of real data and of
    the synthetic seed 0 only."""
    rows = []
    for name, load, classes, cfg in datasets("roof", sizes, seeds):
        synthetic_scene = name.startswith("synthetic als-roof ")
        group = name[len("synthetic als-roof "):].rsplit(" seed ", 1)[0] if synthetic_scene else None
        rows.append((name, load, classes, cfg, group, not synthetic_scene or name.endswith(" seed 0")))
    return rows


def datasets(task: str, sizes=ROOF_SIZES, seeds=ROOF_SEEDS):
    """(name, loader, truth classes, config file) per dataset of the task; the roof task's synthetic
    als-roof scenes: every seed at every size (the roof matrix)."""
    from roadx_ti import io, synthetic

    rows = []
    if task == "road":
        rows = [r[:4] for r in road_datasets()]
    else:
        rows.append(("IGN ign_870000_6618000",
                     lambda: io.read(SHARED_DATA / "roof" / "ign_870000_6618000.las"), [6], "roof_als.yaml"))
        rows.append(("IGN ign_870000_6618000, its unlabelled building as roof",
                     lambda: with_unlabelled_building(io.read(SHARED_DATA / "roof" / "ign_870000_6618000.las")),
                     [6], "roof_als.yaml"))
        rows.append(("IGN ign_874000_6617000_reviewed",
                     lambda: io.read(SHARED_DATA / "roof" / "ign_874000_6617000_reviewed.laz"), [19], "roof_als.yaml"))
        # the six adjacent IGN tiles: real roofs without colour (returns are the vegetation cue),
        # each alone (buildings cut by its edge count), then as the one block they form
        tiles = sorted((SHARED_DATA / "tiles").glob("*.laz"))
        for path in tiles:
            rows.append((f"IGN tile {path.stem.split('_LA93')[0]} (no colour)",
                         lambda p=path: io.read(p), [6], "roof_als.yaml"))
        if tiles:
            rows.append((f"IGN tiles merged: the {len(tiles)} above as one block (no colour)",
                         lambda: _merged(tiles), [6], "roof_als.yaml"))
        # sparse ALS (national surveys: 2-5 points/m2) from the same real tiles, scored on the kept points
        if tiles:
            rows.append((f"IGN tiles merged, thinned to {THIN_DENSITY:g} points/m2 (no colour)",
                         lambda: thin_to_density(_merged(tiles), THIN_DENSITY), [6], "roof_als.yaml"))
        rows.append((f"IGN ign_874000_6617000_reviewed thinned to {THIN_DENSITY:g} points/m2",
                     lambda: thin_to_density(io.read(SHARED_DATA / "roof" / "ign_874000_6617000_reviewed.laz"),
                                             THIN_DENSITY), [19], "roof_als.yaml"))
        # sparse real ALS: one large building at 2.3 points/m2 (PDAL's test data)
        rows.append(("sample_c (2.3 points/m2)", lambda: io.read(SHARED_DATA / "smoke" / "sample_c.las"), [6],
                     "roof_als.yaml"))
        # another country and labeller (AHN3, Amsterdam: class 6 is the building, walls included),
        # scored as it comes; no roof setting was chosen on it
        rows.append(("AHN3 ahn3_2386_9702 (Netherlands, no colour)",
                     lambda: io.read(SHARED_DATA / "road" / "ahn3_2386_9702_roads.laz"), [6], "roof_als.yaml"))
        rows.append((f"AHN3 ahn3_2386_9702 thinned to {THIN_DENSITY:g} points/m2 (no colour)",
                     lambda: thin_to_density(io.read(SHARED_DATA / "road" / "ahn3_2386_9702_roads.laz"), THIN_DENSITY),
                     [6], "roof_als.yaml"))
        for points in sizes:
            for seed in seeds:
                rows.append((f"synthetic als-roof {_size_name(points)} seed {seed}",
                             lambda n=points, s=seed: synthetic.generate("als-roof", n, s), [6], "roof_als.yaml"))
        # hilly towns: the matrix's 300 k scenes on a hillside (the whole scene tilted)
        for grade in TILT_GRADES:
            for seed in TILTED_ROOF_SEEDS:
                rows.append((f"synthetic als-roof 300 k on a {100 * grade:g} % grade seed {seed}",
                             lambda s=seed, g=grade: tilted(synthetic.generate("als-roof", 300_000, s), g),
                             [6], "roof_als.yaml"))
        # noisier sensors: the matrix's 300 k scenes with NOISY_ROOF_SIGMA m more height noise
        for seed in NOISY_ROOF_SEEDS:
            rows.append((f"synthetic als-roof 300 k with {100 * NOISY_ROOF_SIGMA:g} cm more height noise seed {seed}",
                         lambda s=seed: noisier(synthetic.generate("als-roof", 300_000, s), NOISY_ROOF_SIGMA, s),
                         [6], "roof_als.yaml"))
        # denser surveys than the matrix's 15 points/m2 (one block of 100 m, the same layout at each)
        for points, per_m2 in DENSE_ROOF_SCENES:
            for seed in DENSE_ROOF_SEEDS:
                rows.append((f"synthetic als-roof {_size_name(points)} at {per_m2:g} points/m2 seed {seed}",
                             lambda n=points, d=per_m2, s=seed: synthetic.generate("als-roof", n, s, density=d),
                             [6], "roof_als.yaml"))
    return rows


# grades (rise over run, along x) and seeds of the tilted synthetic roof rows
TILT_GRADES = (0.3, 0.5)
TILTED_ROOF_SEEDS = (0, 1, 2)
# Gaussian height noise (m) added to the noisy synthetic roof rows, and their seeds
NOISY_ROOF_SIGMA = 0.07
NOISY_ROOF_SEEDS = (0, 1, 2)


def noisier(cloud, sigma: float, seed: int):
    """``cloud`` with Gaussian height noise of ``sigma`` m added (seeded), as an older sensor or
    image matching would deliver it."""
    from dataclasses import replace

    xyz = cloud.xyz.copy()
    xyz[:, 2] += np.random.default_rng(1000 + seed).normal(0.0, sigma, cloud.n).astype(np.float32)
    return replace(cloud, xyz=xyz)


def tilted(cloud, grade: float):
    """``cloud`` on a hillside: heights raised by ``grade`` x the distance along x from its
    westmost point (verticals stay vertical, roofs keep their shapes on a slope)."""
    from dataclasses import replace

    xyz = cloud.xyz.copy()
    xyz[:, 2] += np.float32(grade) * (xyz[:, 0] - xyz[:, 0].min())
    return replace(cloud, xyz=xyz)


# (points, points per m2) of the dense synthetic roof rows, and their seeds
DENSE_ROOF_SCENES = ((400_000, 40.0), (800_000, 80.0))
DENSE_ROOF_SEEDS = (0, 1, 2)


THIN_DENSITY = 3.0      # points per m2 of the thinned real tiles

# ign_870000_6618000's gabled building that its truth leaves in class 1 (the notes; the RGB shows its
# grey roof): world x / y box of its roof and walls, read off the cloud (x 870214.0-870230.6,
# y 6617089.4-6617106.0; nothing but class 1 lies in it). Issue 16's acceptance scores the file with
# that building as roof.
IGN_870000_BUILDING_BOX = (870214.0, 870230.6, 6617089.4, 6617106.0)
IGN_870000_BUILDING_MIN_HEIGHT = 2.0     # m above the box's lowest point: roof and walls, not the ground


def with_unlabelled_building(cloud):
    """ign_870000_6618000 with its unlabelled building's points (class 1 in the box, more than 2 m
    above the box's lowest point: 2,698 points) in class 6, the truth amended; the pipeline does
    not read input classes."""
    from dataclasses import replace

    xyz = cloud.world_xyz()
    x0, x1, y0, y1 = IGN_870000_BUILDING_BOX
    box = (xyz[:, 0] > x0) & (xyz[:, 0] < x1) & (xyz[:, 1] > y0) & (xyz[:, 1] < y1)
    if not box.any():
        return cloud
    building = box & (cloud.classification == 1) & (xyz[:, 2] > xyz[box, 2].min() + IGN_870000_BUILDING_MIN_HEIGHT)
    return replace(cloud, classification=np.where(building, np.uint8(6), cloud.classification).astype(np.uint8))


def thin_to_density(cloud, per_m2: float):
    """A deterministic, spatially uniform thinning of ``cloud`` to about ``per_m2`` points per m2
    of occupied plan area (roadx_ti.estimates.occupied_area): a point is kept when a hash of its
    world coordinates in centimetres falls below per_m2 / density, so the kept set does not depend
    on the points' order. The cloud itself when it is not denser than that."""
    from roadx_ti.estimates import occupied_area
    from roadx_ti.stages.downsample import hash_keys

    density = cloud.n / max(occupied_area(cloud.xyz[:, :2]), 1e-9)
    if density <= per_m2:
        return cloud
    q = np.round((cloud.xyz.astype(np.float64) + cloud.origin) * 100).astype(np.int64).astype(np.uint64)
    h = hash_keys(q)
    keep = (h >> np.uint64(11)).astype(np.float64) / 2.0 ** 53 < per_m2 / density
    return cloud.subset(np.flatnonzero(keep))


def _merged(paths):
    """One cloud of adjacent files (a common local origin: the floor of their lowest corner)."""
    from roadx_ti import io
    from roadx_ti.tiling import catalog, concat_clouds
    from roadx_ti.tiling.plan import with_points

    files = with_points(catalog(paths))
    origin = np.floor([min(f.bounds[0] for f in files), min(f.bounds[1] for f in files),
                       min(f.z_range[0] for f in files)])
    return concat_clouds([io.read(f.path, origin=origin) for f in files], origin)


def evaluate(task: str, out: Path, rows=None) -> list[dict]:
    from roadx_ti import config, metrics, pipelines
    from roadx_ti.stages.base import StageContext

    target = config.PIPELINE_TARGET[task]
    results = []
    if rows is None:
        rows = road_datasets() if task == "road" else roof_datasets()
    for name, load, truth_classes, cfg_name, group, picture in rows:
        try:
            cloud = load()
        except FileNotFoundError as exc:
            log.warning("skipping %s: %s", name, exc)
            continue
        except Exception as exc:  # io.InputError for a missing shared folder
            log.warning("skipping %s: %s", name, exc)
            continue
        cfg = config.load(REPO / "configs" / cfg_name)
        truth = metrics.class_mask(cloud.classification, truth_classes)
        t0 = time.perf_counter()
        result = pipelines.run(cloud, pipelines.build_stages(cfg.stage_list()),
                               ctx=StageContext(seed=cfg.seed, log=log), truth=truth,
                               target_class=target)
        seconds = time.perf_counter() - t0
        predicted = result.classification == target
        row = {"dataset": name, "config": cfg_name, "points": cloud.n, "truth_classes": truth_classes,
               "seconds": round(seconds, 2), **metrics.scores(truth, predicted),
               "stages": [{k: s.get(k) for k in ("stage", "points_in", "points_out", "removed_target",
                                                  "removed_other", "unlabelled_target", "labelled_other",
                                                  "seconds", "info")} for s in result.stages],
               "group": group, "estimates": result.estimates,
               "stage_estimates": {s["stage"]: s["info"]["estimates"] for s in result.stages
                                   if isinstance(s.get("info"), dict) and "estimates" in s["info"]}}
        results.append(row)
        if picture:
            dataset_png(out, task, name, cloud, truth, predicted)
        log.info("%s: type I %.2f %%, type II %.2f %%, total %.2f %%, kappa %.4f (%.1f s)", name,
                 100 * row["type1"], 100 * row["type2"], 100 * row["total"], row["kappa"], seconds)
    return results


def dataset_png(out: Path, task: str, name: str, cloud, truth, predicted) -> Path:
    """The scene / truth / prediction / errors picture of one dataset: OUT/TASK_NAME.png."""
    from roadx_ti import report

    slug = "".join(c if c.isalnum() else "_" for c in name).strip("_")[:60]
    path = out / f"{task}_{slug}.png"
    report.top_view_png(path, cloud, predicted, truth=truth, target=task, title=f"{task}: {name}")
    return path


def _pct(v):
    return f"{100 * v:.2f} %" if isinstance(v, float) else str(v)


def _stage_counts(s: dict) -> str:
    text = f"{s['stage']} {s.get('removed_target', 0) or 0:,} / {s.get('removed_other', 0) or 0:,}"
    if s.get("unlabelled_target") is not None:
        text += f" (missed {s['unlabelled_target']:,} / wrongly labelled {s['labelled_other']:,})"
    return text


def produced_line(produced: dict) -> str:
    """The report's provenance: one command and date, or each task's when a run of one task kept
    the other's rows from the earlier accuracy.json."""
    sources = list(dict.fromkeys((p["command"], p.get("date")) for p in produced.values()))
    if len(sources) == 1:
        command, date = sources[0]
        return f"Produced by `{command}` on {date}." if date else f"Produced by `{command}`."
    parts = [f"the {task} section by `{p['command']}`" + (f" on {p['date']}" if p.get("date") else "")
             for task, p in produced.items()]
    return ("Produced in parts (a run of one task keeps the other's rows from accuracy.json): "
            + "; ".join(parts) + ".")


def previous_results(path: Path) -> dict:
    """{task: (rows, {"command", "date"})} of an earlier accuracy.json (none when it is absent or
    unreadable); a file from before per-task provenance gives its one command to every task."""
    import json

    try:
        data = json.loads(Path(path).read_text())
        results = data["results"]
        produced = data.get("produced") or {task: {"command": data["command"], "date": None} for task in results}
        return {task: (rows, produced[task]) for task, rows in results.items() if task in produced}
    except (OSError, ValueError, KeyError, TypeError):
        return {}


def merge_with_previous(results: dict, produced: dict, previous: dict):
    """This run's tasks plus the other tasks' rows and provenance from ``previous``
    (previous_results), in the report's order (road, then roof)."""
    merged, sources = {}, {}
    for task in ("road", "roof"):
        if task in results:
            merged[task], sources[task] = results[task], produced[task]
        elif task in previous:
            merged[task], sources[task] = previous[task]
    return merged, sources


def render(task_results: dict, command) -> str:
    """``command``: the command line of the run, or {task: {"command", "date"}} (produced_line)."""
    if isinstance(command, str):
        command = {task: {"command": command, "date": time.strftime('%Y-%m-%d')} for task in task_results}
    lines = ["# Accuracy", "", produced_line(command), ""]
    for task, rows in task_results.items():
        what = "road surface (class 11)" if task == "road" else "building roofs (class 6 / 19)"
        lines += [f"## {task.capitalize()} pipeline: {what}", "",
                  "| dataset | config | points | type I | type II | total | kappa | seconds |",
                  "|---|---|---:|---:|---:|---:|---:|---:|"]
        for r in rows:
            lines.append(f"| {r['dataset']} | {r['config']} | {r['points']:,} | {_pct(r['type1'])} | "
                         f"{_pct(r['type2'])} | {_pct(r['total'])} | {r['kappa']:.4f} | {r['seconds']} |")
        for label, ref in REFERENCE_ROWS[task]:
            lines.append(f"| *{label}* | | | {_pct(ref.get('type1', ''))} | {_pct(ref.get('type2', ''))} | "
                         f"{_pct(ref.get('total', ''))} | {ref.get('kappa', '')} | |")
        groups = [g for g in dict.fromkeys(r.get("group") for r in rows) if g]
        if task == "road" and groups:
            lines += ["", "Per group: median and worst type I / type II (the road issue's bounds: every scene "
                      "E1 <= 5 %, E2 <= 3 %; medians E1 <= 2 %, E2 <= 1 %; AHN3 E1 and E2 <= 10 %):", "",
                      "| group | scenes | median E1 | median E2 | worst E1 | worst E2 |", "|---|---:|---:|---:|---:|---:|"]
            for g in groups + ["all synthetic"]:
                sel = [r for r in rows if (r.get("group") == g if g != "all synthetic" else r.get("group") != "AHN3")]
                e1 = [r["type1"] for r in sel if isinstance(r["type1"], float)]
                e2 = [r["type2"] for r in sel if isinstance(r["type2"], float)]
                if e1 and e2:
                    lines.append(f"| {g} | {len(sel)} | {_pct(float(np.median(e1)))} | {_pct(float(np.median(e2)))} | "
                                 f"{_pct(max(e1))} | {_pct(max(e2))} |")
            lines += ["", "Estimates per scene (survey-wide: density, height and colour noise; road_regions: its own "
                      "on the ground it receives), the values the `auto` parameters followed:", "",
                      "| dataset | density /m2 | height noise m | colour noise | R6 spacing m | R6 height noise m | "
                      "R6 colour noise |", "|---|---:|---:|---:|---:|---:|---:|"]
            for r in rows:
                e, r6 = r.get("estimates") or {}, (r.get("stage_estimates") or {}).get("road_regions", {})
                lines.append(f"| {r['dataset']} | {e.get('density_per_m2', '')} | {e.get('height_noise_m', '')} | "
                             f"{e.get('colour_noise', '')} | {r6.get('point_spacing_m', '')} | "
                             f"{r6.get('height_noise_m', '')} | {r6.get('colour_noise', '')} |")
        if task == "roof" and groups:
            lines += ["", "Synthetic als-roof matrix per size: median and worst kappa (the roof issue's bound: "
                      "every synthetic scene >= 0.95):", "",
                      "| size | scenes | median kappa | worst kappa | scenes below 0.95 |", "|---|---:|---:|---:|---:|"]
            for g in groups:
                kappas = [r["kappa"] for r in rows if r.get("group") == g and isinstance(r["kappa"], float)]
                if kappas:
                    lines.append(f"| {g} | {len(kappas)} | {float(np.median(kappas)):.4f} | {min(kappas):.4f} | "
                                 f"{sum(k < 0.95 for k in kappas)} |")
        if task == "roof":
            lines += ["", "Per dataset: the vegetation cue roof growing used (`rgb_com`: the patent's COM index on "
                      "RGB, `ndvi`: NDVI where the file's NIR varies, `returns`: foliage returns), the spacing "
                      "the `auto` parameters followed (first returns where the file has returns), r_max, "
                      "and the points edge completion added:", "",
                      "| dataset | vegetation cue | spacing m | r_max m | edge points added |", "|---|---|---:|---:|---:|"]
            for r in rows:
                info = {s["stage"]: s.get("info") or {} for s in r["stages"]}
                e = r.get("estimates") or {}
                edges = info.get("roof_filter", {}).get("edges") or {}
                lines.append(f"| {r['dataset']} | {info.get('roof_growing', {}).get('vegetation_cue', '')} | "
                             f"{e.get('pulse_spacing_m', e.get('point_spacing_m', ''))} | "
                             f"{info.get('roof_seeds', {}).get('r_max', '')} | {edges.get('added_points', '')} |")
        lines += ["", "Per stage: target / non-target points each stage removed (a removed point is "
                  "labelled non-target; downsampling only skips points, which take their nearest "
                  "processed point's label); for a labelling stage also, in brackets, the target "
                  "points of its input it left without the target class and the non-target points "
                  "it gave that class (for a segmenting stage: outside / inside every segment; "
                  "counts over processed points, before label transfer).", ""]
        for r in rows:
            lines += [f"**{r['dataset']}**: " + ", ".join(_stage_counts(s) for s in r["stages"]), ""]
        if NOTES.get(task):
            lines += ["Notes:", ""] + [f"- {note}" for note in NOTES[task]] + [""]
    return "\n".join(lines) + "\n"


def _sizes(text: str) -> tuple:
    """Point counts of a size list (300k,1M); argparse.ArgumentTypeError on a bad one."""
    from roadx_ti.config import parse_scene_size

    sizes = tuple(parse_scene_size(v) for v in text.split(",") if v.strip())
    if len(set(sizes)) != len(sizes):     # '1k,1k' ran each scene twice and weighed it twice in the medians
        raise argparse.ArgumentTypeError(f"{text!r} names one size twice")
    return sizes


def _seeds(text: str):
    if "-" in text:
        a, b = text.split("-")
        seeds = tuple(range(int(a), int(b) + 1))
    else:
        seeds = tuple(int(v) for v in text.split(",") if v.strip())
    if not seeds or min(seeds) < 0:      # '5-1' gave an empty matrix and exit 0
        raise ValueError(f"seeds {text!r}: give seeds >= 0 as a-b (a <= b) or a,b,c")
    if len(set(seeds)) != len(seeds):    # '0,0' ran each scene twice and weighed it twice in the medians
        raise argparse.ArgumentTypeError(f"{text!r} names one seed twice")
    return seeds


def _large(text: str) -> int | None:
    """--road-large: a point count, or None for '' / 'none' (no larger scene)."""
    from roadx_ti.config import parse_scene_size

    return None if text.strip().lower() in ("", "none") else parse_scene_size(text)


def _checked(parse, what: str):
    """An argparse type that parses ``text`` with ``parse`` (so that a typo is a usage error before
    any scene is built) and keeps the text itself, which the report's command line quotes."""
    def check(text: str) -> str:
        try:
            parse(text)
        except ValueError:          # argparse.ArgumentTypeError passes through with its own message
            raise argparse.ArgumentTypeError(f"not {what}: {text!r}") from None
        return text
    return check


_sizes_text = _checked(_sizes, "point counts")
_seeds_text = _checked(_seeds, "seeds (a-b or a,b,c)")
_large_text = _checked(_large, "a point count")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--task", choices=["road", "roof", "all"], default="all")
    p.add_argument("--out", default=str(REPO / "benchmarks" / "accuracy"))
    p.add_argument("--roof-sizes", default="300k,1M,4M", type=_sizes_text, help="roof matrix: synthetic scene sizes")
    p.add_argument("--roof-seeds", default="0-9", type=_seeds_text, help="roof matrix: seeds (a-b or a,b,c)")
    p.add_argument("--road-sizes", default="300k,1M,4M", type=_sizes_text, help="road matrix: synthetic scene sizes")
    p.add_argument("--road-seeds", default="0-9", type=_seeds_text, help="road matrix: seeds (a-b or a,b,c)")
    p.add_argument("--road-large", default="16M", type=_large_text,
                   help="road matrix: one larger scene of seed 0 ('' or none for none)")
    p.add_argument("--backend", default="cpu")


def main(args) -> int:
    from roadx_ti import backend, jsonio
    from roadx_ti.cli import UsageError, make_output_folder
    from roadx_ti.io.atomic import atomic_output

    large = _large(args.road_large)
    if args.task != "roof" and large in _sizes(args.road_sizes) and 0 in _seeds(args.road_seeds):
        # the larger scene is seed 0 at that size: the matrix held it already (weighed twice)
        raise UsageError(f"accuracy: --road-large {args.road_large} is one of --road-sizes {args.road_sizes} "
                         "at seed 0, which the matrix runs already; give another size or --road-large none")
    out = Path(args.out)
    make_output_folder(out, "the accuracy report (--out) goes into a folder")
    backend.init(args.backend)
    tasks = ["road", "roof"] if args.task == "all" else [args.task]
    road_rows = road_datasets(_sizes(args.road_sizes), _seeds(args.road_seeds), (large, 0) if large else None)
    roof_rows = roof_datasets(_sizes(args.roof_sizes), _seeds(args.roof_seeds))
    results = {task: evaluate(task, out, road_rows if task == "road" else roof_rows) for task in tasks}
    # the options this run used, as given (a roof run listed the road matrix and left out --backend / --out)
    command = f"python -m roadx_ti accuracy --task {args.task}"
    if "road" in tasks:
        command += f" --road-sizes {args.road_sizes} --road-seeds {args.road_seeds} --road-large '{args.road_large}'"
    if "roof" in tasks:
        command += f" --roof-sizes {args.roof_sizes} --roof-seeds {args.roof_seeds}"
    if args.backend != "cpu":
        command += f" --backend {args.backend}"
    if out.resolve() != (REPO / "benchmarks" / "accuracy").resolve():
        command += f" --out {args.out}"
    produced = {task: {"command": command, "date": time.strftime("%Y-%m-%d")} for task in tasks}
    # a run of one task keeps the other task's rows (and says so): the report stays whole
    report, produced = merge_with_previous(results, produced, previous_results(out / "accuracy.json"))
    jsonio.write(out / "accuracy.json", {"command": command, "produced": produced, "results": report})
    with atomic_output(out / "ACCURACY.md") as tmp:
        Path(tmp).write_text(render(report, produced))
    print(jsonio.dumps({t: [(r["dataset"], round(r["type1"], 4), round(r["type2"], 4), round(r["kappa"], 4))
                            for r in rows] for t, rows in results.items()}, indent=1))
    return 0
