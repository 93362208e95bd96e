"""Per-stage counts of the accuracy report (pipelines.run with truth) and its rendering."""
import numpy as np

from roadx_ti import accuracy, config, pipelines, synthetic
from roadx_ti.stages.base import StageContext
from tests.conftest import REPO


def test_stage_counts_add_up_to_the_errors():
    cloud = synthetic.generate("als-roof", 40_000, seed=2)
    cfg = config.load(REPO / "configs" / "roof_als.yaml")
    truth = cloud.classification == 6
    result = pipelines.run(cloud, pipelines.build_stages(cfg.stage_list()), ctx=StageContext(seed=0),
                           truth=truth, target_class=6)
    predicted = result.classification == 6
    rows = {r["stage"]: r for r in result.stages}
    missed = int((truth & ~predicted).sum())
    false = int((~truth & predicted).sum())
    # every missed roof point was removed by a filter stage or left unlabelled by the last stage
    last = rows["roof_filter"]
    removed = sum(r.get("removed_target", 0) for r in result.stages)
    assert removed + last["unlabelled_target"] == missed
    assert last["labelled_other"] == false
    # the growing stage (segments, no labels) is counted too: outside / inside a segment
    growing = rows["roof_growing"]
    working = rows["roof_growing"]["points_in"]
    assert 0 <= growing["unlabelled_target"] <= working and 0 <= growing["labelled_other"] <= working
    assert "unlabelled_target" not in rows["cloth_ground"]
    text = accuracy.render({"roof": [{"dataset": "scene", "config": "roof_als.yaml", "points": cloud.n,
                                      "seconds": 1.0, "type1": 0.1, "type2": 0.01, "total": 0.02,
                                      "kappa": 0.9, "stages": result.stages}]}, "cmd")
    assert f"roof_filter 0 / 0 (missed {last['unlabelled_target']:,} / wrongly labelled {false:,})" in text
    assert f"cloth_ground {rows['cloth_ground']['removed_target']:,} / {rows['cloth_ground']['removed_other']:,}," in text
    # the vegetation cue, r_max and edge completion per dataset (synthetic als-roof: RGB, no returns)
    cue = rows["roof_growing"]["info"]["vegetation_cue"]
    assert cue == "rgb_com"
    r_max = rows["roof_seeds"]["info"]["r_max"]
    added = rows["roof_filter"]["info"]["edges"]["added_points"]
    assert f"| scene | {cue} | " in text and f" | {r_max} | {added} |" in text


def test_thinning_is_uniform_deterministic_and_order_independent():
    """accuracy.thin_to_density: about the asked density, the same kept points whatever the order,
    spread evenly (every 10 m cell keeps close to the same fraction)."""
    cloud = synthetic.generate("als-roof", 60_000, seed=1)
    from roadx_ti.estimates import occupied_area

    density = cloud.n / occupied_area(cloud.xyz[:, :2])
    thin = accuracy.thin_to_density(cloud, 3.0)
    assert abs(thin.n / occupied_area(cloud.xyz[:, :2]) - 3.0) < 0.15
    perm = np.random.default_rng(0).permutation(cloud.n)
    again = accuracy.thin_to_density(cloud.subset(perm), 3.0)
    key = lambda c: np.sort(c.xyz.view(np.uint32).astype(np.uint64) @ np.array([1, 1 << 20, 1 << 40], np.uint64))  # noqa: E731
    assert np.array_equal(key(thin), key(again))
    cell = np.floor(cloud.xyz[:, :2] / 10).astype(np.int64)
    kept = np.zeros(cloud.n, bool)
    kept[np.isin(key(cloud), key(thin))] = True
    ids, inverse = np.unique(cell, axis=0, return_inverse=True)
    counts = np.bincount(inverse.ravel())
    fraction = np.bincount(inverse.ravel(), kept) / counts
    busy = counts >= 200
    assert np.all(np.abs(fraction[busy] - 3.0 / density) < 0.3 * 3.0 / density)
    assert accuracy.thin_to_density(thin, 10.0) is thin      # not denser: unchanged


def _row(name, kappa):
    return {"dataset": name, "config": "x.yaml", "points": 10, "seconds": 1.0, "type1": 0.1, "type2": 0.01,
            "total": 0.02, "kappa": kappa, "stages": []}


def test_a_run_of_one_task_keeps_the_other_tasks_rows(tmp_path):
    """`accuracy --task roof` rewrites the report whole: the road rows (and their provenance) come
    from the earlier accuracy.json, not dropped (as they were until 2026-12-05)."""
    from roadx_ti import jsonio

    earlier = tmp_path / "accuracy.json"
    jsonio.write(earlier, {"command": "accuracy --task all", "results": {"road": [_row("street", 0.9)],
                                                                          "roof": [_row("old roofs", 0.5)]}})
    previous = accuracy.previous_results(earlier)
    assert previous["road"][1] == {"command": "accuracy --task all", "date": None}
    roof = {"roof": [_row("new roofs", 0.8)]}
    merged, produced = accuracy.merge_with_previous(roof, {"roof": {"command": "accuracy --task roof",
                                                                    "date": "2026-12-05"}}, previous)
    assert list(merged) == ["road", "roof"]
    assert merged["road"][0]["dataset"] == "street" and merged["roof"][0]["dataset"] == "new roofs"
    text = accuracy.render(merged, produced)
    assert "| street |" in text and "| new roofs |" in text and "| old roofs |" not in text
    assert "the road section by `accuracy --task all`; the roof section by `accuracy --task roof` on 2026-12-05" in text
    # one source: one line; an unreadable earlier file keeps nothing (this run's tasks only)
    assert accuracy.produced_line({"road": {"command": "c", "date": "d"}}) == "Produced by `c` on d."
    earlier.write_text("{ not json")
    assert accuracy.previous_results(earlier) == {} and accuracy.previous_results(tmp_path / "absent.json") == {}


def test_the_committed_report_carries_every_note():
    """benchmarks/accuracy/ACCURACY.md lists accuracy.NOTES (notes added after the last regeneration
    are added to the file as the report renders them: one '- note' line each)."""
    text = (REPO / "benchmarks" / "accuracy" / "ACCURACY.md").read_text()
    missing = [note[:60] for task in accuracy.NOTES for note in accuracy.NOTES[task] if f"- {note}\n" not in text]
    assert not missing, missing


def test_scene_names_are_exact_and_the_command_is_the_runs(tmp_path):
    """A 1,500-point scene is '1.5 k' (it was named '1 k', another scene's name); the report's
    command lists the options of the tasks that ran, the backend and the folder (a roof run listed
    the road matrix and left out --backend and --out)."""
    import argparse
    import json
    from unittest import mock

    assert [accuracy._size_name(n) for n in (1500, 300_000, 4_000_000, 2_500_000)] == ["1.5 k", "300 k", "4 M", "2.5 M"]
    args = argparse.Namespace(task="roof", road_sizes="300k", road_seeds="0-9", road_large="16M", roof_sizes="1.5k",
                              roof_seeds="0", backend="vulkan", out=str(tmp_path / "acc"))
    with mock.patch.object(accuracy, "evaluate", return_value=[]), mock.patch("roadx_ti.backend.init"):
        accuracy.main(args)
    command = json.loads((tmp_path / "acc" / "accuracy.json").read_text())["command"]
    assert command == ("python -m roadx_ti accuracy --task roof --roof-sizes 1.5k --roof-seeds 0 "
                       f"--backend vulkan --out {tmp_path / 'acc'}")
