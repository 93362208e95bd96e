"""road_pipeline: METHODS.md R1-R6 end to end on a synthetic uav-road scene, with the stages of
configs/road_uav.yaml (the built-in defaults while that file is absent). No anchor: the row gives
Mpts/s and bytes per point."""
STAGE = "road_pipeline"
SCENE = "uav-road"
VARIANTS = [{"name": "", "params": {"config": "configs/road_uav.yaml", "pipeline": "road"}}]
TARGETS = {}


def roadx_ti(scene, config, pipeline):
    from roadx_ti.bench import pipeline_call

    return pipeline_call(scene, config, pipeline)


IMPLS = {"roadx_ti": roadx_ti}
