"""Imported and predicted values are checked as generated ones are: every damaged GVLN file that
import-sage-episodes reads is refused in one line naming the file and the field (exit 2, every file beside it
hashed unchanged); a path point just off the navigable map is moved onto it and counted; an input that is a FIFO
or a device is refused by its type before it is opened; a prediction far off the map reaches no numpy warning.

Companion of test_fuzz_inputs.py (its tiny scene and run); the last test counts this file's distinct inputs.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
import resource
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from test_fuzz_inputs import snapshot

SPLITS = "Input should be 'train', 'val_seen', 'val_unseen', 'test', 'trajectory_unseen' or 'instruction_unseen'"
TYPES = ("Input should be 'Add_Object', 'Scenario_Driven', 'Relative_Relationship', 'Attribute_Based', "
         "'Area_Based', 'Single_Goal' or 'Base_Action'")
HEX16 = "String should match pattern '^[0-9a-f]{16}$'"


@pytest.fixture(scope="module")
def gvln(tiny_run) -> dict:
    """The tiny run's episodes as the GVLN document export-sage writes. Read-only: deep-copy it."""
    from sagebench.episodes.shards import read_episodes
    from sagebench.gvln.episodes import gvln_document
    from sagebench.scene.loader import parse_spec

    rows = read_episodes(tiny_run / "episodes" / "tiny").to_pylist()
    return gvln_document("tiny", rows, parse_spec((tiny_run / "scenes" / "tiny" / "scene.json").read_text(), "x"))


def _sample(edit: Callable[[dict], Any], k: int = 0) -> Callable[[dict], None]:
    def apply(doc: dict) -> None:
        edit(doc["scenes"][0]["samples"][k])
    return apply


def _extra(**changes: Any) -> Callable[[dict], None]:
    return _sample(lambda s: s["sagebench"].update(changes))


def _instruction(k: int = 0, **changes: Any) -> Callable[[dict], None]:
    return _sample(lambda s: s["instructions"][k].update(changes))


def _own(k: int = 0, **changes: Any) -> Callable[[dict], None]:
    return _sample(lambda s: s["instructions"][k]["sagebench"].update(changes))


def _point(position: list[float], j: int = 1) -> Callable[[dict], None]:
    return _sample(lambda s: s["points"][j].update(position=position))


def _every_instruction(edit: Callable[[dict], None]) -> Callable[[dict], None]:
    def apply(doc: dict) -> None:
        for sample in doc["scenes"][0]["samples"]:
            for ins in sample["instructions"]:
                edit(ins)
    return apply


def _plain_twice(doc: dict) -> None:
    """Each sample twice, as SAGE-3D writes them (its own trajectory ids, no sagebench keys): 24 rows for 12 ids."""
    samples = doc["scenes"][0]["samples"]
    for i, s in enumerate(samples):
        s.pop("sagebench")
        s["trajectory_id"] = str(i)
        for ins in s["instructions"]:
            ins.pop("sagebench")
    samples += copy.deepcopy(samples)


def _text(text: str) -> Callable[[dict], str]:
    return lambda doc: text


def _json_with(marker: Any, raw: str, edit: Callable[[dict, Any], None]) -> Callable[[dict], str]:
    """The document with `raw` (text json cannot write) where `edit` puts `marker`."""
    def apply(doc: dict) -> str:
        edit(doc, marker)
        return json.dumps(doc).replace(json.dumps(marker), raw, 1)
    return apply


S0 = "scenes[0].samples[0]"
# (case id, damage to the tiny run's GVLN document (or, from _text and _json_with, the text to write instead), the
# error line after "FILE: ")
SAGE_CASES: list[tuple[str, Callable[[dict], Any], str]] = [
    ("int-5000-digits", _json_with("@seed@", "9" * 5000, lambda d, m: d["scenes"][0]["samples"][0]["sagebench"]
                                   .update(seed=m)),
     "malformed JSON: Exceeds the limit (4300 digits) for integer string conversion: value has 5000 digits"),
    ("nested-200000", _text("[" * 200_000 + "]" * 200_000), "JSON nested too deeply"),
    ("goal-radius-big", _extra(goal_radius="big"),
     f"{S0}.sagebench.goal_radius: Input should be a valid number, unable to parse string as a number"),
    ("goal-radius-negative", _extra(goal_radius=-1), f"{S0}.sagebench.goal_radius: Input should be greater than 0"),
    ("goal-radius-0", _extra(goal_radius=0.0), f"{S0}.sagebench.goal_radius: Input should be greater than 0"),
    ("goal-radius-inf", _json_with("@r@", "Infinity", lambda d, m: d["scenes"][0]["samples"][0]["sagebench"]
                                   .update(goal_radius=m)), f"{S0}.sagebench.goal_radius: Input should be a finite number"),
    ("goal-instance-2**70", _extra(goal_instance_id=2**70),
     f"{S0}.sagebench.goal_instance_id: Input should be less than or equal to 2147483647"),
    ("goal-instance-unknown", _extra(goal_instance_id=999),
     f"{S0}.sagebench.goal_instance_id: 999 is not an instance of scene 'tiny'"),
    ("start-room-unknown", _extra(start_room="attic"), f"{S0}.sagebench.start_room: 'attic' is not a room of scene 'tiny'"),
    ("seed-negative", _extra(seed=-1), f"{S0}.sagebench.seed: Input should be greater than or equal to 0"),
    ("split-outside-the-run", _extra(split="../../../../../other/episodes/tiny/part-train"), f"{S0}.sagebench.split: {SPLITS}"),
    ("split-empty", _extra(split=""), f"{S0}.sagebench.split: {SPLITS}"),
    ("split-newline", _extra(split="tr\nain"), f"{S0}.sagebench.split: {SPLITS}"),
    ("trajectory-id-path", _extra(trajectory_id="../x"), f"{S0}.sagebench.trajectory_id: {HEX16}"),
    ("episode-id-newline", _own(episode_id="a\nb"), f"{S0}.instructions[0].sagebench.episode_id: {HEX16}"),
    ("instruction-type-unknown", _own(instruction_type="Teleport"), f"{S0}.instructions[0].sagebench.instruction_type: {TYPES}"),
    ("instruction-level-wrong", _own(instruction_type="Base_Action", instruction_level="high"),
     f"{S0}.instructions[0].sagebench: instruction_level 'high', but Base_Action is a low-level type"),
    ("goal-100m-off", _point([100.0, 0.0, 0.5]), f"{S0}.points[1].position: (100, 0) is off the navigable map of "
                                                 "scene 'tiny': no navigable cell within 0.5 m"),
    ("coordinates-1e308", _point([1e308, -1e308, 0.5]), f"{S0}.points[1].position: (1e+308, -1e+308) is off the "
                                                        "navigable map of scene 'tiny': no navigable cell within 0.5 m"),
    ("point-in-the-table", _point([-1.0, -1.0, 0.5]), f"{S0}.points[1].position: (-1, -1) is off the navigable map of "
                                                      "scene 'tiny': no navigable cell within 0.5 m"),
    ("one-point-path", _sample(lambda s: s.update(points=s["points"][:1])),
     f"{S0}.points: 1 point: a vln sample is a path, its start and goal at least"),
    ("episode-ids-all-the-same", _every_instruction(lambda ins: ins["sagebench"].update(episode_id="0" * 16)),
     f"{S0}.instructions[1].sagebench.episode_id: episode id '0000000000000000' again (first at "
     f"{S0}.instructions[0].sagebench.episode_id): each episode has its own id"),
    ("samples-twice", _plain_twice, "scenes[0].samples[4].trajectory_id: trajectory id '0' again (first at "
                                    "scenes[0].samples[0].trajectory_id): each trajectory has its own id"),
    ("instruction-empty", _instruction(generated_instruction=""),
     f"{S0}.instructions[0].generated_instruction: an empty instruction"),
    ("instruction-blank", _instruction(generated_instruction=" \t "),
     f"{S0}.instructions[0].generated_instruction: an empty instruction"),
    ("instruction-text-missing", _sample(lambda s: s["instructions"][0].pop("generated_instruction")),
     f"{S0}.instructions[0].generated_instruction: Field required"),
    ("instruction-bare-empty-string", _sample(lambda s: s.update(instructions=["Go to the table.", ""])),
     f"{S0}.instructions[1].generated_instruction: an empty instruction"),
]


def _refused_exactly(run_cli, args: list, where: Path, line: str) -> None:
    """Exit 2, nothing on stdout, exactly `error: LINE` on stderr, every file under `where` unchanged."""
    before = snapshot(where), sorted(str(p.relative_to(where)) for p in where.rglob("*"))
    code, out, err = run_cli(*args)
    assert (code, out, err) == (2, "", f"error: {line}\n")
    assert (snapshot(where), sorted(str(p.relative_to(where)) for p in where.rglob("*"))) == before


def _run_copy(tiny_run: Path, tmp_path: Path) -> Path:
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run, symlinks=True)
    return run


@pytest.mark.parametrize("damage, expect", [c[1:] for c in SAGE_CASES], ids=[c[0] for c in SAGE_CASES])
def test_damaged_gvln_files(damage, expect, gvln, tiny_run, run_cli, tmp_path):
    run = _run_copy(tiny_run, tmp_path)
    doc = copy.deepcopy(gvln)
    text = damage(doc)
    path = tmp_path / "trajectories_tiny.json"
    path.write_text(text if isinstance(text, str) else json.dumps(doc))
    _refused_exactly(run_cli, ["import-sage-episodes", path, "--run", run], tmp_path, f"{path}: {expect}")


def test_a_start_and_a_goal_just_off_the_map_are_moved_onto_it_and_counted(gvln, tiny_run, run_cli, tmp_path):
    """(3.0, 0.05) lies 0.175 m from the nearest navigable cell (the floor's edge less the agent's radius): one
    sample's start and another's goal there move to that cell's centre, the summary counts them (starts and goals,
    the farthest move), and every other value is the file's."""
    from sagebench.episodes.shards import read_episodes

    run = _run_copy(tiny_run, tmp_path)
    doc = copy.deepcopy(gvln)
    samples = doc["scenes"][0]["samples"]
    samples[0]["points"][0]["position"] = [-3.0, -0.05, 0.5]  # SAGE-3D's frame: x and y turned by 180 degrees
    samples[1]["points"][-1]["position"] = [-3.0, -0.05, 0.5]
    path = tmp_path / "trajectories_tiny.json"
    path.write_text(json.dumps(doc))
    code, out, err = run_cli("import-sage-episodes", path, "--run", run)
    assert (code, err) == (0, "")
    assert out.startswith("import-sage-episodes tiny: 4 trajectories, 12 episode rows, 2 path points snapped onto the "
                          "navigable map (within 0.5 m; 1 starts, 1 goals, the farthest 0.18 m) -> ")
    rows = read_episodes(run / "episodes" / "tiny").to_pylist()
    before = {r["episode_id"]: r for r in read_episodes(tiny_run / "episodes" / "tiny").to_pylist()}
    moved = [r for r in rows if r["trajectory_id"] == samples[0]["sagebench"]["trajectory_id"]]
    assert len(moved) == 3 and all(r["start_position"][:2] == pytest.approx([3.025, 0.225]) for r in moved)
    assert all(r["reference_path"][0][:2] == r["start_position"][:2] for r in moved)
    ended = [r for r in rows if r["trajectory_id"] == samples[1]["sagebench"]["trajectory_id"]]
    assert ended and all(r["goal_position"][:2] == pytest.approx([3.025, 0.225]) for r in ended)
    moved += ended
    for row in (r for r in rows if r not in moved):  # the frame's turn and back moves the last bit at most
        old = before[row["episode_id"]]
        assert all(np.allclose(row[c], old[c], atol=1e-9) if isinstance(old[c], float | list) else row[c] == old[c]
                   for c in old), row["episode_id"]


def _fifo(tmp_path: Path) -> Path:
    os.mkfifo(tmp_path / "fifo.json")
    return tmp_path / "fifo.json"


def _fifo_map(tmp_path: Path) -> Path:
    os.unlink(tmp_path / "run" / "scenes" / "tiny" / "semantic_map.json")
    os.mkfifo(tmp_path / "run" / "scenes" / "tiny" / "semantic_map.json")
    return tmp_path / "trajectories_tiny.json"


INPUT_KINDS = {  # an input of another kind than a file -> the command, and its line after the path
    "fifo": (_fifo, "import-sage-episodes", "{f}: is a FIFO, not a file or folder: sagebench reads inputs from "
                                            "regular files only"),
    "dev-zero": (lambda tmp_path: Path("/dev/zero"), "import-sage-episodes",
                 "/dev/zero: is a character device, not a file or folder: sagebench reads inputs from regular files only"),
    "fifo-semantic-map": (_fifo_map, "gen-trajectories", "{run}/scenes/tiny/semantic_map.json: is a FIFO, not a file: "
                                                         "sagebench reads inputs from regular files only (run "
                                                         "build-scene first)"),
}


def _limited() -> None:
    """The child's memory, bounded: a command that reads /dev/zero whole fails fast instead of filling the machine."""
    resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))


@pytest.mark.parametrize("case", list(INPUT_KINDS))
def test_fifos_and_devices_are_refused_by_type_before_they_are_read(case, gvln, tiny_run, tmp_path):
    """Real processes, with a deadline: on a FIFO the read would wait for a writer forever."""
    run = _run_copy(tiny_run, tmp_path)
    (tmp_path / "trajectories_tiny.json").write_text(json.dumps(gvln))
    make, command, expect = INPUT_KINDS[case]
    path = make(tmp_path)
    args = [path, "--run", run] if command == "import-sage-episodes" else [run]
    before = snapshot(run)
    proc = subprocess.run([sys.executable, "-m", "sagebench", command, *map(str, args)], capture_output=True,
                          text=True, timeout=120, preexec_fn=_limited)
    assert (proc.returncode, proc.stdout, proc.stderr) == (2, "", f"error: {expect.format(f=path, run=run)}\n")
    assert snapshot(run) == before


def test_a_prediction_off_the_map_is_refused_without_a_numpy_warning(tiny_run, tmp_path):
    """A real process (pytest would catch the warnings): one line on stderr and nothing else."""
    rows = [json.loads(line) for line in (tiny_run / "baselines" / "oracle.jsonl").read_text().splitlines()]
    for r in rows:
        r.pop("collision_intensity"), r.pop("intensity_source")
    rows[0]["poses"][-1][:2] = [1e308, 1e308]
    (tmp_path / "pred.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    before = snapshot(tmp_path)
    proc = subprocess.run([sys.executable, "-m", "sagebench", "evaluate", "--run", str(tiny_run), "--predictions",
                           str(tmp_path / "pred.jsonl"), "--out", str(tmp_path / "scores.json")],
                          capture_output=True, text=True, timeout=120)
    n = len(rows[0]["poses"]) - 1
    assert (proc.returncode, proc.stdout, proc.stderr) == (
        2, "", f"error: {tmp_path / 'pred.jsonl'}:1: poses[{n}]: (1e+308, 1e+308) lies more than 50 m outside the "
               "scene's map (x -0.1..6.1, y -0.1..4.2 m)\n")
    assert snapshot(tmp_path) == before


def test_every_case_is_a_distinct_input():
    """This file's damaged inputs, each distinct, counted on top of test_fuzz_inputs' and test_fuzz_safety's."""
    def sample() -> dict:
        return {"trajectory_id": "t", "points": [{"position": [0, 0, 0], "rotation": [0, 0, 0, 1]} for _ in range(2)],
                "instructions": [{"generated_instruction": "Go.", "sagebench": {}} for _ in range(2)], "sagebench": {}}

    texts = set()
    for _, damage, _ in SAGE_CASES:
        d = {"scenes": [{"scene_name": "tiny", "samples": [sample(), sample()]}]}
        out = damage(d)
        texts.add(hashlib.sha256((out if isinstance(out, str) else json.dumps(d)).encode()).hexdigest())
    names = [c[0] for c in SAGE_CASES] + list(INPUT_KINDS) + ["snapped-point", "prediction-1e308-process"]
    assert len(texts) == len(SAGE_CASES) and len(set(names)) == len(names) >= 30
