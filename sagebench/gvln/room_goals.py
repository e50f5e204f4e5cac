"""An object to name as the `end` of an episode whose goal is a room, so that SAGE-Bench can score it.

SAGE-Bench's ObjectBasedSuccessEvaluator (object_based_success.py) looks the first instruction's `end` up among
its semantic map's item ids (objects, walls, "unable areas": never rooms) and counts an agent there when it stands
in that item's box grown by 1 m; an `end` it cannot find sends it to a guess (the likeliest object within 2 m of
the path's end, else the distance to that end). So a room goal is written as the object nearest the goal point
whose box, grown by SAGE_REACH_M less BOX_SLACK_M, holds it; a room goal with none such is left out of the export.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from sagebench.episodes.tasks import VLN, row_task
from sagebench.scene.model import UNLABELLED
from sagebench.topdown.semantic_map import SemanticMap

SAGE_REACH_M = 1.0  # the evaluator's expansion_radius
# what SAGE's box (its mask cells' extent, rounded to 2 decimals, its frame's offset) may lose against the mesh's
BOX_SLACK_M = 0.1


def object_boxes(smap: SemanticMap, names: dict[int, str]) -> tuple[list[int], np.ndarray]:
    """The instance ids of the objects SAGE names (`names`: sagebench.gvln.episodes.item_names) and their [K, 2, 2]
    world boxes [[x, y] min, [x, y] max]."""
    found = [(i.instance_id, i.bbox_m) for i in smap.instances
             if i.kind == "object" and i.category != UNLABELLED and i.instance_id in names]  # SAGE's map has none
    boxes = np.array([[lo[:2], hi[:2]] for _, (lo, hi) in found], dtype=np.float64).reshape(-1, 2, 2)
    return [iid for iid, _ in found], boxes


def goal_object(goal_xy: Sequence[float], ids: list[int], boxes: np.ndarray) -> int | None:
    """The object whose box the world point `goal_xy` is nearest to (per axis, as the evaluator's test is), when
    within SAGE_REACH_M - BOX_SLACK_M of it; None when none is."""
    if not ids:
        return None
    p = np.asarray(goal_xy[:2], dtype=np.float64)
    away = np.maximum(boxes[:, 0] - p, p - boxes[:, 1]).max(axis=1)  # < 0 inside, by the depth
    k = int(np.argmin(away))
    return ids[k] if away[k] <= SAGE_REACH_M - BOX_SLACK_M else None


def room_goal_ends(rows: Sequence[dict[str, Any]], smap: SemanticMap, names: dict[int, str]
                   ) -> tuple[dict[str, int], set[str]]:
    """For the vln trajectories of `rows` whose goal is a room (no goal instance; the other tasks' goals are a
    category, a point or none, and SAGE's task files carry them as such): the object to name as their end, by
    trajectory id, and the ids of those with none near."""
    ids, boxes = object_boxes(smap, names)
    ends: dict[str, int] = {}
    none: set[str] = set()
    for row in rows:
        tid = row["trajectory_id"]
        if row["goal_instance_id"] is not None or row_task(row) != VLN or tid in ends or tid in none:
            continue
        found = goal_object(row["goal_position"], ids, boxes)
        if found is None:
            none.add(tid)
        else:
            ends[tid] = found
    return ends, none
