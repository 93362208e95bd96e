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
