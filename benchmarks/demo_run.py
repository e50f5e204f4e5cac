"""A built and exported demo run directory, shared by the benchmarks that replay or score it."""

from __future__ import annotations

from pathlib import Path


def built_demo_run(root: Path) -> Path:
    """Write the demo scene (seed 0) and run build-scene, gen-trajectories and export-usd into `root`."""
    from sagebench.scene.synth import write_synth_scene
    from sagebench.settings.build_scene import BuildSceneConfig
    from sagebench.stages.build_scene import build_scene
    from sagebench.stages.export_usd import export_usd
    from sagebench.stages.gen_trajectories import GenTrajectoriesConfig, gen_trajectories

    scene = root / "input" / "demo_apartment_0"
    write_synth_scene(scene, seed=0)
    build_scene(scene, root, BuildSceneConfig(seed=0))
    gen_trajectories(root, GenTrajectoriesConfig(seed=0))
    export_usd(root, cache_dir=root / "cache")
    return root
