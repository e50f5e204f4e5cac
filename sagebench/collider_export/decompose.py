"""Convex collider parts for a set of meshes: exact convex pieces directly, concave pieces by their mode's methods."""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from sagebench.collider_export.coacd_cache import PartCache, PieceResult, split_key
from sagebench.collider_export.convex import ConvexPart, ConvexSplit, merge_parts, split_convex, weld
from sagebench.collider_export.fanout import map_processes
from sagebench.collider_export.methods import band_error_cm, ladder, part_budget
from sagebench.collider_export.pieces import Piece, decompose_pieces
from sagebench.collider_export.quality import BandReach
from sagebench.collider_export.vertex_limit import within_vertex_limit
from sagebench.settings.export_usd import ColliderSettings


WHOLE_MESH_FACTOR = 4


@dataclass(frozen=True)
class MeshColliders:
    """All convex parts of one mesh (in the mesh file's frame) and where they came from."""

    parts: list[ConvexPart]
    exact_parts: int  # parts that are convex pieces of the mesh itself
    pieces: list[PieceResult]  # one per concave piece, in mesh order (or one for the whole mesh, see `whole`)
    whole: bool = False  # the mesh had far too many pieces: one voxel collider for all of it
    merged: int = 0  # parts merged away to keep within the part budget


def decompose_meshes(
    meshes: Mapping[str, tuple[np.ndarray, np.ndarray]],
    settings: ColliderSettings,
    *,
    cache: PartCache,
    workers: int = 1,
    convex_tolerance: float = 0.002,
    band: tuple[float, float],
) -> dict[str, MeshColliders]:
    """Parts for each named mesh (vertices [V, 3], faces [F, 3]); all concave pieces share one batch of workers.
    `band` is the agent's (bottom, top) as z in the meshes' frame, m.

    A mesh with more parts than `settings.max_parts` gets its closest parts merged, within the band tolerance
    of its footprint where possible (merge_to_budget); one with more than WHOLE_MESH_FACTOR times that many
    pieces (a plant of a thousand leaves) becomes one voxel collider of the whole mesh within the budget.
    `quality` keeps balanced's parts for a mesh where they are closer in the band (or as close in fewer parts):
    CoACD's parts merged to the budget were once 5 cm off where balanced's were 2. Every part keeps within
    PhysX's hull vertex limit (vertex_limit), so USD and MJCF collide with the same hulls.
    """
    runs = [_decompose(meshes, s, cache=cache, workers=workers, convex_tolerance=convex_tolerance,
                       band=band) for s in mode_passes(settings)]
    if len(runs) == 1:
        return runs[0]
    return {name: min((run[name] for run in runs),
                      key=lambda mc: (band_error_cm(*meshes[name], mc.parts, band), len(mc.parts)))
            for name in meshes}


def mode_passes(settings: ColliderSettings) -> tuple[ColliderSettings, ...]:
    """The settings decompose_meshes decomposes with, one pass each: `quality` runs balanced's pass too."""
    if settings.mode != "quality":
        return (settings,)
    return settings, settings.model_copy(update={"mode": "balanced"})


def _decompose(meshes: Mapping[str, tuple[np.ndarray, np.ndarray]], settings: ColliderSettings, *, cache: PartCache,
               workers: int, convex_tolerance: float, band: tuple[float, float]) -> dict[str, MeshColliders]:
    """decompose_meshes by the one mode `settings.mode`."""
    plan = plan_pieces(meshes, settings, cache=cache, convex_tolerance=convex_tolerance, workers=workers)
    results = iter(decompose_pieces(plan.jobs, settings, cache=cache, workers=workers, band=band))
    out: dict[str, MeshColliders] = {}
    for name, split in plan.splits.items():
        if name in plan.over:
            result = next(results)
            out[name] = MeshColliders(within_vertex_limit(result.parts), 0, [result], whole=True)
            continue
        pieces = [next(results) for _ in split.concave]
        parts = list(split.parts) + [p for r in pieces for p in r.parts]
        budget = object_budget(pieces, settings)
        kept = merge_to_budget(parts, meshes[name], settings, band, budget) if len(parts) > budget else parts
        exact = len(split.parts) if kept is parts else 0
        out[name] = MeshColliders(within_vertex_limit(kept), exact, pieces, merged=len(parts) - len(kept))
    return {name: out[name] for name in meshes}


@dataclass(frozen=True)
class PiecePlan:
    """How named meshes split: exact parts and concave pieces per mesh, the meshes too split up to decompose
    piece by piece, and the jobs for decompose_pieces (mesh order, each mesh's pieces in order)."""

    splits: dict[str, ConvexSplit]
    over: frozenset[str]
    jobs: list[Piece]


def plan_pieces(meshes: Mapping[str, tuple[np.ndarray, np.ndarray]], settings: ColliderSettings, *,
                cache: PartCache, convex_tolerance: float = 0.002, workers: int = 1) -> PiecePlan:
    """The pieces decompose_meshes runs, without running them (a run spreads them over its executor); the
    meshes not split before (`cache`) are split on up to `workers` processes."""
    splits = split_meshes(meshes, cache, tolerance=convex_tolerance, workers=workers)
    over = {name for name, s in splits.items()
            if len(s.parts) + len(s.concave) > WHOLE_MESH_FACTOR * settings.max_parts}
    jobs = []  # one batch, so the whole-mesh jobs run beside the pieces (biggest first)
    for name, split in splits.items():
        if name in over:
            jobs.append(Piece(f"{name} (whole mesh: {len(split.parts) + len(split.concave)} pieces)",
                              *weld(*meshes[name]), ("voxel",)))
        else:
            jobs += [Piece(piece_name(name, k), pv, pf, ladder(settings, len(pf)))
                     for k, (pv, pf) in enumerate(split.concave)]
    return PiecePlan(splits, frozenset(over), jobs)


def piece_name(mesh: str, k: int) -> str:
    """How messages name a mesh's k-th concave piece."""
    return f"{mesh} (concave piece {k})"


def object_budget(pieces: list[PieceResult], settings: ColliderSettings) -> int:
    """The parts a mesh may keep: the part budget, or the last resort's where one of its pieces needed it."""
    return max((part_budget(p.method, settings) for p in pieces), default=settings.max_parts)


def split_meshes(meshes: Mapping[str, tuple[np.ndarray, np.ndarray]], cache: PartCache, *, tolerance: float,
                 workers: int = 1) -> dict[str, ConvexSplit]:
    """convex.split_convex of each named mesh (vertices [V, 3], faces [F, 3]), read from `cache` where split
    before, else split on up to `workers` processes and cached."""
    keys = {name: split_key(v, f, tolerance) for name, (v, f) in meshes.items()}
    out = {name: cache.get_split(key) for name, key in keys.items()}
    todo = [name for name, split in out.items() if split is None]
    split = functools.partial(split_convex, tolerance=tolerance)
    for name, made in zip(todo, map_processes(split, [meshes[n] for n in todo], workers=workers,
                                              sizes=[len(meshes[n][1]) for n in todo])):
        cache.put_split(keys[name], made)
        out[name] = made
    return out


def merge_to_budget(parts: list[ConvexPart], mesh: tuple[np.ndarray, np.ndarray], settings: ColliderSettings,
                    band: tuple[float, float], budget: int) -> list[ConvexPart]:
    """`parts` of the mesh (vertices [V, 3], faces [F, 3]) merged to `budget` parts, each merge kept within
    the band tolerance of the mesh's footprint in the agent's band (z, m) where some pair allows it
    (convex.merge_parts)."""
    import trimesh

    source = trimesh.Trimesh(*mesh, process=False)
    reach = BandReach(source, np.concatenate([p.vertices for p in parts]), band)
    return merge_parts(parts, budget, band, reach=reach, tolerance=settings.band_tolerance_cm / 100)


def tolerance_cause(mesh: str, mc: MeshColliders, settings: ColliderSettings) -> str:
    """Why a mesh's colliders may miss its agent-band footprint by more than the tolerance, for the messages:
    the part budget (a whole-mesh voxel collider, a piece whose best method used every part it may, parts merged)
    or its methods (none, the escalation's included, came closer on the piece named)."""
    worst = max(range(len(mc.pieces)), key=lambda k: mc.pieces[k].band_error_cm, default=None)
    if mc.whole:
        return (f"voxelised whole at the {settings.max_parts}-part budget (--max-parts): more than "
                f"{WHOLE_MESH_FACTOR} times that many pieces")
    if worst is not None and mc.pieces[worst].band_error_cm > settings.band_tolerance_cm:
        piece, name = mc.pieces[worst], piece_name(mesh, worst)
        if len(piece.parts) >= part_budget(piece.method, settings):
            return f"{piece.method} parts of its piece {name} at the {budget_text([piece], settings)}"
        return (f"no method of --colliders {settings.mode} came closer on its piece {name} (best: {piece.method}, "
                f"{piece.band_error_cm:.1f} cm in {len(piece.parts)} parts)")
    if mc.merged:
        return f"{mc.merged} parts merged at the {budget_text(mc.pieces, settings)}"
    return "each of its pieces is within it on its own; the parts together are not"


def budget_text(pieces: list[PieceResult], settings: ColliderSettings) -> str:
    """`32-part budget (--max-parts)`, or the last resort's where one of `pieces` needed it."""
    budget = object_budget(pieces, settings)
    return f"{budget}-part budget ({'--max-parts' if budget == settings.max_parts else '--exact-max-parts'})"
