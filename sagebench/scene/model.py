"""The artist-scene input format (scene.json) as pydantic models; the JSON Schema is generated from them."""

from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

Kind = Literal["object", "wall", "floor", "ceiling", "door", "window"]
DoorState = Literal["open", "closed", "ajar"]
Units = Literal["m", "cm", "mm"]
UpAxis = Literal["Z", "Y"]

UNIT_SCALE: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001}

MIN_DETERMINANT = 1e-12  # |det| of a transform's 3x3 part below this flattens a mesh (a 1e-4 scale on each axis)
Vec3 = tuple[float, float, float]
FiniteFloat = Annotated[float, Field(allow_inf_nan=False, strict=True)]  # strict: "1.5" (a string) is refused
# Names and words become USD prim names, MJCF attributes and instruction text: no control character (NUL, newline)
Text = Annotated[str, Field(pattern=r"^[^\x00-\x1f\x7f]*$")]
Name = Annotated[str, Field(min_length=1, pattern=r"^[^\x00-\x1f\x7f]+$")]
INT32_MAX = 2**31 - 1  # instance ids are stored as int32 in maps, PLYs and episode rows
SCENE_ID_MAX = 128  # scene ids name directories and files
# the category of geometry no label explains (import-interiorgs' evidence): an obstacle that no instruction, goal,
# landmark or SAGE item may name, since nobody said what it is
UNLABELLED = "unlabelled"


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Transform(_Model):
    """Mesh-file coordinates to scene coordinates: either TRS (scale, then rotation, then translation) or a 4x4 matrix."""

    translation: tuple[FiniteFloat, FiniteFloat, FiniteFloat] = (0.0, 0.0, 0.0)
    rotation_wxyz: tuple[FiniteFloat, FiniteFloat, FiniteFloat, FiniteFloat] = (1.0, 0.0, 0.0, 0.0)
    scale: tuple[FiniteFloat, FiniteFloat, FiniteFloat] = (1.0, 1.0, 1.0)
    matrix: tuple[tuple[FiniteFloat, ...], ...] | None = Field(
        default=None, description="Row-major 4x4 matrix; when given, translation/rotation/scale must be left out."
    )

    @field_validator("rotation_wxyz")
    @classmethod
    def _unit_quaternion(cls, q: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        n = math.sqrt(sum(c * c for c in q))
        if n < 1e-9:
            raise ValueError("rotation_wxyz is a zero quaternion")
        return tuple(c / n for c in q)  # type: ignore[return-value]

    @field_validator("matrix")
    @classmethod
    def _four_by_four(cls, m: tuple[tuple[float, ...], ...] | None) -> tuple[tuple[float, ...], ...] | None:
        if m is not None and (len(m) != 4 or any(len(r) != 4 for r in m)):
            raise ValueError("matrix must be 4 rows of 4 numbers")
        if m is not None and tuple(m[3]) != (0.0, 0.0, 0.0, 1.0):
            raise ValueError(f"matrix's last row must be 0 0 0 1, got {' '.join(f'{v:g}' for v in m[3])}")
        return m

    @model_validator(mode="after")
    def _one_form(self) -> Transform:
        trs_set = {"translation", "rotation_wxyz", "scale"} & self.model_fields_set
        if self.matrix is not None and trs_set:
            raise ValueError(f"give either matrix or {', '.join(sorted(trs_set))}, not both")
        det = float(np.linalg.det(self.as_matrix()[:3, :3]))
        if not abs(det) > MIN_DETERMINANT:
            raise ValueError(f"singular transform (determinant {det:.3g}): a zero scale or a flat matrix squashes "
                             f"the mesh into a plane")
        return self

    def as_matrix(self) -> np.ndarray:
        """[4, 4] float64 homogeneous matrix."""
        if self.matrix is not None:
            return np.asarray(self.matrix, dtype=np.float64)
        w, x, y, z = self.rotation_wxyz
        rot = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
            ]
        )
        out = np.eye(4)
        out[:3, :3] = rot * np.asarray(self.scale)[None, :]
        out[:3, 3] = self.translation
        return out


class Door(_Model):
    """A door leaf authored in its closed pose; it turns about a vertical hinge axis to its state's angle."""

    state: DoorState
    hinge: tuple[FiniteFloat, FiniteFloat, FiniteFloat] = Field(
        description="A point on the hinge axis, in scene units and frame."
    )
    swing: Literal[1, -1] = Field(default=1, description="+1 opens counter-clockwise seen from above, -1 clockwise.")
    open_deg: Annotated[float, Field(gt=0, le=180, strict=True)] = 90.0
    ajar_deg: Annotated[float, Field(gt=0, le=180, strict=True)] = 45.0

    @field_validator("swing", mode="before")
    @classmethod
    def _not_a_boolean(cls, v: object) -> object:
        if isinstance(v, bool):  # true == 1 in Python: a boolean would pass as +1
            raise ValueError(f"swing must be 1 or -1 (got {str(v).lower()})")
        return v

    def angle_rad(self) -> float:
        """Signed rotation of the leaf from its closed pose about the up axis."""
        deg = {"closed": 0.0, "ajar": self.ajar_deg, "open": self.open_deg}[self.state]
        return math.radians(deg) * self.swing


class Room(_Model):
    id: Name
    type: Annotated[Name, Field(description="kitchen, living_room, bedroom, bathroom, ...")]
    polygon: list[tuple[FiniteFloat, ...]] = Field(
        description="Floor outline: [x, y] points when up_axis is Z, else [x, y, z] points in scene units."
    )

    @field_validator("polygon")
    @classmethod
    def _enough_points(cls, pts: list[tuple[float, ...]]) -> list[tuple[float, ...]]:
        if len(pts) < 3:
            raise ValueError("a floor polygon needs at least 3 points")
        if len({len(p) for p in pts}) != 1 or len(pts[0]) not in (2, 3):
            raise ValueError("polygon points must all be [x, y] or all be [x, y, z]")
        return pts


class SceneObject(_Model):
    instance_id: Annotated[int, Field(ge=1, le=INT32_MAX, strict=True,
                                      description="Unique per scene; 0 is reserved for background.")]
    category: Name
    kind: Kind = "object"
    mesh: Annotated[str, Field(min_length=1, pattern=r"^[^\x00]*$", description="Path relative to the scene directory.")]
    transform: Transform = Transform()
    room_id: Name | None = None
    attributes: dict[Name, Text] = Field(default_factory=dict, description="colour, material, state, ...")
    door: Door | None = None

    @model_validator(mode="after")
    def _door_fields(self) -> SceneObject:
        if self.kind == "door" and self.door is None:
            raise ValueError("a door needs a 'door' entry with its state (open, closed or ajar) and hinge")
        if self.kind != "door" and self.door is not None:
            raise ValueError(f"only kind 'door' may have a 'door' entry (kind is {self.kind!r})")
        return self


class SceneSpec(_Model):
    """scene.json: everything sagebench needs to know about an artist scene besides its meshes."""

    scene_id: Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$", max_length=SCENE_ID_MAX)]
    units: Units = "m"
    up_axis: UpAxis = "Z"
    floor_height: FiniteFloat = Field(default=0.0, description="Height of the walkable floor along up_axis, scene units.")
    rooms: list[Room] = Field(default_factory=list)
    objects: Annotated[list[SceneObject], Field(min_length=1)]
    sage_offset: tuple[FiniteFloat, FiniteFloat] = Field(
        default=(0.0, 0.0), description="m: a world point (x, y) is (sage_offset - (x, y)) in SAGE-3D's 3D frame "
                                        "(its tools mirror about map bounds rounded to 2 decimals); import-interiorgs "
                                        "writes it, 0 elsewhere.")
    license: Annotated[str, Field(pattern=r"^[a-z0-9][a-z0-9.+-]*$", max_length=64)] | None = Field(
        default=None, description="The licence of the scene's content as a Hugging Face license id (cc0-1.0, "
                                  "cc-by-4.0, apache-2.0, other, ...): what a run's dataset card declares.")

    @model_validator(mode="after")
    def _cross_checks(self) -> SceneSpec:
        seen: dict[int, int] = {}
        for i, obj in enumerate(self.objects):
            if obj.instance_id in seen:
                raise ValueError(
                    f"objects[{i}].instance_id: duplicate instance_id {obj.instance_id} (also objects[{seen[obj.instance_id]}])"
                )
            seen[obj.instance_id] = i
        room_ids = [r.id for r in self.rooms]
        if len(set(room_ids)) != len(room_ids):
            raise ValueError("rooms: duplicate room id")
        for i, obj in enumerate(self.objects):
            if obj.room_id is not None and obj.room_id not in room_ids:
                raise ValueError(f"objects[{i}].room_id: unknown room {obj.room_id!r}")
        if self.up_axis == "Y":
            for j, room in enumerate(self.rooms):
                if len(room.polygon[0]) != 3:
                    raise ValueError(f"rooms[{j}].polygon: a Y-up scene needs [x, y, z] points")
        return self
