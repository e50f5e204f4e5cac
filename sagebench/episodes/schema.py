"""The episode row (one trajectory-instruction pair) as an Arrow schema, the columns docs/outputs.md lists.

Positions are [x, y, z] and waypoints [x, y, z, yaw] in world metres and radians (Z up, yaw
counter-clockwise from +X). Columns that may be null: the instance ids (a room endpoint has none),
the rooms (an endpoint outside every room polygon), and the instruction columns when
`--instructions none` writes bare trajectories.
"""

from __future__ import annotations

import pyarrow as pa

_F64 = pa.float64()

EPISODE_FIELDS: list[tuple[pa.Field, str]] = [
    (pa.field("episode_id", pa.string(), nullable=False), "Stable id of this row: hash of trajectory_id, level, type and index."),
    (pa.field("trajectory_id", pa.string(), nullable=False), "Stable id of the path: hash of scene, endpoints and waypoints."),
    (pa.field("scene_id", pa.string(), nullable=False), "scene_id of scenes/<scene_id>/."),
    (pa.field("instruction_level", pa.string()), "high or low."),
    (pa.field("instruction_type", pa.string()),
     "Add_Object, Scenario_Driven, Relative_Relationship, Attribute_Based, Area_Based, Base_Action or Single_Goal."),
    (pa.field("instruction_text", pa.string()), "The instruction; never contains an internal id."),
    (pa.field("start_instance_id", pa.int32()), "Instance the path starts at; null when it starts in a room."),
    (pa.field("goal_instance_id", pa.int32()), "Instance the path ends at; null when it ends in a room."),
    (pa.field("start_room", pa.string()), "Room id (scene.json rooms[].id) of the start."),
    (pa.field("goal_room", pa.string()), "Room id of the goal."),
    (pa.field("start_position", pa.list_(_F64, 3), nullable=False), "[x, y, z] world metres, z = floor height."),
    (pa.field("start_yaw", _F64, nullable=False), "Radians CCW from +X: heading of the first path segment."),
    (pa.field("goal_position", pa.list_(_F64, 3), nullable=False), "[x, y, z] world metres."),
    (pa.field("goal_radius", _F64, nullable=False), "Success radius around goal_position, metres."),
    (pa.field("reference_path", pa.list_(pa.list_(_F64, 4)), nullable=False),
     "Waypoints [x, y, z, yaw]; yaw = heading of the next segment (the last keeps the previous one)."),
    (pa.field("geodesic_distance", _F64, nullable=False), "Length of reference_path in the XY plane, metres."),
    (pa.field("instruction_source", pa.string()), "template or llm:<model>."),
    (pa.field("seed", pa.int64(), nullable=False), "The --seed the row was generated with."),
    (pa.field("split", pa.string(), nullable=False),
     "train, val_seen, val_unseen or test: unseen splits hold whole scenes, seen splits share scenes with train."),
]

# each field carries its meaning as metadata {"description": ...}, so every shard documents its columns
EPISODE_SCHEMA = pa.schema([f.with_metadata({"description": doc}) for f, doc in EPISODE_FIELDS],
                           metadata={"title": "sagebench episode row (Parquet, episodes/<scene_id>/part-<split>-NNNNN.parquet)"})


def episode_schema_ipc(schema: pa.Schema = EPISODE_SCHEMA) -> bytes:
    """The schema as an Arrow IPC message (schemas/episode.arrow; episode_tasks.arrow for a run with other tasks):
    `pyarrow.ipc.read_schema` reads it back."""
    return schema.serialize().to_pybytes()


def field_descriptions() -> dict[str, str]:
    """Column name -> meaning, in column order."""
    return {f.name: doc for f, doc in EPISODE_FIELDS}
