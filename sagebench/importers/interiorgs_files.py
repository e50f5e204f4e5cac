"""An InteriorGS scene folder read and checked: labels.json, structure.json and the occupancy map, as typed arrays.

The folder (`NNNN_NNNNNN/`, per the dataset card of manycore-research/InteriorGS) holds
- `3dgs_compressed.ply`: the scene's 3D Gaussians (SuperSplat's compressed layout; a plain INRIA-layout
  `3dgs.ply` is read instead where the compressed file is absent);
- `labels.json`: a list (or `{"labels": [...]}`) of `{ins_id, label, bounding_box: 8 corners {x, y, z}}`;
- `structure.json`: `rooms[]` (`profile` polygon, `room_type`), `walls[]` (`location` segment, `thickness`,
  `height`), `holes[]` (`profile` 3D polygon, `thickness`, `type` DOOR or WINDOW), `ins[]` (not read: labels.json
  holds the same boxes with their orientation);
- `occupancy.png` (255 free, 0 occupied, 127 unknown; a 16-bit PNG is scaled to these) and `occupancy.json`
  (`scale` m per pixel, `min` corner).

Every coordinate is metres in one frame with Z up (the card's Right, Back, Up), the floor at z = 0. Each
problem is one DataError naming the file and the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, ValidationError, field_validator

from sagebench.errors import DataError, first_error
from sagebench.input_files import read_json

PLY_FILES = ("3dgs_compressed.ply", "3dgs.ply")  # looked for in this order
LABELS = "labels.json"
STRUCTURE = "structure.json"
OCCUPANCY_PNG = "occupancy.png"
OCCUPANCY_JSON = "occupancy.json"
REQUIRED = (LABELS, STRUCTURE, OCCUPANCY_PNG, OCCUPANCY_JSON)
FREE, OCCUPIED, UNKNOWN = 255, 0, 127  # occupancy.png values
SIZE_SLACK_PX = 1.5  # occupancy.json's extent / scale may differ from the image size by this much (rounding)

MAX_COORD_M = 1e6  # a coordinate farther than this from the origin is no indoor scene's (and its grids would overflow)
Finite = Annotated[float, Field(allow_inf_nan=False, ge=-MAX_COORD_M, le=MAX_COORD_M)]
LABEL_MAX = 128  # characters of a label or ins_id: a label names the object's category and its mesh files
Word = Annotated[str, Field(max_length=LABEL_MAX, pattern=r"^[^\x00-\x1f\x7f]*$")]  # one line, as scene.json's names


class _Model(BaseModel):
    model_config = ConfigDict(extra="ignore", frozen=True)  # the dataset's files may carry keys we do not read


class _Corner(_Model):
    x: Finite
    y: Finite
    z: Finite


def _int_as_text(value: Any) -> Any:
    return str(value) if isinstance(value, int) and not isinstance(value, bool) else value


class _Label(_Model):
    ins_id: Annotated[Word, BeforeValidator(_int_as_text)] = ""  # SAGE-3D reads it with a default too
    label: Annotated[Word, Field(min_length=1)]
    bounding_box: list[_Corner]

    @field_validator("bounding_box")
    @classmethod
    def _eight(cls, corners: list[_Corner]) -> list[_Corner]:
        if len(corners) != 8:
            raise ValueError(f"{len(corners)} corners; an oriented box has 8")
        return corners


def _polygon(points: list[tuple[float, ...]], dims: int, least: int, what: str) -> list[tuple[float, ...]]:
    if len(points) < least:
        raise ValueError(f"{len(points)} points; {what} needs at least {least}")
    if any(len(p) < dims for p in points):
        raise ValueError(f"every point needs at least {dims} numbers")
    return points


class _Room(_Model):
    profile: list[tuple[Finite, ...]]
    room_type: str = ""

    @field_validator("profile")
    @classmethod
    def _outline(cls, pts: list[tuple[float, ...]]) -> list[tuple[float, ...]]:
        return _polygon(pts, 2, 3, "a room outline")


class _Wall(_Model):
    location: list[tuple[Finite, ...]]
    thickness: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    height: Annotated[float, Field(gt=0, allow_inf_nan=False)]

    @field_validator("location")
    @classmethod
    def _segment(cls, pts: list[tuple[float, ...]]) -> list[tuple[float, ...]]:
        if len(pts) != 2:
            raise ValueError(f"{len(pts)} points; a wall's line segment has 2")
        return _polygon(pts, 2, 2, "a segment")


class _Hole(_Model):
    profile: list[tuple[Finite, ...]]
    thickness: Annotated[float, Field(ge=0, allow_inf_nan=False)] = 0.0
    type: str

    @field_validator("profile")
    @classmethod
    def _outline(cls, pts: list[tuple[float, ...]]) -> list[tuple[float, ...]]:
        return _polygon(pts, 3, 3, "an opening's outline")

    @field_validator("type")
    @classmethod
    def _kind(cls, kind: str) -> str:
        if kind.upper() not in ("DOOR", "WINDOW"):
            raise ValueError(f"type {kind!r} is neither DOOR nor WINDOW")
        return kind.upper()


class _Structure(_Model):
    rooms: list[_Room] = Field(default_factory=list)
    walls: list[_Wall] = Field(default_factory=list)
    holes: list[_Hole] = Field(default_factory=list)


class _OccupancyMeta(_Model):
    scale: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    min: list[Finite]
    max: list[Finite] | None = None


@dataclass(frozen=True)
class Label:
    """One annotated instance: its id in the dataset, its class as written, its box's 8 corners [8, 3] (m)."""

    index: int  # position in labels.json
    ins_id: str
    label: str
    corners: np.ndarray
    renamed_from: str | None = None  # the ins_id as written, when an earlier label has it too


@dataclass(frozen=True)
class RoomOutline:
    profile: np.ndarray  # [P, 2] xy, m
    room_type: str


@dataclass(frozen=True)
class WallSegment:
    a: np.ndarray  # [2] xy of one end of the wall's line, m
    b: np.ndarray  # [2] the other end
    thickness: float  # m, across the line (half on each side)
    height: float  # m above the floor


@dataclass(frozen=True)
class Hole:
    profile: np.ndarray  # [P, 3] the opening's outline on its wall, m
    thickness: float
    kind: str  # DOOR or WINDOW


@dataclass(frozen=True)
class OccupancyMap:
    """occupancy.png as a grid in sagebench's convention: `free[i, j]` is the cell whose centre is
    (origin + (j + 0.5) * scale, origin + (i + 0.5) * scale), i.e. row = y, col = x from the lower-left corner.

    The PNG itself is that grid turned by 180 degrees about the vertical (its row r is y row r from `min`,
    its column c the x column W - 1 - c): the reading SAGE-3D's semantic_map_builder.py makes, where labels'
    boxes are drawn at (H - 1 - i, W - 1 - j) and the image is only flipped up-down, so that the two agree.
    """

    values: np.ndarray  # [H, W] uint8 in sagebench's orientation
    scale: float
    origin: tuple[float, float]

    @property
    def free(self) -> np.ndarray:
        return self.values == FREE


@dataclass(frozen=True)
class InteriorGSFolder:
    path: Path
    ply: Path
    labels: tuple[Label, ...]
    rooms: tuple[RoomOutline, ...]
    walls: tuple[WallSegment, ...]
    holes: tuple[Hole, ...]
    occupancy: OccupancyMap

    @property
    def scene_id(self) -> str:
        return self.path.resolve().name


def is_interiorgs_folder(path: Path) -> bool:
    """A directory with labels.json and structure.json and no scene.json: InteriorGS's layout, not sagebench's."""
    path = Path(path)
    return path.is_dir() and (path / LABELS).is_file() and (path / STRUCTURE).is_file() and not (path / "scene.json").exists()


def read_folder(path: Path) -> InteriorGSFolder:
    """Read and check every file of an InteriorGS scene folder but the PLY (only located here)."""
    path = Path(path)
    if not path.is_dir():
        raise DataError("not a directory (an InteriorGS scene folder)", path=path)
    ply = next((path / n for n in PLY_FILES if (path / n).is_file()), None)
    missing = [n for n in REQUIRED if not (path / n).is_file()] + ([] if ply else [PLY_FILES[0]])
    if missing:
        raise DataError(f"missing {', '.join(missing)} (an InteriorGS scene folder holds {PLY_FILES[0]}, "
                        f"{', '.join(REQUIRED)})", path=path)
    return InteriorGSFolder(path=path, ply=ply, labels=read_labels(path / LABELS),
                            **_structure(path / STRUCTURE), occupancy=read_occupancy(path / OCCUPANCY_PNG,
                                                                                     path / OCCUPANCY_JSON))


def _validated(model: type[BaseModel], raw: Any, path: Path, prefix: str = "") -> Any:
    try:
        return model.model_validate(raw)
    except ValidationError as err:
        loc, msg, _ = first_error(err)
        field = ".".join(p for p in (prefix, loc) if p).replace(".[", "[") or None
        raise DataError(msg, path=path, field=field) from None


def read_labels(path: Path) -> tuple[Label, ...]:
    raw = read_json(path)
    items = raw["labels"] if isinstance(raw, dict) and "labels" in raw else raw
    prefix = "labels" if isinstance(raw, dict) else ""
    if not isinstance(items, list):
        raise DataError('must hold a list of labels (or {"labels": [...]})', path=path)
    if not items:
        raise DataError("holds no labels: an InteriorGS scene labels each of its objects", path=path)
    out = []
    for i, item in enumerate(items):
        lab = _validated(_Label, item, path, f"{prefix}[{i}]")
        corners = np.array([[c.x, c.y, c.z] for c in lab.bounding_box], dtype=np.float64)
        out.append(Label(i, str(lab.ins_id), lab.label.strip(), corners))
    ids = {lab.ins_id for lab in out}
    if len(out) > 1 and len(ids) == 1 and "" not in ids:
        raise DataError(f"all {len(out)} labels have ins_id {out[0].ins_id!r}: each instance needs its own",
                        path=path, field=f"{prefix}[1].ins_id")
    return _renamed_duplicates(out)


def _renamed_duplicates(labels: list[Label]) -> tuple[Label, ...]:
    """Each label whose ins_id an earlier label already has gets `<ins_id>#<k>` (k = 2, 3, ... the first free),
    remembered in `renamed_from`, so that an ins_id names one instance (interiorgs_import.json maps instances
    back to labels by it). A label without an ins_id has none to repeat."""
    taken = {lab.ins_id for lab in labels}
    seen: set[str] = set()
    out = []
    for lab in labels:
        if lab.ins_id and lab.ins_id in seen:
            k = 2
            while f"{lab.ins_id}#{k}" in taken:
                k += 1
            new = f"{lab.ins_id}#{k}"
            taken.add(new)
            lab = Label(lab.index, new, lab.label, lab.corners, renamed_from=lab.ins_id)
        seen.add(lab.ins_id)
        out.append(lab)
    return tuple(out)


def _structure(path: Path) -> dict[str, tuple]:
    s = _validated(_Structure, read_json(path), path)
    if not s.rooms:
        raise DataError("no rooms: the floor plan needs at least one room profile", path=path, field="rooms")
    return {
        "rooms": tuple(RoomOutline(np.array([p[:2] for p in r.profile], dtype=np.float64), r.room_type.strip())
                       for r in s.rooms),
        "walls": tuple(WallSegment(np.array(w.location[0][:2], dtype=np.float64),
                                   np.array(w.location[1][:2], dtype=np.float64), w.thickness, w.height)
                       for w in s.walls),
        "holes": tuple(Hole(np.array([p[:3] for p in h.profile], dtype=np.float64), h.thickness, h.type)
                       for h in s.holes),
    }


def _grey(im: Any) -> np.ndarray:
    """[H, W] uint8 of an opened image: a 16-bit grey PNG (PIL mode I;16 or I) scaled from 0..65535 to 0..255, so
    that 32767 reads as 127 (unknown) instead of being clipped to 255 (free) as PIL's conversion to L does."""
    if im.mode.startswith("I"):
        wide = np.asarray(im).astype(np.float64)
        return np.clip(np.round(wide / 257.0), 0, 255).astype(np.uint8)
    return np.asarray(im.convert("L"))


def read_occupancy(png: Path, meta_path: Path) -> OccupancyMap:
    """occupancy.png and occupancy.json; the JSON's extent must match the image's size."""
    from PIL import Image, UnidentifiedImageError

    meta = _validated(_OccupancyMeta, read_json(meta_path), meta_path)
    if len(meta.min) < 2 or (meta.max is not None and len(meta.max) < 2):
        raise DataError("min and max need at least x and y", path=meta_path, field="min")
    try:
        with Image.open(png) as im:
            image = _grey(im)
    except (OSError, UnidentifiedImageError) as err:
        raise DataError(f"cannot read the image: {err}", path=png) from None
    h, w = image.shape
    if meta.max is not None:
        span = (np.asarray(meta.max[:2]) - np.asarray(meta.min[:2])) / meta.scale
        if not (abs(span[0] - w) <= SIZE_SLACK_PX and abs(span[1] - h) <= SIZE_SLACK_PX):
            raise DataError(f"min..max at scale {meta.scale:g} m/px spans {span[0]:.1f} x {span[1]:.1f} px but "
                            f"{png.name} is {w} x {h} px", path=meta_path, field="scale")
    elif not math.isfinite(meta.min[0] + w * meta.scale):
        raise DataError("min + image size * scale is not finite", path=meta_path, field="scale")
    return OccupancyMap(values=np.ascontiguousarray(image[:, ::-1]), scale=meta.scale,
                        origin=(float(meta.min[0]), float(meta.min[1])))
