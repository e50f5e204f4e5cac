"""Mutation check: apply named breaks to a temporary copy of the package and run the tests that should catch them.

Each mutant replaces one exact snippet of one module (the snippet must occur exactly once, so a mutant
that no longer applies after a refactor is reported, not silently skipped) and runs the named test files
on that copy. A mutant "survives" when those tests still pass: a test has gone weak. The real working tree
is never modified. Usage: python tools/mutants.py [NAME ...]   (`make mutants`; exit 1 if any survives).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
COPIED = ("sagebench", "tests", "tools", "docs", "schemas", "pyproject.toml", "README.md")


@dataclass(frozen=True)
class Mutant:
    name: str
    path: str  # module, relative to the repository root
    old: str
    new: str
    tests: tuple[str, ...]  # test files, or node ids (file::test) where one test of a slow file is the one that bites


MUTANTS = (
    Mutant("export-training rewrites the shards an interrupted export finished", "sagebench/training/export.py",
           "        if path.is_file():\n", "        if False:\n", ("tests/test_cli_export_training.py",)),
    Mutant("export-training turns by truncating, as SAGE's generate_actions.py", "sagebench/training/actions.py",
           "turns = round(abs(change) / turn)", "turns = int(abs(change) / turn)", ("tests/test_training_actions.py",)),
    Mutant("gsplat gets log-scales instead of standard deviations", "sagebench/render/gsplat_convention.py",
           "scales=np.exp(g.log_scales.astype(np.float64)).astype(np.float32)",
           "scales=g.log_scales.astype(np.float32)", ("tests/test_render_gsplat_convention.py",)),
    Mutant("gsplat gets quaternions x first", "sagebench/render/gsplat_convention.py",
           "quats=np.ascontiguousarray(g.quats_wxyz, np.float32)",
           "quats=np.ascontiguousarray(g.quats_wxyz[:, [1, 2, 3, 0]], np.float32)",
           ("tests/test_render_gsplat_convention.py",)),
    Mutant("auto picks gsplat even for instance ids", "sagebench/render/backends.py",
           'return "gsplat" if not lacking and gsplat_missing() is None else "cpu"',
           'return "gsplat" if gsplat_missing() is None else "cpu"', ("tests/test_render_backends.py",)),
    Mutant("run's pool workers start with every core's threads, spinning", "sagebench/pipeline/executors.py",
           "    worker_init(threads)\n    signal.signal(", "    signal.signal(", ("tests/test_threads.py",)),
    Mutant("kernels warmed before fan-out miss the DTW kernel", "sagebench/pipeline/kernels.py",
           "    dtw(np.zeros((2, 2)), np.ones((3, 2)))\n", "", ("tests/test_pipeline_kernels.py",)),
    Mutant("oracle passes a station only by ending near it", "sagebench/navsim/policies.py",
           "_segment_distance(t[self.next[i]], moved_from, pose[:2])",
           "_segment_distance(t[self.next[i]], pose[:2], pose[:2])", ("tests/test_navsim_policies.py",)),
    Mutant("oracle stops on passing the end, however far it then stands", "sagebench/navsim/policies.py",
           "np.hypot(*(t[-1] - pose[:2])) > self.actions.forward_step", "np.hypot(*(t[-1] - pose[:2])) > math.inf",
           ("tests/test_navsim_policies.py",)),
    Mutant("collider pieces cached only in memory", "sagebench/collider_export/pieces.py",
           "        self.cache.put(result)\n", "", ("tests/test_collider_pieces.py",)),
    Mutant("a Ctrl-C a library swallows while the CLI imports is ignored", "sagebench/__main__.py",
           "            if interrupted():\n                raise KeyboardInterrupt\n", "",
           ("tests/test_fuzz_safety.py::test_ctrl_c_a_library_swallows_while_the_cli_imports_still_ends_the_run",)),
    Mutant("the command forgets a Ctrl-C noted while the CLI imported", "sagebench/ui.py",
           "        yield\n        return\n    _INTERRUPTED.clear()\n",
           "        _INTERRUPTED.clear()\n        yield\n        return\n    _INTERRUPTED.clear()\n",
           ("tests/test_ui.py::test_a_ctrl_c_noted_while_the_cli_imported_is_kept_when_the_command_starts",)),
    Mutant("a wall collider may close the doorway it leaves open", "sagebench/collider_export/free_floor.py",
           "        if spot is not None:\n", "        if False:\n", ("tests/test_collider_determinism.py",)),
    Mutant("the safety limit is part of the piece cache key", "sagebench/collider_export/pieces.py",
           "exclude=UNSHAPING,", "exclude=frozenset(),", ("tests/test_collider_pieces.py",)),
    Mutant("voxel hulls keep only the first point of each lattice run", "sagebench/collider_export/voxel.py",
           "    return first | last\n", "    return first\n", ("tests/test_collider_voxel.py",)),
    Mutant("a narrow passage opens where the agent does not fit", "sagebench/topdown/passages.py",
           "need=radius + MARGIN", "need=radius - 0.01", ("tests/test_topdown_passages.py",)),
    Mutant("a passage cell's search stops before it is known whether the agent fits", "sagebench/topdown/passages.py",
           "+ half * np.sqrt(2) >= need - SLACK)]", "+ half * 0.3 >= need - SLACK)]",
           ("tests/test_topdown_passages.py::test_a_cell_settled_early_is_decided_as_the_full_search_decides_it",)),
    Mutant("shortcuts cross a narrow passage's cells", "sagebench/astar/shortcut.py",
           "if nav[cells[i, 0], cells[i, 1]] != 1:", "if nav[cells[i, 0], cells[i, 1]] == 0:",
           ("tests/test_astar_shortcut.py",)),
    Mutant("balanced keeps the first method whatever its band error", "sagebench/collider_export/methods.py",
           "return error_cm <= settings.band_tolerance_cm", "return True",
           ("tests/test_collider_pieces.py",)),
    Mutant("mesh splits never read back from the cache", "sagebench/collider_export/coacd_cache.py",
           "            return _decode_split(path.read_bytes())\n", "            return None\n",
           ("tests/test_collider_decompose.py",)),
    Mutant("merging to the part budget ignores the band footprint", "sagebench/collider_export/decompose.py",
           "reach=reach, tolerance=", "reach=None, tolerance=", ("tests/test_collider_decompose.py",)),
    Mutant("quality mode keeps its own parts when balanced's are closer", "sagebench/collider_export/decompose.py",
           '    if settings.mode != "quality":\n', "    if True:\n", ("tests/test_collider_decompose.py",)),
    Mutant("a run spreads only quality's own pass over its executor", "sagebench/collider_export/scene_export.py",
           "for colliders in mode_passes(config.colliders)", "for colliders in (config.colliders,)",
           ("tests/test_pipeline_run.py",)),
    Mutant("every concave piece becomes its convex hull", "sagebench/collider_export/methods.py",
           '    if method == "hull":\n', "    if True:\n", ("tests/test_collider_decompose.py",)),
    Mutant("voxel merge ignores the band footprint", "sagebench/collider_export/voxel.py",
           "        return excess * big + wv\n", "        return wv\n", ("tests/test_collider_voxel.py",)),
    Mutant("every flat piece is its padded hull, notched or not", "sagebench/collider_export/convex.py",
           "    if bridged.is_empty:\n", "    if True:\n", ("tests/test_collider_convex.py",)),
    Mutant("hull wound without qhull's facet planes", "sagebench/collider_export/convex.py",
           "    faces[inward] = faces[inward][:, ::-1]\n", "", ("tests/test_collider_convex.py",)),
    Mutant("a rotated box's x range read without its margin turned", "sagebench/importers/boxes.py",
           "reach = np.abs(self.axes).T @ (self.half + margin)", "reach = np.abs(self.axes).T @ self.half + margin",
           ("tests/test_importers_boxes.py",)),
    Mutant("voxel layers laid from the box, not the band's edge", "sagebench/splat_geometry/surface.py",
           "        lo[2] -= (centre[2] + lo[2] - settings.band[0]) % pitch", "        lo[2] -= 0.0",
           ("tests/test_splat_geometry_surface.py",)),
    Mutant("filled voxels' corners past the box's own points", "sagebench/splat_geometry/surface.py",
           "np.clip(corners_b, lo_b, hi_b))])", "corners_b)])",
           ("tests/test_splat_geometry_surface.py",)),
    Mutant("a post round its splats, not behind them", "sagebench/splat_geometry/surface.py",
           "    middle = _towards_middle(", "    middle = (lambda start, *_: start)(",
           ("tests/test_splat_geometry_surface.py",)),
    Mutant("one hull over an object's Gaussians", "sagebench/splat_geometry/surface.py",
           "    if len(boxes) > settings.max_parts:\n", "    if len(boxes) > 1:\n        settings = SurfaceSettings(max_parts=1)\n",
           ("tests/test_splat_geometry_surface.py",)),
    Mutant("occupancy.png read north up", "sagebench/importers/interiorgs_files.py",
           "values=np.ascontiguousarray(image[:, ::-1])", "values=np.ascontiguousarray(image[::-1])",
           ("tests/test_importers_interiorgs_files.py",)),
    Mutant("a leaf's swing read the wrong way round", "sagebench/importers/interiorgs_structure.py",
           "1 if turn > 0 else -1, round(angle, 3))", "-1 if turn > 0 else 1, round(angle, 3))",
           ("tests/test_importers_interiorgs_structure.py",)),
    Mutant("the floor under a sofa given to the sofa", "sagebench/importers/interiorgs.py",
           "    ids = structure.ids(pts, config.structure_margin, across_only=True)\n",
           "    ids = np.zeros(len(pts), dtype=np.int64)\n", ("tests/test_cli_import_interiorgs.py",)),
    Mutant("collider parts over PhysX's 64 hull vertices", "sagebench/collider_export/decompose.py",
           "MeshColliders(within_vertex_limit(kept), exact", "MeshColliders(kept, exact",
           ("tests/test_collider_decompose.py",)),
    Mutant("repeated Gaussian display colours not indexed", "sagebench/collider_export/usd_writer.py",
           "    values, index = np.unique(colour, axis=0, return_inverse=True)", "    values, index = colour, np.arange(len(colour))",
           ("tests/test_usd_writer.py",)),
    Mutant("crate layer without its own stage metadata", "sagebench/collider_export/usd_writer.py",
           "    stage_metadata(crate)\n", "", ("tests/test_usd_writer.py",)),
    Mutant("NuRec specular coefficients channel-major, as the PLY holds them", "sagebench/splats/nurec.py",
           '"features_specular": specular.reshape(n, rest * 3)}',
           '"features_specular": specular.transpose(0, 2, 1).reshape(n, rest * 3)}', ("tests/test_splats_nurec.py",)),
    Mutant("door leaves stand on the floor", "sagebench/collider_export/scene_export.py",
           "parts = mc.parts if obj.door is None else clear_floor(mc.parts, matrix, spec.floor_height)",
           "parts = mc.parts", ("tests/test_mjcf_scenes.py",)),
    Mutant("bodies overlapping where placed push each other apart", "sagebench/collider_export/mjcf_writer.py",
           "    exclude = overlapping_bodies(spec.compile())\n", "    exclude = [] if spec.compile() else []\n",
           ("tests/test_mjcf_writer.py",)),
    Mutant("door servo holds the closed angle", "sagebench/collider_export/mjcf_writer.py",
           "    servo.biasprm[:3] = [k * h.angle, -k, 0.0]\n", "    servo.biasprm[:3] = [0.0, -k, 0.0]\n",
           ("tests/test_mjcf_writer.py",)),
    Mutant("a hollow bin weighs its hull full of wood", "sagebench/collider_export/bodies.py",
           "    return bulk if low <= bulk <= high else typical\n", "    return bulk\n", ("tests/test_usd_writer.py",)),
    Mutant("catalogue elevation ignored", "sagebench/scene/synth.py",
           "translation=_r3((*item.xy, item.z + entry.elevation_m))", "translation=_r3((*item.xy, item.z))",
           ("tests/test_scene_furniture.py",)),
    Mutant("VLN-CE gt locations repeat the start for every turn", "sagebench/vlnce/gt.py",
           "    moved = np.concatenate([[True], np.any(p[1:] != p[:-1], axis=1)])\n",
           "    moved = np.ones(len(p), dtype=bool)\n", ("tests/test_navsim_teacher.py",)),
    Mutant("dataset card licence is always other", "sagebench/episodes/card.py",
           '    return values.pop() if len(values) == 1 else "other"\n', '    return "other"\n',
           ("tests/test_episodes_card.py",)),
    Mutant("SAGE's collision payload visible to every camera", "sagebench/collider_export/sage_layout.py",
           "    UsdGeom.Imageable(collision).CreateVisibilityAttr(UsdGeom.Tokens.invisible)\n", "",
           ("tests/test_collider_sage_layout.py",)),
    Mutant("collider quality: faces between touching parts counted as surface", "sagebench/collider_export/quality.py",
           "keep = ~_inside_other(coll_pts + 1e-6 * collider.face_normals[coll_face], owner, planes)",
           "keep = np.ones(len(coll_pts), dtype=bool)", ("tests/test_collider_quality.py",)),
    Mutant("collider quality: band footprints without their enclosed areas", "sagebench/collider_export/quality.py",
           "src = ndimage.binary_fill_holes(rasterise(src_polys, lo, pitch, shape))",
           "src = rasterise(src_polys, lo, pitch, shape)", ("tests/test_collider_quality.py",)),
    Mutant("collider quality: inside test stops before the last plane", "sagebench/collider_export/quality.py",
           "for j in range(planes.shape[0]):", "for j in range(planes.shape[0] - 1):", ("tests/test_collider_quality.py",)),
    Mutant("collider quality: distance search bounded by half the nearest corner", "sagebench/collider_export/quality.py",
           ".query(points)[0][:, None] + 1e-9", ".query(points)[0][:, None] * 0.5", ("tests/test_collider_quality.py",)),
    Mutant("collider quality: overlapping parts' volume counted twice", "sagebench/collider_export/quality.py",
           "        envelope[fresh[:, 0], fresh[:, 1], fresh[:, 2]] = True  # a cell two parts share counts once\n", "",
           ("tests/test_collider_quality.py",)),
    Mutant("export judges colliders in the default band, not the map's", "sagebench/stages/export_usd.py",
           "low, high = read_semantic_map(scene_dir / SEMANTIC_MAP).band_m", "low, high = 0.05, 1.2",
           ("tests/test_cli_export_usd.py::test_colliders_are_judged_in_the_band_the_map_was_built_for",)),
    Mutant("ndtw divided by the number of poses", "sagebench/metrics/episode.py",
           "(len(ref) * config.ndtw_threshold)", "(len(poses) * config.ndtw_threshold)", ("tests/test_metrics.py",)),
    Mutant("SPL rewards a path shorter than the geodesic", "sagebench/metrics/episode.py",
           "return sr * g / max(g, length) if", "return sr * g / length if length > 0 and", ("tests/test_metrics.py",)),
    Mutant("height band without its top", "sagebench/topdown/occupancy.py",
           "valid = [(z >= z_lo) & (z <= z_hi)]", "valid = [z >= z_lo]", ("tests/test_topdown_occupancy.py",)),
    Mutant("height band not offset by the floor height", "sagebench/topdown/builder.py",
           "z_lo, z_hi = (spec.floor_height + z for z in agent.band)", "z_lo, z_hi = agent.band",
           ("tests/test_topdown_build_scene.py",)),
    Mutant("fast renderer: one SH degree-3 coefficient halved", "sagebench/render/splat_render.py",
           "C3[1] * x * y * z * sh[i, 10, c]", "0.5 * C3[1] * x * y * z * sh[i, 10, c]",
           ("tests/test_replay_render.py",)),
    Mutant("fast renderer: last SH term dropped", "sagebench/render/splat_render.py",
           "\n                  + C3[6] * x * (xx - 3 * yy) * sh[i, 15, c])", ")", ("tests/test_replay_render.py",)),
    Mutant("fast renderer: faint Gaussians' reach a sqrt(2) short", "sagebench/render/splat_render.py",
           "return 2.0 * min(CUTOFF, math.log(o / MIN_ALPHA))", "return 2.0 * min(CUTOFF, 0.5 * math.log(o / MIN_ALPHA))",
           ("tests/test_replay_render.py",)),
    Mutant("fast renderer: row chords centred on the wrong side of a tilted ellipse", "sagebench/render/splat_render.py",
           "mid = fu + fb * fdy / fa", "mid = fu - fb * fdy / fa", ("tests/test_replay_render.py",)),
    Mutant("depth radix sort skips the low 11 bits", "sagebench/render/splat_render.py",
           "for shift in range(0, 8 * bits.itemsize, 11):", "for shift in range(11, 8 * bits.itemsize, 11):",
           ("tests/test_render_chunks.py",)),
    Mutant("float32 exp without its cubic term", "sagebench/render/splat_render.py",
           "(np.float32(0.5) + r * np.float32(1.0 / 6.0))", "np.float32(0.5)", ("tests/test_render_precision.py",)),
    Mutant("parallel counting sorts: slices before keys", "sagebench/render/splat_render.py",
           "    for d in range(count.shape[1]):\n        for p in range(count.shape[0]):\n            c = count[p, d]",
           "    for p in range(count.shape[0]):\n        for d in range(count.shape[1]):\n            c = count[p, d]",
           ("tests/test_render_chunks.py",)),
    Mutant("chunk cull ignores the Gaussians' size", "sagebench/render/chunks.py",
           "+ 3.0 * packed.max_scale[None] * k", "", ("tests/test_render_chunks.py",)),
    Mutant("derived ICP without contact", "sagebench/evaluation/intensity.py",
           "np.maximum(b, np.where(pure_turns(p, min_step=tol), 0.0, n))", "b", ("tests/test_cli_evaluate.py",)),
    Mutant("measured ICP without contact along the step", "sagebench/navsim/simulator.py",
           "np.maximum(motion.intensity, near)", "motion.intensity", ("tests/test_env.py",)),
    Mutant("contact counted only at a step's end pose", "sagebench/navsim/motion.py",
           "touched = (found > 0).any(axis=1)", "touched = found[:, steps] > 0", ("tests/test_navsim_motion.py",)),
    Mutant("env checks its actions against a default replay", "sagebench/settings/rollout.py",
           "problem = beyond_limits(self.actions, self.replay)",
           "problem = beyond_limits(self.actions, ReplayConfig())",
           ("tests/test_env.py::test_actions_beyond_the_envs_own_replay_limits_are_refused_naming_the_fields",)),
    Mutant("SH basis: a degree-3 constant halved", "sagebench/render/sh.py",
           "1.445305721320277,", "0.7226528606601385,", ("tests/test_replay_render.py",)),
    Mutant("validate: penetration tolerance 0.01 -> 0.05 m", "sagebench/settings/validate.py",
           "default=0.01, ge=0", "default=0.05, ge=0", ("tests/test_validation_checks.py",)),
    Mutant("validate: push-off rule removed", "sagebench/validation/checks.py",
           "penetration > config.penetration_tolerance or deviation > config.deviation_tolerance",
           "penetration > config.penetration_tolerance", ("tests/test_validation_checks.py",)),
    Mutant("run's collider pieces smallest first", "sagebench/pipeline/schedule.py",
           "(-piece.cost, self.progress.total, piece)", "(piece.cost, self.progress.total, piece)",
           ("tests/test_pipeline_schedule.py",)),
    Mutant("a scene's export submitted before its pieces are done", "sagebench/pipeline/schedule.py",
           "if self.planned[sid] is None or self.planned[sid]:", "if self.planned[sid] is None:",
           ("tests/test_pipeline_schedule.py",)),
    Mutant("stamp key ignored", "sagebench/pipeline/tasks.py",
           'if stamp is None or stamp.get("key") != key:', "if stamp is None:", ("tests/test_pipeline_tasks.py",)),
    Mutant("stamps never current", "sagebench/pipeline/tasks.py",
           'return outputs == stamp["outputs"] and bool(outputs)', "return False",
           ("tests/test_pipeline_tasks.py",)),
    Mutant("library versions left out of the stamp key", "sagebench/stamps.py",
           'h.update(json.dumps(output_versions(), sort_keys=True).encode() + b"\\0")', "pass",
           ("tests/test_pipeline_tasks.py",)),
    Mutant("a stage command trusts the files it reads", "sagebench/stamps.py",
           "    check_stamped(run_dir, scene_id, CONTRACT[stage].reads)\n", "    pass\n",
           ("tests/test_stage_stamps.py::test_a_stage_refuses_an_input_changed_since_the_stage_that_wrote_it",)),
    Mutant("a stray file in a stamped directory passes", "sagebench/stamps.py",
           'return "stray" if path.is_file() else None', "return None",
           ("tests/test_stage_stamps.py::test_validate_checks_a_run_made_stage_by_stage_against_its_stamps",)),
    Mutant("validate without a manifest trusts the stamped files", "sagebench/stages/validate.py",
           '        check_stamped(run_dir, scene_id, stamped_places(run_dir, scene_id, besides="validate"))\n',
           "        pass\n",
           ("tests/test_stage_stamps.py::test_validate_checks_a_run_made_stage_by_stage_against_its_stamps",)),
    Mutant("verify leaves the stamps out beside a manifest", "sagebench/pipeline/verify.py",
           "*check_stamps(run_dir, scenes).lines(leave_out=named)", "",
           ("tests/test_fuzz_safety.py::test_verify_checks_rows_and_the_usd_stage_beyond_the_hashes",)),
    Mutant("an import leaves gen-trajectories' stamp on its episodes", "sagebench/stamps.py",
           "            stamp_path(run_dir, scene_id, other).unlink(missing_ok=True)\n", "            pass\n",
           ("tests/test_stage_stamps.py::test_imported_episodes_are_stamped_by_the_import",)),
    Mutant("a default changed in its model only", "sagebench/settings/gen_trajectories.py",
           'default=200, ge=1, description="Distinct trajectories per scene.")',
           'default=100, ge=1, description="Distinct trajectories per scene.")', ("tests/test_cli_help.py",)),
    Mutant("a bad option named by its field", "sagebench/settings/option.py",
           "option = next((s.name for s in settings_of(model) if s.path == loc), loc)", "option = loc",
           ("tests/test_cli_help.py",)),
    Mutant("an option's help written apart from its field's description", "sagebench/cli_settings.py",
           "    option = typer.Option(setting.name, help=help_text(setting, overrides=overrides),",
           '    option = typer.Option(setting.name, help=help_text(setting, overrides=overrides).replace(", m", ""),',
           ("tests/test_cli_help.py",)),
    Mutant("write_bytes writes the final name in place", "sagebench/fileio.py",
           'fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{TEMP_TAG}", suffix=".tmp", dir=path.parent)',
           "fd, tmp = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644), str(path)",
           ("tests/test_fileio.py",)),
    Mutant("alignment passes on too few compared pixels", "sagebench/replay/alignment.py",
           "if a.compared < need:", "if a.compared < need - 1:", ("tests/test_replay_alignment.py",)),
    Mutant("resume removes every hidden *.tmp / *.old", "sagebench/fileio.py",
           "return _TEMPORARY.fullmatch(name) is not None", 'return name.startswith(".") and name.endswith((".tmp", ".old"))',
           ("tests/test_fileio.py",)),
    Mutant("outputs keep mkstemp's mode 0600", "sagebench/fileio.py",
           "os.fchmod(fh.fileno(), 0o666 & ~current_umask())", "pass", ("tests/test_fileio.py",)),
    Mutant("cleanup walks into input scenes", "sagebench/fileio.py",
           "            if kept(path):\n                continue\n", "", ("tests/test_fileio.py",)),
    Mutant("the lock file keeps a longer stale pid's tail", "sagebench/run_lock.py",
           "        os.ftruncate(fd, 0)\n", "",
           ("tests/test_pipeline_run.py::test_the_refusal_names_the_holders_pid_over_a_longer_stale_one",)),
    Mutant("temporaries cleaned before the run lock is taken", "sagebench/pipeline/run.py",
           '    with claim_run_dir(run_dir, "run", force=force, config=config_path, inputs=sources.values()):\n'
           '        clean_temporaries(run_dir, sources.values())\n',
           '    clean_temporaries(run_dir, sources.values())\n'
           '    with claim_run_dir(run_dir, "run", force=force, config=config_path, inputs=sources.values()):\n',
           ("tests/test_pipeline_run.py::test_a_refused_run_leaves_the_live_runs_files_alone",)),
    Mutant("category order from a set (hash seed)", "sagebench/topdown/builder.py",
           "*sorted({o.category for o in objects})", "*list({o.category for o in objects})",
           ("tests/test_hash_seed.py",)),
    Mutant("A* cuts blocked corners", "sagebench/astar/grid_astar.py",
           "if not (_free(nav, r + dr, c) and _free(nav, r, c + dc) and _free(nav, r + dr, c + dc)):",
           "if not _free(nav, r + dr, c + dc):", ("tests/test_astar_grid.py",)),
    Mutant("inflation measured to cell centres", "sagebench/topdown/occupancy.py",
           "disk = _square_distance(dr, dc) * resolution < radius - 1e-9",
           "disk = np.hypot(dr, dc) * resolution < radius - 1e-9", ("tests/test_topdown_occupancy.py",)),
    Mutant("LLM: no whole-request deadline (per-read timeouts only)", "sagebench/http_client.py",
           "            for s in self._socks:\n                _shut(s)", "            pass",
           ("tests/test_instructions_llm_client.py", "tests/test_http_client.py")),
    Mutant("LLM: the breaker never opens", "sagebench/instructions/llm_client.py",
           "self.reason is None and self._run >= self.limit", "False", ("tests/test_instructions_llm_client.py",)),
    Mutant("grounding: a phrase that fits the goal and others is accepted", "sagebench/instructions/grounding.py",
           "if cands == {want}:", "if want in cands:", ("tests/test_instructions_grounding.py",)),
    Mutant("grounding: room placement unchecked", "sagebench/instructions/grounding.py",
           "cands = [o for o in cands if g._rooms(o.instance_id) & rooms]", "pass",
           ("tests/test_instructions_grounding.py",)),
    Mutant("doors: a floor exactly JOINS_M away is not joined", "sagebench/instructions/relations.py",
           "<= JOINS_M", "< JOINS_M", ("tests/test_instructions_naming.py",)),
    Mutant("doors: a door is only in its annotated room", "sagebench/instructions/grounding.py",
           "frozenset(o.joins if o.joins is not None else (o.room_id,))", "frozenset((o.room_id,))",
           ("tests/test_instructions_naming.py",)),
    Mutant("sight: walls do not block the view", "sagebench/instructions/sight.py",
           "if self.walls[row, col]:", "if False:", ("tests/test_instructions_sight.py",)),
    Mutant("USD: SH coefficients a constant primvar", "sagebench/collider_export/usd_writer.py",
           "sh.SetInterpolation(UsdGeom.Tokens.vertex)", "sh.SetInterpolation(UsdGeom.Tokens.constant)",
           ("tests/test_usd_writer.py",)),
    Mutant("USD: collider normals inward", "sagebench/collider_export/usd_writer.py",
           "n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])", "n = np.cross(v[:, 2] - v[:, 0], v[:, 1] - v[:, 0])",
           ("tests/test_usd_writer.py",)),
    Mutant("USD: gravity along -Y on a Z-up stage", "sagebench/collider_export/usd_writer.py",
           "Gf.Vec3f(0.0, 0.0, -1.0)", "Gf.Vec3f(0.0, -1.0, 0.0)", ("tests/test_usd_writer.py",)),
    Mutant("MJCF: door hinge without its state angle", "sagebench/collider_export/mjcf_writer.py",
           "pos=list(h.pos), ref=h.angle,", "pos=list(h.pos),", ("tests/test_mjcf_writer.py",)),
    Mutant("replay keeps the scene's joints", "sagebench/replay/physics.py",
           "[*spec.actuators, *spec.excludes, *spec.joints]", "[*spec.actuators, *spec.excludes]",
           ("tests/test_replay_physics.py",)),
    Mutant("replay agent's body starts 35 cm above the floor", "sagebench/replay/physics.py",
           "agent_prism(agent.radius, *agent.band)", "agent_prism(agent.radius, 0.35, agent.height)",
           ("tests/test_replay_physics.py",)),
    Mutant("replay agent is the default body, not the map's", "sagebench/replay/scene_model.py",
           "agent = read_semantic_map(scene_dir / SEMANTIC_MAP).agent()",
           "agent = build_replay_model.__kwdefaults__['agent']",
           ("tests/test_cli_validate.py::test_the_replay_agent_is_the_body_the_map_was_built_for",)),
    Mutant("habitat rotation a quarter turn off", "sagebench/vlnce/frame.py",
           "half = (yaw - math.pi / 2) / 2", "half = yaw / 2", ("tests/test_vlnce.py",)),
    Mutant("habitat frame mirrored", "sagebench/vlnce/frame.py",
           "[0.0, -1.0, 0.0]])", "[0.0, 1.0, 0.0]])", ("tests/test_vlnce.py",)),
    Mutant("a room half in the main region counts as reachable", "sagebench/topdown/regions.py",
           "return self.room_main_cells[room] > REACHABLE_SHARE * self.room_cells[room]",
           "return self.room_main_cells[room] >= REACHABLE_SHARE * self.room_cells[room]",
           ("tests/test_topdown_regions.py",)),
    Mutant("regions joined across a blocked corner", "sagebench/topdown/regions.py",
           "ndimage.label(navigable.astype(bool))", "ndimage.label(navigable.astype(bool), structure=np.ones((3, 3)))",
           ("tests/test_topdown_regions.py",)),
    Mutant("objects in unreachable rooms become goals", "sagebench/episodes/targets.py",
           "or not inst.polygon.coordinates or inst.room in cut_off):", "or not inst.polygon.coordinates):",
           ("tests/test_topdown_build_scene.py",)),
    Mutant("walls footprinted by their parts' hulls", "sagebench/topdown/footprints.py",
           'BAND_SECTION_KINDS = frozenset({"wall"})', "BAND_SECTION_KINDS = frozenset()",
           ("tests/test_topdown_footprints.py", "tests/test_topdown_build_scene.py")),
    Mutant("band section keeps every enclosed face", "sagebench/topdown/footprints.py",
           "faces = faces[_covered(shapely.get_coordinates(shapely.point_on_surface(faces)), flat)]", "pass",
           ("tests/test_topdown_footprints.py",)),
    Mutant("a panel's footprint chord keyed on x only", "sagebench/topdown/footprints.py",
           "key = points[:, 0] + 1e-3 * points[:, 1]", "key = points[:, 0]", ("tests/test_topdown_footprints.py",)),
    Mutant("high-level types without quotas", "sagebench/instructions/balance.py",
           "cap, chosen = dict(first), {}", "cap, chosen = {t: len(pool) for t in kinds}, {}",
           ("tests/test_instructions_balance.py",)),
    Mutant("a short type's trajectories shared again", "sagebench/instructions/balance.py",
           "chosen.update({i: t for i, t in flow.items() if t not in reached})", "pass",
           ("tests/test_instructions_balance.py",)),
    Mutant("a door hinge anywhere in the scene", "sagebench/scene/checks.py",
           "    if gap > HINGE_TOLERANCE_M:\n", "    if gap > 100 * HINGE_TOLERANCE_M:\n", ("tests/test_fuzz_inputs.py",)),
    Mutant("env and rollout processes keep OpenMP's spin-wait", "sagebench/threads.py",
           'os.environ.setdefault("OMP_WAIT_POLICY", wait.upper())', "pass", ("tests/test_threads.py",)),
    Mutant("a policy server gets the run's episode ids", "sagebench/navsim/http_policy.py",
           "self.ids = [self.opaque_id(e.episode_id) for e in episodes]",
           "self.ids = [e.episode_id for e in episodes]", ("tests/test_navsim_http_policy.py",)),
    Mutant("every profile observes the pose", "sagebench/navsim/profiles.py",
           "extra = tuple(k for k in PRIVILEGED if k in privileged)",
           'extra = tuple(k for k in PRIVILEGED if k in (*privileged, "pose"))', ("tests/test_navsim_profiles.py",)),
    Mutant("a policy request's timeout is per socket read", "sagebench/http_client.py",
           "        self._timer.start()\n", "", ("tests/test_navsim_http_policy.py", "tests/test_http_client.py")),
    Mutant("the watchdog holds no socket to cut (a closing reply takes conn.sock away before its body is read)",
           "sagebench/http_client.py", "            self._socks.append(sock)", "            pass",
           ("tests/test_navsim_http_policy.py",)),
    Mutant("a policy reply cut short is sent again", "sagebench/http_client.py",
           "retry = isinstance(cause, CONNECTION_ERRORS)", "retry = True",
           ("tests/test_navsim_http_policy.py", "tests/test_http_client.py")),
    Mutant("an HTTP error status is retried", "sagebench/navsim/http_policy.py",
           'raise HTTPFailure(client.clean(f"HTTP {reply.status} {reply.reason}{said(reply.body)}"), kind="status")',
           'raise HTTPFailure(client.clean(f"HTTP {reply.status} {reply.reason}{said(reply.body)}"), kind="status",'
           ' retry=True)',
           ("tests/test_navsim_http_policy.py",)),
    Mutant("resume keeps a torn last line", "sagebench/navsim/journal.py",
           'whole = text[: text.rfind("\\n") + 1]', "whole = text", ("tests/test_navsim_journal.py",)),
    Mutant("evaluate scores a rollout's unasked episodes too", "sagebench/stages/evaluate.py",
           "asked_only = record is not None and not config.all_episodes", "asked_only = False",
           ("tests/test_cli_rollout.py",)),
    Mutant("turning beside a wall counts as contact (simulator)", "sagebench/navsim/simulator.py",
           "np.where(translating, np.maximum(motion.intensity, near), motion.intensity)",
           "np.maximum(motion.intensity, near)", ("tests/test_env.py",)),
    Mutant("a derived turn in place counts the contact around it", "sagebench/evaluation/intensity.py",
           "np.where(pure_turns(p, min_step=tol), 0.0, n)", "n", ("tests/test_evaluation_intensity.py",)),
    Mutant("a blocked turn costs nothing", "sagebench/navsim/motion.py",
           "np.where(turning, 1.0 - share, 0.0)", "0.0", ("tests/test_navsim_motion.py",)),
    Mutant("a user's folder taken for a run", "sagebench/run_folder.py",
           "    if not foreign:\n        return\n", "    if True:\n        return\n",
           ("tests/test_run_folder.py::test_a_users_folder_comes_out_byte_identical",)),
    Mutant("the run lock opened through a link", "sagebench/run_lock.py",
           "    if before is not None and not stat.S_ISREG(before.st_mode):\n", "    if False:\n",
           ("tests/test_run_folder.py::test_a_lock_that_is_not_sagebench_s_is_refused_and_its_target_kept",)),
    Mutant("the HTTP client follows redirects", "sagebench/http_client.py",
           "urllib.request.ProxyHandler(self._proxies), _NoRedirect(),", "urllib.request.ProxyHandler(self._proxies),",
           ("tests/test_fuzz_safety.py::test_the_api_key_reaches_no_file_log_or_other_host",
            "tests/test_http_client.py::test_a_redirect_is_not_followed_and_names_where_it_pointed")),
    Mutant("an HTTP reply with a Content-Length past the size bound is read whole", "sagebench/http_client.py",
           "            if raw.length > self.max_bytes:\n", "            if False:\n", ("tests/test_http_client.py",)),
    Mutant("JSON replies parsed however deep they nest", "sagebench/http_client.py",
           "        if depth > MAX_JSON_DEPTH:\n", "        if False:\n",
           ("tests/test_http_client.py", "tests/test_navsim_http_policy.py")),
    Mutant("the key's value left in server replies", "sagebench/http_client.py",
           "            text = text.replace(secret, REDACTED)\n", "            pass\n",
           ("tests/test_fuzz_safety.py::test_the_api_key_reaches_no_file_log_or_other_host",)),
    Mutant("the response format decided anew by every request", "sagebench/instructions/llm_client.py",
           "            self._format = fmt\n", "            pass\n", ("tests/test_instructions_llm_client.py",)),
    Mutant("validate trusts whatever shards are left", "sagebench/stages/validate.py",
           'not check_listed(run_dir, [f"{EPISODES}/{scene_id}/", f"{SCENES}/{scene_id}/"])', "False",
           ("tests/test_fuzz_safety.py::test_validate_checks_the_content_it_reads",)),
    Mutant("a failed stage's old outputs stay listed", "sagebench/pipeline/run.py",
           "            drop_stale_outputs(run_dir, sid, o.stage)\n", "            pass\n",
           ("tests/test_fuzz_safety.py::test_a_failed_llm_run_leaves_no_stale_shards_listed",)),
    Mutant("an export written into the run", "sagebench/run_folder.py",
           "    if real_out.is_relative_to(real_run):\n", "    if False:\n",
           ("tests/test_run_folder.py::test_an_export_never_writes_into_the_run_a_users_folder_or_a_locked_one",)),
    Mutant("an export written over a user's folder", "sagebench/run_folder.py",
           "        if not os.path.lexists(d / marker) and any(", "        if False and any(",
           ("tests/test_run_folder.py::test_an_export_never_writes_into_the_run_a_users_folder_or_a_locked_one",)),
    Mutant("a file output written into a run", "sagebench/run_folder.py",
           "    if not rel or rel[0] not in (*FILE_COMMAND_WRITES.get(command, ()), *_declared(run)):\n",
           "    if False:\n",
           ("tests/test_run_folder.py::test_a_file_output_never_lands_in_a_run_or_on_a_users_file",)),
    Mutant("--force replaces an input", "sagebench/run_folder.py", "            if how:\n", "            if False:\n",
           ("tests/test_run_folder.py::test_force_never_replaces_an_input_or_a_folder_above_one",)),
    Mutant("a user's file replaced without --force", "sagebench/run_folder.py",
           "    if force or (stat.S_ISREG(st.st_mode) and (st.st_size == 0 or out.ours(Path(out.path)))):\n",
           "    if True:\n",
           ("tests/test_run_folder.py::test_sidecars_are_claimed_and_sagebench_s_own_outputs_are_replaced",)),
    Mutant("two rollouts share a results file", "sagebench/run_folder.py",
           "            with results_lock(out.path):\n", "            with contextlib.nullcontext():\n",
           ("tests/test_run_folder.py::test_a_second_writer_of_a_results_file_is_refused",)),
    Mutant("the project's config and inputs taken for the user's", "sagebench/run_folder.py",
           "        elif name not in LAYOUT_NAMES and _only(Path(e.path), mine):\n", "        elif False:\n",
           ("tests/test_run_folder.py::test_a_project_folder_of_its_config_and_inputs_takes_the_run",)),
    Mutant("a cp -al copy's lock refused", "sagebench/run_lock.py",
           " if st.st_nlink != 1 and not _a_lock(fd, st)", " if st.st_nlink != 1",
           ("tests/test_run_folder.py::test_a_cp_al_copy_of_a_finished_run_takes_a_writer_and_the_original_is_untouched",)),
    Mutant("a cp -al copy's lock written through", "sagebench/run_lock.py",
           "            if mine.st_nlink == 1:\n", "            if True:\n",
           ("tests/test_run_folder.py::test_a_cp_al_copy_of_a_finished_run_takes_a_writer_and_the_original_is_untouched",)),
    Mutant("a split from a file names a shard", "sagebench/episodes/shards.py", "    if bad is not None:",
           "    if False:", ("tests/test_episodes.py::test_a_split_that_is_not_a_split_name_never_names_a_file",)),
    Mutant("import-sage-episodes writes a run unclaimed", "sagebench/cli.py",
           '    with claim_run_dir(run, "import-sage-episodes", force=force):\n', "    if True:\n",
           ("tests/test_run_folder.py::test_import_sage_episodes_never_writes_a_run_another_command_holds",)),
    Mutant("export-sage writes over a user's folder", "sagebench/cli.py",
           '    with claim_export_dir(out, run_dir, "export-sage", MARKER):\n', "    if True:\n",
           ("tests/test_run_folder.py::test_export_sage_goes_again_into_its_own_output_and_never_over_a_users_file",)),
    Mutant("a mesh's face count not read from its header", "sagebench/scene/mesh_budget.py",
           "    if faces is not None and faces > MAX_MESH_FACES:\n", "    if False:\n",
           ("tests/test_fuzz_safety.py::test_scene_inputs_that_raised_are_one_line",)),
    Mutant("a policy retry's backoff sleeps past the request's deadline", "sagebench/http_client.py",
           "n + 1 == attempts or (deadline is not None and time.monotonic() + pause >= deadline):",
           "n + 1 == attempts:",
           ("tests/test_navsim_http_policy.py", "tests/test_http_client.py")),
    Mutant("export-training resumes over a run whose Gaussians changed", "sagebench/training/export.py",
           "files += [scene / GAUSSIANS, scene / TOPDOWN,", "files += [scene / TOPDOWN,",
           ("tests/test_cli_export_training.py::test_a_resume_over_changed_gaussians_or_at_another_size_is_refused"
            "[gaussians]",)),
    Mutant("export-training resumes at another image size", "sagebench/training/export.py",
           'NOT_IN_SHARDS = {"renderer", "batch", "workers", "navila"}',
           'NOT_IN_SHARDS = {"renderer", "batch", "workers", "navila", "width", "height"}',
           ("tests/test_cli_export_training.py::test_a_resume_over_changed_gaussians_or_at_another_size_is_refused"
            "[size]",)),
    Mutant("an InteriorGS door opening takes the farthest door label in reach", "sagebench/importers/interiorgs.py",
           "door = min(near, key=lambda n: n[:2])[2]", "door = max(near, key=lambda n: n[:2])[2]",
           ("tests/test_importers_interiorgs_structure.py",)),
    Mutant("the VLN-CE server evicts the agent it just made once its table is full", "sagebench/adapters/vlnce.py",
           "self.table.popitem(last=False)", "self.table.popitem()",
           ("tests/test_adapters_vlnce.py::"
            "test_a_full_agent_table_lets_the_least_recently_asked_agent_go_never_the_new_one",)),
    Mutant("the VLN-CE server acts again on a retried step", "sagebench/adapters/vlnce.py",
           "            if step == episode.step:\n                return episode.reply\n", "",
           ("tests/test_adapters_vlnce.py::test_a_repeated_step_gets_its_first_answer_and_the_agent_acts_once",
            "tests/test_adapters_vlnce.py::test_a_lost_reply_changes_nothing")),
    Mutant("a single VLN-CE agent object serves two episodes at once", "sagebench/adapters/vlnce.py",
           "if not self.fresh and self.latest != eid:", "if False:",
           ("tests/test_adapters_vlnce.py::test_one_agent_object_behind_a_server_refuses_a_second_episode_at_once",)),
    Mutant("solid spans dropped from occupancy", "sagebench/topdown/occupancy.py",
           "    out |= _solid_spans(tris, part, grid, z_lo, z_hi)\n", "", ("tests/test_topdown_occupancy.py",)),
)


def _copy(dest: Path) -> None:
    for name in COPIED:
        src = ROOT / name
        if src.is_dir():  # without numba's caches: they miss changes to constants imported from other modules
            shutil.copytree(src, dest / name, symlinks=True, ignore=shutil.ignore_patterns("*.nbi", "*.nbc"))
        elif src.exists():
            shutil.copy2(src, dest / name)


def _pytest(copy: Path, tests: tuple[str, ...]) -> tuple[bool, float, str]:
    env = os.environ | {"PYTHONPATH": str(copy)}
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", "-p", "no:xdist",
                           *tests], cwd=copy, env=env, capture_output=True, text=True)
    return proc.returncode == 0, time.perf_counter() - start, proc.stdout[-2000:] + proc.stderr[-2000:]


def _first_failure(log: str) -> str:
    """The test that failed first (pytest's short summary line), for the report."""
    lines = [ln.split(" - ")[0].removeprefix("FAILED ") for ln in log.splitlines() if ln.startswith("FAILED ")]
    return f"by {lines[0]}" if lines else "(the run failed before a test did: see pytest)"


def _check_imports_from(copy: Path) -> None:
    env = os.environ | {"PYTHONPATH": str(copy)}
    where = subprocess.run([sys.executable, "-c", "import sagebench; print(sagebench.__file__)"], cwd=copy, env=env,
                           capture_output=True, text=True, check=True).stdout.strip()
    if not Path(where).is_relative_to(copy):
        sys.exit(f"mutants: the copy's tests import sagebench from {where}, not from the copy")


def main(names: list[str]) -> int:
    chosen = [m for m in MUTANTS if not names or m.name in names]
    if names and len(chosen) != len(names):
        sys.exit(f"mutants: unknown name among {names}; known: {[m.name for m in MUTANTS]}")
    survivors, broken = [], []
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="sagebench-mutants-") as tmp:
        clean = Path(tmp) / "clean"
        _copy(clean)
        _check_imports_from(clean)
        tests = tuple(sorted({t for m in chosen for t in m.tests}))
        ok, seconds, log = _pytest(clean, tests)
        print(f"{'unmutated':<52} {'pass' if ok else 'FAIL':>8} {seconds:6.1f} s")
        if not ok:
            print(log)
            return 1
        for i, m in enumerate(chosen):
            copy = Path(tmp) / f"m{i}"
            _copy(copy)
            target = copy / m.path
            text = target.read_text()
            if text.count(m.old) != 1:
                broken.append(m.name)
                print(f"{m.name:<52} {'NO MATCH':>8}   ({m.path}: the snippet occurs {text.count(m.old)} times)")
                continue
            target.write_text(text.replace(m.old, m.new))
            passed, seconds, log = _pytest(copy, m.tests)
            by = " ".join(m.tests) if passed else _first_failure(log)
            print(f"{m.name:<52} {'SURVIVED' if passed else 'killed':>8} {seconds:6.1f} s  {by}", flush=True)
            if passed:
                survivors.append(m.name)
            shutil.rmtree(copy)
    print(f"{len(chosen) - len(survivors) - len(broken)} of {len(chosen)} mutants killed "
          f"in {time.perf_counter() - start:.0f} s (load average {os.getloadavg()[0]:.1f})"
          + (f"; survived: {', '.join(survivors)}" if survivors else "")
          + (f"; no longer apply: {', '.join(broken)}" if broken else ""))
    return 1 if survivors or broken else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
