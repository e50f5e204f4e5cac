"""A worked example for every command, shown at the end of its --help (and so in docs/cli.md).

They make one session from a fresh clone: `make demo` writes out/demo, and each example reads what the
examples before it wrote. tests/test_cli_docs.py parses every example line against its command's options.
"""

from __future__ import annotations

import textwrap

# command -> (example command line, what it does), in the order a newcomer would run them
EXAMPLES: dict[str, tuple[tuple[str, str], ...]] = {
    "demo": (
        ("sagebench demo --out out/demo --seed 0",
         "What `make demo` runs: the demo apartment through every stage into out/demo, then the oracle baseline, "
         "scored."),
    ),
    "synth-scene": (
        ("sagebench synth-scene --seed 3 --out scenes/apt3",
         "Another apartment (seed 3) as an artist scene: scenes/apt3/scene.json and scenes/apt3/meshes/."),
    ),
    "check-scene": (
        ("sagebench check-scene scenes/apt3",
         "Prints its rooms, objects, extent, door states and map size; writes nothing."),
    ),
    "import-interiorgs": (
        ("sagebench import-interiorgs InteriorGS/0001_839920 --out scenes/0001_839920",
         "A downloaded InteriorGS scene folder as a sagebench scene directory, with its summary line "
         "(docs/interiorgs.md); not part of the demo session: it needs the gated dataset."),
    ),
    "build-scene": (
        ("sagebench build-scene scenes/apt3 --out runs/apt3",
         "Maps and Gaussians into runs/apt3/scenes/demo_apartment_3/ (look at topdown.png there)."),
    ),
    "gen-trajectories": (
        ("sagebench gen-trajectories runs/apt3 --per-scene 50",
         "50 trajectories, each with two low-level and one high-level instruction, into "
         "runs/apt3/episodes/demo_apartment_3/."),
    ),
    "render": (
        ("sagebench render runs/apt3 --scene demo_apartment_3 --pose 3,2,0.8 --out view.png",
         "The view from (3, 2) m on the floor, heading 0.8 rad counter-clockwise from +X."),
    ),
    "export-usd": (
        ("sagebench export-usd runs/apt3 --workers 2",
         "Colliders, scene.usda + geometry.usdc and scene.xml beside the maps in runs/apt3/scenes/<id>/."),
    ),
    "validate": (
        ("sagebench validate runs/apt3",
         "Replays every trajectory in MuJoCo into runs/apt3/validation/; exit status 1 lists each failure."),
    ),
    "export-vlnce": (
        ("sagebench export-vlnce out/demo --out out/vlnce",
         "The demo's episodes as habitat R2R files: out/vlnce/<split>/<split>.json.gz, vocab.txt, scenes/."),
    ),
    "export-habitat": (
        ("sagebench export-habitat runs/tasks --out out/habitat",
         "The run's objectnav, pointnav and imagenav episodes as habitat-lab datasets: out/habitat/<task>/<split>/"
         "<split>.json.gz, scenes/."),
    ),
    "export-training": (
        ("sagebench export-training out/demo --out out/train --split val_seen",
         "The val_seen episodes as WebDataset shards of (view, instruction, action) in out/train/."),
    ),
    "export-sage": (
        ("sagebench export-sage runs/apt3 --out out/sage",
         "runs/apt3's episodes as SAGE-3D's GVLN trajectory file, out/sage/demo_apartment_3/"
         "trajectories_demo_apartment_3.json."),
    ),
    "import-sage-episodes": (
        ("sagebench import-sage-episodes out/sage/demo_apartment_3/trajectories_demo_apartment_3.json --run runs/apt3",
         "Reads them back as the episodes of the scene the file names (replacing its own), as SAGE-Bench's released "
         "episodes are read to be rolled out and evaluated here."),
    ),
    "run": (
        ("sagebench run out/demo/run.toml --workers 2",
         "The demo's run again: every stage whose inputs and settings are unchanged is skipped."),
    ),
    "verify": (
        ("sagebench verify out/demo",
         "Re-hashes every file against out/demo/manifest.json."),
        ("sagebench verify out/demo --regenerate --config out/demo/run.toml",
         "Regenerates the run into a temporary directory and compares it byte for byte."),
    ),
    "baseline": (
        ("sagebench baseline --agent straight --run out/demo --out straight.jsonl",
         "The straight-to-the-goal agent closed-loop over every demo episode."),
    ),
    "evaluate": (
        ("sagebench evaluate --run out/demo --predictions straight.jsonl --out scores.json",
         "Its SR, SPL, nDTW, CSR, ICP, ... overall, per level, type and split, printed and written as JSON."),
        ("sagebench evaluate --run out/demo --predictions straight.jsonl --visualize out/pictures",
         "The same scores, and one picture per episode in out/pictures/: the map, both paths, where the agent "
         "touched something, the instruction and the metrics."),
    ),
    "report": (
        ("sagebench report out/demo --predictions out/demo/baselines/oracle.jsonl --predictions straight.jsonl "
         "--out out/report",
         "The demo run and both agents as web pages: open out/report/index.html in a browser."),
    ),
    "rollout": (
        ("sagebench rollout --run out/demo --policy random --out random.jsonl --episodes 6",
         "Six episodes of the random policy, seeing 224x224 RGB and depth."),
        ("sagebench rollout --run out/demo --policy http://127.0.0.1:8000/act --out mine.jsonl",
         "Every episode with your policy server answering each step (the protocol: docs/agents.md)."),
    ),
    "schemas": (
        ("sagebench schemas --out schemas",
         "Rewrites schemas/*.schema.json and schemas/episode.arrow (what `make schemas` runs)."),
    ),
}


def epilog(command: str) -> str:
    """The examples of `command` as a click epilog, laid out here (click's \\b keeps each block as written): the
    command line, then what it does, indented and wrapped to fit 80 columns."""
    blocks = [f"\b\n  {line}\n" + textwrap.fill(what, 76, initial_indent="      ", subsequent_indent="      ")
              for line, what in EXAMPLES[command]]
    return "\n\n".join(["Example:" if len(blocks) == 1 else "Examples:", *blocks])
