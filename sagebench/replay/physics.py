"""MuJoCo replay of commanded paths: a velocity-driven cylinder agent follows waypoints through the colliders.

The agent (AgentConfig radius/height) sits on planar joints: slide-x and slide-y on a body that carries the
collision shape, and a yaw hinge on a child body that carries only the drive site. Contacts therefore push the
agent but never twist its heading. The shape is a 32-sided prism circumscribing the cylinder (at most 1 mm
wider): MuJoCo's polytope collision gives exact depths and the radial normal at a corner, while its
cylinder-versus-mesh contacts report the box face's normal at vertical edges (the agent snags on every
corner) and libccd's MPR over-states face depths several-fold. The prism spans floor + clearance to
floor + height (the map's blocking band); plane geoms (the MJCF's ground) and the bodies named as floors stop
colliding, so floor contacts never happen. Contacts are frictionless.

Three velocity actuators act through the site: forward speed v and lateral speed (always commanded 0) along
the heading, and turn rate omega. Their gains are deadbeat (kv = mass / dt with the Euler integrator: the
commanded velocity is reached in one step) and the forward force is capped at what that takes, so a wall
stops the agent instead of being tunnelled through; the lateral cap is a tenth of that, so a brushed corner
pushes the agent aside.

Per step t (from pose t-1 to pose t) the record holds the command, the achieved motion, whether the
agent touched anything at pose t-1 (contact sensor, deepest contact) and the collision intensity
c(t) = clip(1 - (achieved . commanded) / |commanded|^2, 0, 1) of the planar displacement while in
contact, 0 otherwise (docs/metrics.md, ICP).

`replay_one` steps one MjData in a plain loop (the reference); `replay_batch` steps many paths together
with `mujoco.rollout` threads, one step per call, the controller vectorised between calls. Both use the
same controller and zero the solver warm start before every step, so they give the same record.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from sagebench.settings.shared import AgentConfig, ReplayConfig

AGENT_BODY = "sagebench_agent"
HEADING_BODY = "sagebench_agent_heading"
AGENT_GEOM = "sagebench_agent_cylinder"
DRIVE_SITE = "sagebench_agent_drive"
AGENT_MASS = 20.0  # kg, translating body; only the ratio to the gains matters
HEADING_MASS = 1.0  # kg
HEADING_IZZ = 1.0  # kg m^2
LATERAL_FORCE_FRACTION = 0.1  # of the forward force cap
PRISM_SIDES = 32
_CONTACT_DATA = 1 | 8  # contact sensor fields: found, dist (mjtConDataField bits)
_REDUCE_MINDIST = 1


@dataclass(frozen=True)
class ReplayModel:
    """A compiled scene with the agent added; indices into qpos/qvel/ctrl/sensordata of the agent."""

    model: mujoco.MjModel
    config: ReplayConfig
    agent: AgentConfig  # the body the agent was built with
    floor_z: float
    qpos: tuple[int, int, int]  # addresses of x, y, yaw
    sensor: int  # address of the contact sensor's (found, dist)

    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)


@dataclass(frozen=True)
class ReplayRecord:
    """One replay: T = steps + 1 poses, row 0 the start; per-step arrays describe the step into pose t.

    poses        [T, 4] float64  x, y, z (floor), yaw in [-pi, pi)
    command      [T, 2] float64  commanded (v m/s, omega rad/s); row 0 zeros
    achieved     [T, 2] float64  achieved (forward m/s along the commanded heading, yaw rate rad/s)
    contact      [T] bool        the agent touched a collider when the step began
    penetration  [T] float64     depth of the deepest such contact, m (0 without contact)
    intensity    [T] float64     collision intensity c(t) in [0, 1]
    outcome      str             how it ended: 'reached' (the last waypoint), 'stalled' (no progress towards the
                                 current waypoint for stall_time: something blocks it) or 'time_limit'
    waypoint     int             the waypoint it was heading for at the end (len(path) - 1 when reached)
    """

    poses: np.ndarray
    command: np.ndarray
    achieved: np.ndarray
    contact: np.ndarray
    penetration: np.ndarray
    intensity: np.ndarray
    outcome: str
    waypoint: int

    @property
    def steps(self) -> int:
        return len(self.poses) - 1


def build_replay_model(
    scene: mujoco.MjSpec | str | Path,
    *,
    agent: AgentConfig = AgentConfig(),
    floor_z: float = 0.0,
    floor_bodies: Sequence[str] = (),
    config: ReplayConfig = ReplayConfig(),
) -> ReplayModel:
    """Add the agent to a scene (an MjSpec, left untouched, or a path to scene.xml) and compile it.

    `floor_bodies` names bodies whose geoms are floor (slabs of kind floor) and must not collide. The
    scene's own joints (doors' hinges, furniture's free joints), the door servos on them and its contact
    exclusions are removed: the agent moves through the world as exported, doors at their state's angle and
    furniture where it stands.
    """
    spec = mujoco.MjSpec.from_file(str(scene)) if isinstance(scene, str | Path) else scene.copy()
    for element in [*spec.actuators, *spec.excludes, *spec.joints]:
        spec.delete(element)
    dt = config.timestep
    spec.option.timestep = dt
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    spec.option.gravity = [0.0, 0.0, 0.0]
    floors = set(floor_bodies)
    missing = floors - {b.name for b in spec.bodies}
    if missing:
        raise ValueError(f"floor_bodies: no body named {sorted(missing)[0]!r} in the scene")
    for geom in spec.geoms:
        if geom.type == mujoco.mjtGeom.mjGEOM_PLANE or geom.parent.name in floors:
            geom.contype = 0
            geom.conaffinity = 0
    spec.compiler.fusestatic = True  # the scene's jointless bodies join the world: a step takes a third of the time

    body = spec.worldbody.add_body(name=AGENT_BODY, pos=[0.0, 0.0, floor_z])
    body.mass, body.inertia, body.explicitinertial = AGENT_MASS, [1.0, 1.0, 1.0], True
    body.add_joint(name=f"{AGENT_BODY}_x", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[1, 0, 0])
    body.add_joint(name=f"{AGENT_BODY}_y", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 1, 0])
    spec.add_mesh(name=AGENT_GEOM, uservert=agent_prism(agent.radius, *agent.band).ravel().tolist())
    body.add_geom(name=AGENT_GEOM, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=AGENT_GEOM, condim=1, priority=1,
                  contype=1, conaffinity=1)
    heading = body.add_body(name=HEADING_BODY)
    heading.mass, heading.inertia, heading.explicitinertial = HEADING_MASS, [1.0, 1.0, HEADING_IZZ], True
    heading.add_joint(name=f"{AGENT_BODY}_yaw", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
    heading.add_site(name=DRIVE_SITE)

    mass = AGENT_MASS + HEADING_MASS
    forward_cap = mass * config.max_speed / dt
    for gear, inertia, cap in (([1, 0, 0, 0, 0, 0], mass, forward_cap),
                               ([0, 1, 0, 0, 0, 0], mass, LATERAL_FORCE_FRACTION * forward_cap),
                               ([0, 0, 0, 0, 0, 1], HEADING_IZZ, None)):
        act = spec.add_actuator(trntype=mujoco.mjtTrn.mjTRN_SITE, target=DRIVE_SITE, gear=gear)
        act.set_to_velocity(kv=inertia / dt)
        if cap is not None:
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.forcerange = [-cap, cap]
    spec.add_sensor(type=mujoco.mjtSensor.mjSENS_CONTACT, objtype=mujoco.mjtObj.mjOBJ_GEOM, objname=AGENT_GEOM,
                    intprm=[_CONTACT_DATA, _REDUCE_MINDIST, 1])
    model = spec.compile()
    qpos = tuple(int(model.jnt_qposadr[model.joint(f"{AGENT_BODY}_{n}").id]) for n in ("x", "y", "yaw"))
    sensor = int(model.sensor_adr[model.nsensor - 1])
    return ReplayModel(model=model, config=config, agent=agent, floor_z=float(floor_z),
                       qpos=qpos, sensor=sensor)  # type: ignore[arg-type]


def agent_prism(radius: float, z0: float, z1: float, sides: int = PRISM_SIDES) -> np.ndarray:
    """[2 * sides, 3] vertices of a prism whose side faces touch the cylinder of `radius` (z0..z1, m)."""
    r = radius / math.cos(math.pi / sides)
    angle = (np.arange(sides) + 0.5) * 2 * math.pi / sides
    ring = np.column_stack([r * np.cos(angle), r * np.sin(angle)])
    return np.vstack([np.column_stack([ring, np.full(sides, z)]) for z in (z0, z1)])


# ---------------------------------------------------------------- the path-following controller


@dataclass(frozen=True)
class _Paths:
    """Commanded poses of B paths padded to M: xy [B, M, 2], yaw [B, M], n [B], turn [B, M] (turn-in-place)."""

    xy: np.ndarray
    yaw: np.ndarray
    n: np.ndarray
    turn: np.ndarray


def _check_path(path: np.ndarray, index: int) -> np.ndarray:
    p = np.asarray(path, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 4 or len(p) == 0:
        raise ValueError(f"paths[{index}]: expected [M, 4] (x, y, z, yaw) with M >= 1, got shape {p.shape}")
    if not np.isfinite(p).all():
        raise ValueError(f"paths[{index}]: non-finite value")
    return p


def _pack(paths: Sequence[np.ndarray], config: ReplayConfig) -> _Paths:
    checked = [_check_path(p, i) for i, p in enumerate(paths)]
    b, m = len(checked), max(len(p) for p in checked)
    xy, yaw = np.zeros((b, m, 2)), np.zeros((b, m))
    n = np.array([len(p) for p in checked])
    for i, p in enumerate(checked):
        xy[i, : len(p)], yaw[i, : len(p)] = p[:, :2], p[:, 3]
        xy[i, len(p):], yaw[i, len(p):] = p[-1, :2], p[-1, 3]
    seg = np.linalg.norm(np.diff(xy, axis=1), axis=2)
    turn = np.zeros((b, m), dtype=bool)
    turn[:, 1:] = seg < config.waypoint_tolerance  # a waypoint on top of the previous one is a turn command
    return _Paths(xy=xy, yaw=yaw, n=n, turn=turn)


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def time_limit(path: np.ndarray, config: ReplayConfig) -> float:
    """Seconds allowed for one path [M, 4]: time_factor x (driving + turning at the limits) + time_slack."""
    p = np.asarray(path, dtype=np.float64)
    seg = np.diff(p[:, :2], axis=0)
    length = np.linalg.norm(seg, axis=1)
    moving = length >= config.waypoint_tolerance
    headings = np.where(moving, np.arctan2(seg[:, 1], seg[:, 0]), p[1:, 3])
    turns = np.abs(_wrap(np.diff(np.concatenate([p[:1, 3], headings])))).sum()
    ideal = length.sum() / config.max_speed + turns / config.max_turn_rate
    return config.time_factor * ideal + config.time_slack


@dataclass
class _Follow:
    """The controller's memory per path [B]: target waypoint, nearest approach to it (distance m and heading
    error rad) and the step of the last progress."""

    idx: np.ndarray
    best_dist: np.ndarray
    best_err: np.ndarray
    progress_step: np.ndarray

    @classmethod
    def start(cls, paths: Sequence[np.ndarray]) -> _Follow:
        b = len(paths)
        return cls(idx=np.array([min(1, len(p) - 1) for p in paths]), best_dist=np.full(b, np.inf),
                   best_err=np.full(b, np.inf), progress_step=np.zeros(b, dtype=np.int64))


REACHED, STALLED, TIME_LIMIT = 1, 2, 3
OUTCOMES = {REACHED: "reached", STALLED: "stalled", TIME_LIMIT: "time_limit"}
_PROGRESS_DIST = 0.01  # m nearer the waypoint, or
_PROGRESS_ANGLE = 0.05  # rad nearer its heading, counts as progress


def _control(paths: _Paths, rows: np.ndarray, follow: _Follow, pose: np.ndarray, step: int, config: ReplayConfig
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One controller tick for the paths `rows` [B] from poses [B, 3] (x, y, yaw); updates `follow` at `rows`.

    Turn-then-drive: a waypoint is reached within waypoint_tolerance (a turn command when its yaw is within
    yaw_tolerance too); the agent turns at up to max_turn_rate towards the next one and drives only while the
    heading error is below turn_in_place, at up to max_speed and never past the waypoint, so it traces the
    polyline. A waypoint counts as reached up to waypoint_tolerance short, so a turn command (a waypoint within
    waypoint_tolerance of the one before) may lie farther off than that: the agent drives to it first.
    Returns v [B] m/s, omega [B] rad/s and the outcome [B] (0 while running, else REACHED/STALLED).
    """
    dt = config.timestep
    xy, yaw = pose[:, :2], pose[:, 2]
    idx = follow.idx[rows].copy()
    while True:
        target = paths.xy[rows, idx]
        dist = np.linalg.norm(target - xy, axis=1)
        turn = paths.turn[rows, idx]
        yaw_err = _wrap(paths.yaw[rows, idx] - yaw)
        reached = (dist < config.waypoint_tolerance) & (~turn | (np.abs(yaw_err) < config.yaw_tolerance))
        last = idx >= paths.n[rows] - 1
        advance = reached & ~last
        if not advance.any():
            break
        idx[advance] += 1
    bearing = np.arctan2(target[:, 1] - xy[:, 1], target[:, 0] - xy[:, 0])
    turning = turn & (dist < config.waypoint_tolerance)  # a turn command not within reach is driven to first
    err = np.where(turning, yaw_err, _wrap(bearing - yaw))
    omega = np.clip(err / dt, -config.max_turn_rate, config.max_turn_rate)
    drive = ~turning & (np.abs(err) <= config.turn_in_place)
    v = np.where(drive, np.minimum(config.max_speed, dist / dt) * np.cos(err), 0.0)

    new_target = idx != follow.idx[rows]
    best_dist = np.where(new_target, np.inf, follow.best_dist[rows])
    best_err = np.where(new_target, np.inf, follow.best_err[rows])
    progress = new_target | (dist < best_dist - _PROGRESS_DIST) | (np.abs(err) < best_err - _PROGRESS_ANGLE)
    follow.idx[rows] = idx
    follow.best_dist[rows] = np.where(progress, dist, best_dist)
    follow.best_err[rows] = np.where(progress, np.abs(err), best_err)
    follow.progress_step[rows] = np.where(progress, step, follow.progress_step[rows])
    stalled = (step - follow.progress_step[rows]) * dt >= config.stall_time
    outcome = np.where(reached & last, REACHED, np.where(stalled, STALLED, 0))
    v[outcome > 0], omega[outcome > 0] = 0.0, 0.0
    return v, omega, outcome


# ---------------------------------------------------------------- stepping


@dataclass
class _Log:
    """Per-step values of a batch, appended one step (of the paths still running) at a time."""

    rows: list[np.ndarray] = field(default_factory=list)  # [b] int64 path index
    pose: list[np.ndarray] = field(default_factory=list)  # [b, 3] x, y, unwrapped yaw after the step
    command: list[np.ndarray] = field(default_factory=list)  # [b, 2] v, omega
    sensor: list[np.ndarray] = field(default_factory=list)  # [b, 2] contacts found, deepest dist at the step's start

    def add(self, rows: np.ndarray, pose: np.ndarray, command: np.ndarray, sensor: np.ndarray) -> None:
        self.rows.append(np.array(rows, dtype=np.int64))
        self.pose.append(np.array(pose, dtype=np.float64))
        self.command.append(np.array(command, dtype=np.float64))
        self.sensor.append(np.array(sensor, dtype=np.float64))


def _records(rm: ReplayModel, starts: np.ndarray, log: _Log, outcome: np.ndarray, follow: _Follow
             ) -> list[ReplayRecord]:
    """Group the log by path and derive achieved motion and collision intensity."""
    dt = rm.timestep
    rows = np.concatenate(log.rows) if log.rows else np.zeros(0, dtype=np.int64)
    order = np.argsort(rows, kind="stable")  # steps were logged in time order
    cat = lambda parts, width: (np.concatenate(parts) if parts else np.zeros((0, width)))[order]  # noqa: E731
    pose_all, cmd_all, sens_all = cat(log.pose, 3), cat(log.command, 2), cat(log.sensor, 2)
    bounds = np.searchsorted(rows[order], np.arange(len(starts) + 1))
    out = []
    for b in range(len(starts)):
        sl = slice(bounds[b], bounds[b + 1])
        pose = np.vstack([starts[b][None], pose_all[sl]])
        n = len(pose)
        command = np.vstack([np.zeros((1, 2)), cmd_all[sl]])
        found, dist = sens_all[sl, 0], sens_all[sl, 1]
        contact = np.concatenate([[False], found > 0])
        penetration = np.concatenate([[0.0], np.where(found > 0, np.maximum(0.0, -dist), 0.0)])
        heading = np.column_stack([np.cos(pose[:-1, 2]), np.sin(pose[:-1, 2])])
        forward = (np.diff(pose[:, :2], axis=0) * heading).sum(1)  # achieved displacement along the heading, m
        wanted = command[1:, 0] * dt
        moving = np.abs(wanted) > 1e-9
        ratio = np.divide(forward, wanted, out=np.ones(n - 1), where=moving)
        intensity = np.concatenate([[0.0], np.where(contact[1:] & moving, np.clip(1.0 - ratio, 0.0, 1.0), 0.0)])
        achieved = np.vstack([np.zeros((1, 2)), np.column_stack([forward / dt, np.diff(pose[:, 2]) / dt])])
        poses = np.column_stack([pose[:, :2], np.full(n, rm.floor_z), _wrap(pose[:, 2])])
        out.append(ReplayRecord(poses=poses, command=command, achieved=achieved, contact=contact,
                                penetration=penetration, intensity=intensity, outcome=OUTCOMES[int(outcome[b])],
                                waypoint=int(follow.idx[b])))
    return out


def _max_steps(paths: Sequence[np.ndarray], config: ReplayConfig) -> np.ndarray:
    return np.array([int(math.ceil(time_limit(p, config) / config.timestep)) for p in paths])


def start_penetration(rm: ReplayModel, pose: np.ndarray) -> float | None:
    """Depth (m) of the deepest contact of the agent standing at `pose` (x, y, z, yaw), None when it touches
    nothing: a path of one pose has no step to replay, and its start must still be clear."""
    d = mujoco.MjData(rm.model)
    d.qpos[list(rm.qpos)] = pose[0], pose[1], pose[3]
    mujoco.mj_forward(rm.model, d)
    found, dist = d.sensordata[rm.sensor: rm.sensor + 2]
    return max(0.0, -float(dist)) if found > 0 else None


def replay_one(rm: ReplayModel, path: np.ndarray) -> ReplayRecord:
    """Replay one commanded path [M, 4] (x, y, z, yaw; the agent starts at row 0) in a plain mj_step loop.

    The reference for `replay_batch`.
    """
    paths = [_check_path(path, 0)]
    config, m = rm.config, rm.model
    packed, follow, max_steps = _pack(paths, config), _Follow.start(paths), _max_steps(paths, config)[0]
    starts = np.array([[path[0, 0], path[0, 1], path[0, 3]]], dtype=np.float64)
    q = list(rm.qpos)
    d = mujoco.MjData(m)
    d.qpos[q] = starts[0]
    rows, log = np.zeros(1, dtype=np.int64), _Log()
    outcome = np.full(1, TIME_LIMIT)
    for step in range(max_steps + 1):
        v, omega, ended = _control(packed, rows, follow, d.qpos[q][None], step, config)
        if ended[0]:
            outcome[0] = ended[0]
            break
        if step == max_steps:
            break
        d.ctrl[:] = v[0], 0.0, omega[0]
        d.qacc_warmstart[:] = 0.0
        mujoco.mj_step(m, d)
        log.add(rows, d.qpos[q][None], [[v[0], omega[0]]], d.sensordata[rm.sensor: rm.sensor + 2][None])
    return _records(rm, starts, log, outcome, follow)[0]


def replay_batch(rm: ReplayModel, paths: Sequence[np.ndarray], *, threads: int = 2) -> list[ReplayRecord]:
    """Replay many commanded paths [M_i, 4] at once: every path still running advances one step per
    `mujoco.rollout` call on `threads` threads, and the controller runs vectorised between calls."""
    from mujoco import rollout

    paths = [_check_path(p, i) for i, p in enumerate(paths)]
    if not paths:
        return []
    config, m = rm.config, rm.model
    packed, follow, max_steps = _pack(paths, config), _Follow.start(paths), _max_steps(paths, config)
    starts = np.array([[p[0, 0], p[0, 1], p[0, 3]] for p in paths], dtype=np.float64)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    qcols = mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_TIME) + np.array(rm.qpos)
    d = mujoco.MjData(m)
    state = np.empty((len(paths), mujoco.mj_stateSize(m, spec)))
    for b in range(len(paths)):
        d.qpos[list(rm.qpos)] = starts[b]
        mujoco.mj_getState(m, d, state[b], spec)
    datas = [mujoco.MjData(m) for _ in range(max(1, threads))]
    active = np.arange(len(paths))
    outcome = np.full(len(paths), TIME_LIMIT)
    log = _Log()
    ctrl = np.zeros((len(paths), 1, m.nu))
    with rollout.Rollout(nthread=max(1, threads)) as pool:
        for step in range(int(max_steps.max()) + 1):
            v, omega, ended = _control(packed, active, follow, state[active][:, qcols], step, config)
            outcome[active[ended > 0]] = ended[ended > 0]
            keep = (ended == 0) & (step < max_steps[active])
            active, v, omega = active[keep], v[keep], omega[keep]
            if not len(active):
                break
            b = len(active)
            ctrl[:b, 0, 0], ctrl[:b, 0, 2] = v, omega
            out_state, sensordata = pool.rollout(m, datas, state[active], ctrl[:b], nstep=1,
                                                 initial_warmstart=np.zeros((b, m.nv)))
            state[active] = out_state[:, 0]
            log.add(active, state[active][:, qcols], np.column_stack([v, omega]),
                    sensordata[:, 0, rm.sensor: rm.sensor + 2])
    return _records(rm, starts, log, outcome, follow)
