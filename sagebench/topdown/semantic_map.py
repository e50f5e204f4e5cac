"""semantic_map.json as pydantic models: what build-scene writes and later stages read; its JSON Schema."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from sagebench.errors import DataError, first_error
from sagebench.input_files import read_input
from sagebench.scene.model import DoorState, Kind
from sagebench.settings.shared import AgentConfig

XY = tuple[float, float]
DECIMALS = 4  # lengths in semantic_map.json are rounded to 0.1 mm: stable text, far below a grid cell


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class MultiPolygon(_Model):
    """GeoJSON MultiPolygon in world metres: polygons of rings (exterior first, then holes), each ring closed.

    `shapely.geometry.shape(instance.polygon.model_dump())` gives the shapely geometry.
    """

    type: Literal["MultiPolygon"] = "MultiPolygon"
    coordinates: list[list[list[XY]]]

    @field_validator("coordinates")
    @classmethod
    def _closed_rings(cls, polys: list[list[list[XY]]]) -> list[list[list[XY]]]:
        for rings in polys:
            for ring in rings:
                if len(ring) < 4 or ring[0] != ring[-1]:
                    raise ValueError(f"a ring needs at least 4 points, the last equal to the first (got {len(ring)})")
        return polys


class MapInstance(_Model):
    instance_id: Annotated[int, Field(ge=1)]
    category: str
    category_id: Annotated[int, Field(ge=1, description="Index into `categories` and value in topdown.npz `category`.")]
    kind: Kind
    room: str | None = Field(description="Room id from scene.json, else the room holding the footprint's centroid.")
    polygon: MultiPolygon = Field(description="Footprint, m: union of the convex hulls of the object's parts; a "
                                              "wall's cross-section within the height band (its openings kept).")
    bbox_m: tuple[tuple[float, float, float], tuple[float, float, float]] = Field(
        description="World axis-aligned box [[x, y, z] min, [x, y, z] max] of the posed mesh, m."
    )
    area_m2: Annotated[float, Field(ge=0)]
    min_z: float
    max_z: float
    door_state: DoorState | None = None
    blocks: bool = Field(description="Some of its geometry lies in the agent's height band.")


class Region(_Model):
    region_id: Annotated[int, Field(ge=1, description="Value in topdown.npz `region`.")]
    area_m2: Annotated[float, Field(ge=0)]
    rooms: list[str]


class RoomReach(_Model):
    room_id: str
    type: str
    navigable_area_m2: Annotated[float, Field(ge=0)]
    regions: list[int] = Field(description="Regions with navigable cells in the room.")
    reachable: bool = Field(description="More than half of the room's navigable area lies in the main region.")
    unreachable_area_m2: Annotated[float, Field(ge=0, description="The room's navigable area outside the main region.")]
    reachable_rooms: list[str] = Field(
        description="Other rooms an agent can walk to from this one: one region holds more than half of each "
                    "one's navigable area.")


class SemanticMap(_Model):
    """semantic_map.json: every instance's footprint and the navigable map's reachability report."""

    scene_id: str
    resolution: Annotated[float, Field(gt=0, description="m per cell.")]
    origin: XY = Field(description="World (x, y) of the lower-left corner of cell (0, 0), m.")
    shape: tuple[int, int] = Field(description="[H rows (y), W cols (x)] of every array in topdown.npz.")
    floor_height: float
    band_m: XY = Field(description="World z range whose geometry blocks: floor + the agent's clearance .. floor + "
                                   "its height.")
    agent_radius: Annotated[float, Field(gt=0)]
    connectivity: Literal[8] = Field(default=8, description="Regions join 8-connected steps that cut no blocked corner "
                                                           "(the planner's), so cells touching only diagonally do not.")
    categories: list[str] = Field(description="Category id -> name; id 0 is 'background' (no object).")
    instances: list[MapInstance]
    navigable_area_m2: Annotated[float, Field(ge=0)]
    regions: list[Region]
    main_region: Annotated[int, Field(ge=0, description="The largest region (lowest id among equals); 0 when "
                                                        "nothing is navigable.")]
    rooms: list[RoomReach]
    all_rooms_connected: bool = Field(description="Every room is reachable (see RoomReach.reachable).")

    def agent(self) -> AgentConfig:
        """The agent's body the map was built for, as build-scene recorded it: every later stage takes it from here."""
        return AgentConfig(radius=self.agent_radius, clearance=round(self.band_m[0] - self.floor_height, DECIMALS),
                           height=round(self.band_m[1] - self.floor_height, DECIMALS))


def read_semantic_map(path: Path) -> SemanticMap:
    """A scene's semantic_map.json; a missing or malformed one is a DataError naming the file (and the field)."""
    try:
        raw = read_input(path)
    except DataError as err:
        raise DataError(f"{err.detail} (run build-scene first)", path=path) from None
    try:
        smap = SemanticMap.model_validate_json(raw)
    except ValidationError as err:
        loc, msg, _ = first_error(err)
        raise DataError(msg, path=path, field=loc) from None
    rooms = {r.room_id for r in smap.rooms}
    for i, inst in enumerate(smap.instances):
        if inst.room is not None and inst.room not in rooms:
            raise DataError(f"room {inst.room!r} is not one of the map's rooms ({', '.join(sorted(rooms)) or 'none'})",
                            path=path, field=f"instances[{i}].room")
    return smap
