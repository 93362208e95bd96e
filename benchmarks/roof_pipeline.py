"""roof_pipeline: METHODS.md P1-P4 end to end on a synthetic als-roof scene, with the stages of
configs/roof_als.yaml (the built-in defaults while that file is absent). No anchor: the row gives
Mpts/s and bytes per point."""
STAGE = "roof_pipeline"
SCENE = "als-roof"
VARIANTS = [{"name": "", "params": {"config": "configs/roof_als.yaml", "pipeline": "roof"}}]
TARGETS = {}


def roadx_ti(scene, config, pipeline):
    from roadx_ti.bench import pipeline_call

    return pipeline_call(scene, config, pipeline)


IMPLS = {"roadx_ti": roadx_ti}
