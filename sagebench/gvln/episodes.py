"""sagebench episode rows <-> SAGE-3D's GVLN trajectory file, as `save_trajectory_file` writes it (after
`trajectory_2d_to_3d.py`, whose 3D frame SAGE-Bench's simulator reads) and `episodes_adapter.py` reads it.

    {"dataset_metadata": {"name": "GVLN"},
     "scenes": [{"scene_id": 0, "scene_name": "<the scene key's part after its last '_'>", "samples": [
        {"trajectory_id": "...",
         "instructions": [{"instruction_type", "start", "end", "generated_instruction", "scene_id"}, ...],
         "points": [{"point": "0", "position": [x, y, z], "rotation": [qx, qy, qz, qw], "action": [], ...}, ...]}]}]}

One sample per trajectory, one instruction per episode row; the adapter makes episode "<trajectory_id>-<k>"
of instruction k, starting at the first point's position and rotation, its goal the last point. `start` and
`end` name objects as SAGE-3D's item ids do: "<category>_<k>", k counting the scene's objects of that category
(doors and windows included) from 1 in instance-id order. Frames: sagebench.gvln.frame.

What SAGE-3D's format has no field for (row ids, split, goal radius, instance ids, rooms, level, source, seed)
goes under a "sagebench" key of the sample or instruction, which SAGE-3D's reader ignores; reading a file
without it, rows get ids hashed from the scene and SAGE's trajectory id, rooms from the room polygons, instance
ids from the item names. Read values are checked as generated rows are (rows_from_gvln), and path points are put
on the scene's navigable map.
"""

from __future__ import annotations

import hashlib
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import shapely
from pydantic import (
    AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field, ValidationError, field_validator, model_validator,
)

from sagebench.episodes.ids import episode_id
from sagebench.episodes.task_rows import SceneMap, category_viewpoints, cell_points
from sagebench.episodes.tasks import NOGOAL_INSTRUCTION, VLN, goal_image_recipe, pointgoal_polar, row_task
from sagebench.errors import DataError, first_error
from sagebench.gvln.frame import SAGE_Z, sage_rotation, to_sage_xy, wrap, yaw_from_sage_rotation
from sagebench.gvln.tasks import GOAL_LESS, TASK_KEYS, sage_task_fields, sample_task
from sagebench.input_files import read_json
from sagebench.metrics.on_foot import NavigableMap
from sagebench.scene.model import SceneSpec
from sagebench.settings.shared import Split, Task
from sagebench.topdown.semantic_map import SemanticMap

ITEM_KINDS = ("object", "door", "window")
# sagebench's instruction types -> SAGE-3D's spelling (prompt_traj_to_instruction.json); the rest are the same
TO_SAGE_TYPE = {"Attribute_Based": "Attribute-based", "Area_Based": "Area-based"}
# SAGE-3D's types -> (level, type) in sagebench; "Default" is its fallback "Navigate from A to B." (a goal only)
FROM_SAGE_TYPE = {
    "Add_Object": ("high", "Add_Object"), "Scenario_Driven": ("high", "Scenario_Driven"),
    "Relative_Relationship": ("high", "Relative_Relationship"), "Attribute-based": ("high", "Attribute_Based"),
    "Attribute_Based": ("high", "Attribute_Based"), "Area-based": ("high", "Area_Based"),
    "Area_Based": ("high", "Area_Based"), "Default": ("low", "Single_Goal"), "Single_Goal": ("low", "Single_Goal"),
    "Base_Action": ("low", "Base_Action"),
}
# the camera fields SAGE-3D's trajectory generator gives every point (its training-data scripts read them)
POINT_CAMERA = {"action": [], "camera_images": [], "focal_length": 7.0, "horizontal_aperture": 20.954999923706055,
                "vertical_aperture": 20.954999923706055, "focus_distance": 0.0, "clipping_range": [1.0, 1000000.0]}
SAGE_SOURCE = "sage-bench"  # instruction_source of rows read from a file without sagebench's own


def scene_name(scene_id: str) -> str:
    """SAGE-3D's `scene_name`: the scene key's part after its last '_' (save_trajectory_file's tail_id)."""
    return scene_id.split("_")[-1]


def item_names(spec: SceneSpec) -> dict[int, str]:
    """instance id -> SAGE-3D item id "<category>_<k>" of every object, door and window."""
    counts: Counter[str] = Counter()
    out = {}
    for obj in sorted(spec.objects, key=lambda o: o.instance_id):
        if obj.kind in ITEM_KINDS:
            counts[obj.category] += 1
            out[obj.instance_id] = f"{obj.category}_{counts[obj.category]}"
    return out


def gvln_document(scene_id: str, rows: Sequence[dict[str, Any]], spec: SceneSpec,
                  ends: dict[str, int] | None = None) -> dict[str, Any]:
    """The GVLN file of one scene's episode rows (in their order; a trajectory's rows grouped into one sample);
    `ends`: the object to name as the end of a trajectory whose goal is a room (sagebench.gvln.room_goals)."""
    names, ends = item_names(spec), ends or {}
    samples: dict[str, dict[str, Any]] = {}
    for row in rows:
        tid = row["trajectory_id"]
        if tid not in samples:
            samples[tid] = _sample(row, spec)
        if row["instruction_text"] is None:
            if row_task(row) != VLN:  # a goal task's episode without an instruction: its id kept on the sample
                samples[tid]["sagebench"]["episode_id"] = row["episode_id"]
            continue
        kind = row["instruction_type"]
        samples[tid]["instructions"].append({
            "instruction_type": GOAL_LESS if row_task(row) == "nogoal" else TO_SAGE_TYPE.get(kind, kind) or "",
            "start": names.get(row["start_instance_id"], row["start_room"] or ""),
            "end": names.get(row["goal_instance_id"] or ends.get(tid), row["goal_room"] or ""),
            "generated_instruction": row["instruction_text"],
            "scene_id": scene_id,
            "sagebench": {"episode_id": row["episode_id"], "instruction_level": row["instruction_level"],
                          "instruction_type": kind, "instruction_source": row["instruction_source"]},
        })
    return {"dataset_metadata": {"name": "GVLN"},
            "scenes": [{"scene_id": 0, "scene_name": scene_name(scene_id), "samples": list(samples.values())}]}


def _sample(row: dict[str, Any], spec: SceneSpec) -> dict[str, Any]:
    floor = spec.floor_height
    path = np.asarray(row["reference_path"], dtype=np.float64).reshape(-1, 4)
    xy = to_sage_xy(path[:, :2], spec.sage_offset)
    points = []
    for j, (p, yaw) in enumerate(zip(xy, path[:, 3])):
        last = j == len(path) - 1
        points.append({"point": str(j), "position": [float(p[0]), float(p[1]), floor + SAGE_Z],
                       "rotation": [0.0, 0.0, 0.0, 1.0] if last and len(path) > 1 else sage_rotation(float(yaw)),
                       **POINT_CAMERA})
    keep = ("trajectory_id", "goal_radius", "start_instance_id", "goal_instance_id", "start_room",
            "goal_room", "split", "seed")
    sample = {"trajectory_id": row["trajectory_id"], "instructions": [], "points": points,
              "sagebench": {k: row.get(k) for k in keep}}
    if row_task(row) != VLN:
        sample["sagebench"].update({k: row.get(k) for k in TASK_KEYS})
        if row_task(row) == "nogoal":
            sample["sagebench"]["goal_radius"] = None  # no goal: no radius
        sample.update(sage_task_fields(row, floor, spec.sage_offset))
    return sample


# ---------------------------------------------------------------- reading

SNAP_M = 0.5  # a path point off the navigable map moves to the nearest navigable cell this near; farther, it is refused
Finite = Annotated[float, Field(allow_inf_nan=False)]
Hex16 = Annotated[str, Field(pattern=r"^[0-9a-f]{16}$")]  # a trajectory or episode id as sagebench makes them
Name = Annotated[str, Field(min_length=1, max_length=256, pattern=r"^[^\x00-\x1f\x7f]+$")]
Xyz = Annotated[list[Finite], Field(min_length=3, max_length=3)]
InstanceId = Annotated[int, Field(ge=1, le=2**31 - 1)]  # the episode shard's int32
LEVEL_OF_TYPE = {kind: level for level, kind in FROM_SAGE_TYPE.values()}  # sagebench's instruction types


def _said(text: str) -> str:
    if not text.strip():
        raise ValueError("an empty instruction")
    return text


def _as_instruction(item: Any) -> Any:
    """An instruction given as a bare string (SAGE-3D's older files) as the object it stands for."""
    return {"generated_instruction": item} if isinstance(item, str) else item


class _Model(BaseModel):
    model_config = ConfigDict(extra="ignore", frozen=True)


class _Point(_Model):
    position: list[Finite]
    rotation: list[Finite]

    @field_validator("position")
    @classmethod
    def _xyz(cls, v: list[float]) -> list[float]:
        if len(v) != 3:
            raise ValueError(f"{len(v)} numbers; a position is [x, y, z]")
        return v

    @field_validator("rotation")
    @classmethod
    def _xyzw(cls, v: list[float]) -> list[float]:
        if len(v) != 4:
            raise ValueError(f"{len(v)} numbers; a rotation is [qx, qy, qz, qw]")
        return v


class _InstructionExtra(_Model):
    """An instruction's "sagebench" entry, as gvln_document writes it."""

    episode_id: Hex16 | None = None
    instruction_level: Literal["low", "high"] | None = None
    instruction_type: Literal[tuple(LEVEL_OF_TYPE)] | None = None  # type: ignore[valid-type]
    instruction_source: Name | None = None

    @model_validator(mode="after")
    def _level_of_type(self) -> _InstructionExtra:
        kind = self.instruction_type
        if kind is not None and self.instruction_level not in (None, LEVEL_OF_TYPE[kind]):
            raise ValueError(f"instruction_level {self.instruction_level!r}, but {kind} is a "
                             f"{LEVEL_OF_TYPE[kind]}-level type")
        return self


class _Instruction(_Model):
    instruction_type: str = ""
    start: str = ""
    end: str = ""
    generated_instruction: Annotated[str, AfterValidator(_said)]
    sagebench: _InstructionExtra | None = None


class _SampleExtra(_Model):
    """A sample's "sagebench" entry, as gvln_document writes it: checked as the rows it becomes are when generated."""

    trajectory_id: Hex16 | None = None
    goal_radius: Annotated[float, Field(gt=0, allow_inf_nan=False)] | None = None
    start_instance_id: InstanceId | None = None
    goal_instance_id: InstanceId | None = None
    start_room: Name | None = None
    goal_room: Name | None = None
    split: Split | None = None  # the --split type: part of the shards' file names
    seed: Annotated[int, Field(ge=0, le=2**63 - 1)] | None = None
    task: Task | None = None
    episode_id: Hex16 | None = None  # of a task's episode without an instruction
    budget_s: Annotated[float, Field(gt=0, allow_inf_nan=False)] | None = None
    budget_steps: Annotated[int, Field(ge=1, le=2**31 - 1)] | None = None
    goal_category: Name | None = None
    goal_instance_ids: Annotated[list[InstanceId], Field(min_length=1)] | None = None
    goal_viewpoints: Annotated[list[Xyz], Field(min_length=1)] | None = None
    goal_polar: Annotated[list[Finite], Field(min_length=2, max_length=2)] | None = None
    goal_yaw: Finite | None = None
    goal_image: Name | None = None


class _Sample(_Model):
    trajectory_id: str | int = "0"
    instructions: list[Annotated[_Instruction, BeforeValidator(_as_instruction)]] = Field(default_factory=list)
    points: Annotated[list[_Point], Field(min_length=1, description="A path: its start, and its goal but for no-goal.")]
    sagebench: _SampleExtra | None = None
    # the fields SAGE-Bench's task classes read (task_types.py), SAGE's 3D frame
    task_type: str | None = None
    target_object: Name | None = None
    target_object_position: Xyz | None = None
    goal_position: Xyz | None = None
    target_image: Name | None = None
    target_image_position: Xyz | None = None


class _Scene(_Model):
    scene_name: str = "scene"
    samples: list[_Sample] = Field(default_factory=list)


class _File(_Model):
    scenes: Annotated[list[_Scene], Field(min_length=1)]


@dataclass(frozen=True)
class GvlnScene:
    path: Path
    scene_name: str
    samples: tuple[_Sample, ...]


def read_gvln(path: Path) -> GvlnScene:
    """The first scene of a GVLN file (the only one SAGE-3D's adapter reads), checked."""
    raw = read_json(path)
    try:
        doc = _File.model_validate(raw)
    except ValidationError as err:
        loc, msg, _ = first_error(err)
        raise DataError(msg, path=path, field=loc) from None
    scene = doc.scenes[0]
    for i, sample in enumerate(scene.samples):
        for j, point in enumerate(sample.points[:-1]):
            qx, _, qz, _ = point.rotation
            if qx == 0.0 and qz != 0.0:
                raise DataError(f"rotation {point.rotation} turns about z: a trajectory in SAGE-3D's 2D map frame, "
                                "not yet moved into its 3D frame by trajectory_2d_to_3d.py", path=path,
                                field=f"scenes[0].samples[{i}].points[{j}].rotation")
    return GvlnScene(Path(path), scene.scene_name, tuple(scene.samples))


@dataclass
class GvlnRows:
    rows: list[dict[str, Any]] = field(default_factory=list)
    skipped: Counter[str] = field(default_factory=Counter)  # instructions left out, by type (no task to give them)
    snapped: int = 0  # path points moved onto the navigable map (within SNAP_M)
    snapped_ends: Counter[str] = field(default_factory=Counter)  # of them, samples' starts and goals ("start", "goal")
    snapped_max_m: float = 0.0  # the farthest any of them moved
    trajectories: dict[str, str] = field(default_factory=dict)  # id -> where it was given
    episodes: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class _Context:
    """What every sample of a file is read against: the scene, its map, and what the file does not say."""

    spec: SceneSpec
    navmap: NavigableMap
    goal_maps: tuple[SemanticMap, SceneMap]  # where an objectnav sample's goal viewpoints are found
    path: Path
    goal_radius: float
    split: str
    budget: tuple[float, int]  # a no-goal episode's time (s) and step budget

    def rooms(self) -> list[tuple[str, shapely.Polygon]]:
        return [(r.id, shapely.Polygon(r.polygon)) for r in self.spec.rooms]


def rows_from_gvln(scene: GvlnScene, spec: SceneSpec, navmap: NavigableMap, goal_maps: tuple[SemanticMap, SceneMap], *,
                   goal_radius: float, split: str, budget: tuple[float, int]) -> GvlnRows:
    """sagebench episode rows of the scene `spec` for every sample and instruction of `scene`, checked as generated
    rows are: instances and rooms of the scene, path points on its navigable map `navmap` (or moved onto it from at
    most SNAP_M away), trajectory and episode ids unique. Each sample's task is sagebench.gvln.tasks.sample_task's;
    SAGE-3D's Goal-less instructions are no-goal episodes from their sample's start (`budget`: their time and step
    budget where the file has none); an objectnav sample's goal viewpoints, where the file has none, are found on
    `goal_maps` (the scene's semantic map and gen-trajectories' map of it) as gen-trajectories finds them;
    instructions of a type sagebench does not know are left out and counted."""
    ctx, out = _Context(spec, navmap, goal_maps, scene.path, goal_radius, split, budget), GvlnRows()
    for i, sample in enumerate(scene.samples):
        where = f"scenes[0].samples[{i}]"
        extra = sample.sagebench or _SampleExtra()
        _check_names(extra, spec, scene.path, where)
        task = sample_task(extra.task, sample.model_dump(include=set(SAGE_FIELDS)),
                           [ins.instruction_type for ins in sample.instructions])
        path, moved = _reference_path(sample, spec, navmap, scene.path, where)
        if task != "nogoal" and len(path) < 2:
            raise DataError(f"1 point: a {task} sample is a path, its start and goal at least", path=scene.path,
                            field=f"{where}.points")
        _count_snapped(out, moved, task)
        tid = extra.trajectory_id or _hashed(spec.scene_id, str(sample.trajectory_id))
        given = ("sagebench.trajectory_id", tid) if extra.trajectory_id else ("trajectory_id", sample.trajectory_id)
        _unique("trajectory", tid, given[1], out.trajectories, scene.path, f"{where}.{given[0]}")
        base = _base_row(sample, extra, path, tid, ctx)
        base.update(_task_columns(task, sample, extra, base, ctx, where))
        if task == VLN:
            _vln_rows(sample, base, out, ctx, where)
        else:
            _task_rows(sample, base, out, extra.episode_id, ctx.path, where)
    return out


SAGE_FIELDS = ("task_type", "target_object", "target_object_position", "goal_position", "target_image",
               "target_image_position")


def _hashed(scene_id: str, sage_id: str, what: str = "") -> str:
    """A trajectory id for a sample of SAGE-3D's trajectory `sage_id` (`what`: its no-goal episodes)."""
    return hashlib.sha256(f"{scene_id}|sage|{sage_id}{what}".encode()).hexdigest()[:16]


def _base_row(sample: _Sample, extra: _SampleExtra, path: np.ndarray, tid: str, ctx: _Context) -> dict[str, Any]:
    """The shared columns of a sample's rows (its path's start and end, the instances and rooms there)."""
    by_name = {name: iid for iid, name in item_names(ctx.spec).items()}
    room_of_object = {o.instance_id: o.room_id for o in ctx.spec.objects}
    fields = extra.model_fields_set
    start, end = (sample.instructions[0].start, sample.instructions[0].end) if sample.instructions else ("", "")
    start_id = extra.start_instance_id if "start_instance_id" in fields else by_name.get(start)
    goal_id = extra.goal_instance_id if "goal_instance_id" in fields else by_name.get(end)
    return {
        "trajectory_id": tid, "scene_id": ctx.spec.scene_id,
        "start_instance_id": start_id, "goal_instance_id": goal_id,
        "start_room": extra.start_room if "start_room" in fields else
        (room_of_object.get(start_id) or _room_at(path[0], ctx.rooms())),
        "goal_room": extra.goal_room if "goal_room" in fields else
        (room_of_object.get(goal_id) or _room_at(path[-1], ctx.rooms())),
        "start_position": path[0, :3].tolist(), "start_yaw": float(path[0, 3]),
        "goal_position": path[-1, :3].tolist(), "goal_radius": extra.goal_radius or ctx.goal_radius,
        "reference_path": path.tolist(),
        "geodesic_distance": float(np.linalg.norm(np.diff(path[:, :2], axis=0), axis=1).sum()),
        "seed": extra.seed or 0, "split": extra.split or ctx.split,
    }


def _task_columns(task: str, sample: _Sample, extra: _SampleExtra, base: dict[str, Any], ctx: _Context,
                  where: str) -> dict[str, Any]:
    """The task's columns of a sample's rows: its "sagebench" entry's, else derived from SAGE's fields and path."""
    if task == "nogoal":
        return _nogoal_columns(base, (extra.budget_s or ctx.budget[0], extra.budget_steps or ctx.budget[1]))
    (x, y, _), (gx, gy, _) = base["start_position"], base["goal_position"]
    if task == "pointnav":
        return {"task": task, "goal_polar": extra.goal_polar or list(pointgoal_polar(x, y, base["start_yaw"], gx, gy))}
    if task == "imagenav":
        yaw = extra.goal_yaw if extra.goal_yaw is not None else base["reference_path"][-1][3]
        return {"task": task, "goal_yaw": yaw,
                "goal_image": extra.goal_image or sample.target_image or goal_image_recipe(gx, gy, yaw)}
    if task == "objectnav":
        return _objectnav_columns(sample, extra, base["goal_radius"], ctx, where)
    return {"task": task}


def _nogoal_columns(base: dict[str, Any], budget: tuple[float, int]) -> dict[str, Any]:
    """A no-goal episode from the start of `base`: no goal (its start, radius 0), its budget."""
    return {"task": "nogoal", "goal_position": base["start_position"], "goal_radius": 0.0, "geodesic_distance": 0.0,
            "reference_path": base["reference_path"][:1], "goal_instance_id": None, "goal_room": base["start_room"],
            "budget_s": float(budget[0]), "budget_steps": int(budget[1])}


def _objectnav_columns(sample: _Sample, extra: _SampleExtra, radius: float, ctx: _Context,
                       where: str) -> dict[str, Any]:
    """An ObjectNav sample's category (SAGE's target_object), every instance of it, and its goal viewpoints: the
    file's, else the main region's navigable cells within the success `radius` of any instance (SAGE's files have
    none)."""
    category = extra.goal_category or sample.target_object
    key = "sagebench.goal_category" if extra.goal_category else "target_object"
    ids = extra.goal_instance_ids or [o.instance_id for o in ctx.spec.objects if o.category == category]
    if not ids:
        raise DataError(f"category {category!r} has no instance in scene {ctx.spec.scene_id!r}", path=ctx.path,
                        field=f"{where}.{key}")
    viewpoints = extra.goal_viewpoints or _viewpoints(category, radius, ctx, f"{where}.{key}")
    return {"task": "objectnav", "goal_category": category, "goal_instance_ids": list(ids),
            "goal_viewpoints": viewpoints}


def _viewpoints(category: str, radius: float, ctx: _Context, where: str) -> list[list[float]]:
    """The goal viewpoints of `category` in the scene, as gen-trajectories finds them; none is a DataError."""
    smap, maps = ctx.goal_maps
    cells = category_viewpoints(smap, maps, category, radius)[1]
    if not len(cells):
        raise DataError(f"no navigable cell of the main region within {radius:g} m of a {category} instance: no goal "
                        "viewpoint", path=ctx.path, field=where)
    return cell_points(maps, cells)


def _vln_rows(sample: _Sample, base: dict[str, Any], out: GvlnRows, ctx: _Context, where: str) -> None:
    """One row per instruction of a VLN sample (a bare row when it has none), its Goal-less ones no-goal rows of a
    trajectory of their own (its start); instructions of an unknown type counted in `out`."""
    if not sample.instructions:
        out.rows.append({**base, "episode_id": episode_id(base["trajectory_id"], "none", "", 0),
                         "instruction_level": None, "instruction_type": None, "instruction_text": None,
                         "instruction_source": None})
    nogoal = {**base, **_nogoal_columns(base, ctx.budget),
              "trajectory_id": _hashed(base["scene_id"], base["trajectory_id"], "|nogoal")}
    counts: Counter[tuple[str, str]] = Counter()
    for k, ins in enumerate(sample.instructions):
        own = ins.sagebench or _InstructionExtra()
        if ins.instruction_type == GOAL_LESS and own.instruction_type is None:
            _add_row(out, nogoal, ins, (None, None), "nogoal", counts, f"{where}.instructions[{k}]", ctx.path)
        elif own.instruction_type is not None or ins.instruction_type in FROM_SAGE_TYPE:
            _add_row(out, base, ins, _level_type(ins), "", counts, f"{where}.instructions[{k}]", ctx.path)
        else:
            out.skipped[ins.instruction_type or "(no type)"] += 1


def _task_rows(sample: _Sample, base: dict[str, Any], out: GvlnRows, eid: str | None, path: Path,
               where: str) -> None:
    """One row per instruction of a sample of a task other than vln (one without an instruction when it has none:
    a no-goal one with SAGE-Bench's exploration instruction); an instruction's type is kept where sagebench knows it."""
    if not sample.instructions:
        text, source = (NOGOAL_INSTRUCTION, SAGE_SOURCE) if base["task"] == "nogoal" else (None, None)
        out.rows.append({**base, "episode_id": eid or episode_id(base["trajectory_id"], base["task"], "", 0),
                         "instruction_level": None, "instruction_type": None, "instruction_text": text,
                         "instruction_source": source})
    counts: Counter[tuple[str, str]] = Counter()
    for k, ins in enumerate(sample.instructions):
        _add_row(out, base, ins, _level_type(ins), base["task"], counts, f"{where}.instructions[{k}]", path)


def _level_type(ins: _Instruction) -> tuple[str | None, str | None]:
    """sagebench's level and type of an instruction (its "sagebench" entry's, else from SAGE-3D's type)."""
    own = ins.sagebench or _InstructionExtra()
    if own.instruction_type is not None:
        return LEVEL_OF_TYPE[own.instruction_type], own.instruction_type
    return FROM_SAGE_TYPE.get(ins.instruction_type, (None, None))


def _add_row(out: GvlnRows, base: dict[str, Any], ins: _Instruction, level_type: tuple[str | None, str | None],
             task: str, counts: Counter[tuple[str, str]], where: str, path: Path) -> None:
    """Append the row of instruction `ins` (at `where`) of a sample's rows `base`; its episode id unique."""
    own = ins.sagebench or _InstructionExtra()
    level, kind = level_type
    key = (level or task, kind or "")
    eid = own.episode_id or episode_id(base["trajectory_id"], *key, counts[key])
    counts[key] += 1
    _unique("episode", eid, eid, out.episodes, path, where + (".sagebench.episode_id" if own.episode_id else ""))
    out.rows.append({**base, "episode_id": eid, "instruction_level": level, "instruction_type": kind,
                     "instruction_text": ins.generated_instruction,
                     "instruction_source": own.instruction_source or SAGE_SOURCE})


def _check_names(extra: _SampleExtra, spec: SceneSpec, path: Path, where: str) -> None:
    """The instances and rooms a sample's "sagebench" entry names are the scene's."""
    ids, rooms = {o.instance_id for o in spec.objects}, {r.id for r in spec.rooms}
    for key, known, what in (("start_instance_id", ids, "an instance"), ("goal_instance_id", ids, "an instance"),
                             ("start_room", rooms, "a room"), ("goal_room", rooms, "a room")):
        value = getattr(extra, key)
        if value is not None and value not in known:
            raise DataError(f"{value!r} is not {what} of scene {spec.scene_id!r}", path=path,
                            field=f"{where}.sagebench.{key}")


def _unique(what: str, key: str, shown: str | int, seen: dict[str, str], path: Path, field_: str) -> None:
    """Note where the `what` ("trajectory", "episode") id `key` comes from (`field_`, where the file says `shown`);
    a DataError when it came before."""
    if key in seen:
        raise DataError(f"{what} id {shown!r} again (first at {seen[key]}): each {what} has its own id", path=path,
                        field=field_)
    seen[key] = field_


def _count_snapped(out: GvlnRows, moved: np.ndarray, task: str) -> None:
    """Add a sample's moved points (`moved` [M]: how far each path point moved onto the map, m) to `out`'s counts:
    all of them, its start and its goal (the last point, but for a no-goal sample's)."""
    out.snapped += int((moved > 0).sum())
    out.snapped_max_m = max(out.snapped_max_m, float(moved.max()))
    out.snapped_ends["start"] += int(moved[0] > 0)
    out.snapped_ends["goal"] += int(task != "nogoal" and len(moved) > 1 and moved[-1] > 0)


def _reference_path(sample: _Sample, spec: SceneSpec, navmap: NavigableMap, path: Path, where: str
                    ) -> tuple[np.ndarray, np.ndarray]:
    """[M, 4] world waypoints [x, y, floor, yaw] on the navigable map (each point's own heading, the last one keeping
    the one before), and [M] how far each point was moved onto the map (m, 0 where it was on it); a point farther
    off is a DataError."""
    pts = sample.points
    given = to_sage_xy(np.array([p.position[:2] for p in pts], dtype=np.float64), spec.sage_offset)
    xy, moved = navmap.place(given)
    off = np.flatnonzero(np.isnan(xy[:, 0]))
    if len(off):
        x, y = pts[off[0]].position[:2]
        raise DataError(f"({x:g}, {y:g}) is off the navigable map of scene {spec.scene_id!r}: no navigable cell "
                        f"within {SNAP_M:g} m", path=path, field=f"{where}.points[{off[0]}].position")
    yaws = [yaw_from_sage_rotation(p.rotation) for p in pts]
    if len(yaws) > 1:
        yaws[-1] = yaws[-2]  # SAGE-3D resets the last point's rotation
    distance = np.where(moved, np.linalg.norm(xy - given, axis=1), 0.0)
    return np.column_stack([xy, np.full(len(pts), spec.floor_height), [wrap(y) for y in yaws]]), distance


def _room_at(point: np.ndarray, rooms: list[tuple[str, shapely.Polygon]]) -> str | None:
    return next((rid for rid, poly in rooms if shapely.contains_xy(poly, float(point[0]), float(point[1]))), None)
