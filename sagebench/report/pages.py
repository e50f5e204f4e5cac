"""The report's pages as HTML text: the overview, one page per scene, one per episode, and the agents compared.

Where the files lie (the pages link to each other and to local images only): index.html and agents.html at the
top, scenes/<scene>.html, episodes/<episode>.html, img/<scene>/topdown.png and the views
img/<scene>/<trajectory>_start.jpg and _goal.jpg.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

import numpy as np

from sagebench.evaluation.scoring import TASK_METRICS, EpisodeScore
from sagebench.report.agents import Agent
from sagebench.report.html import (
    AGENT_COLOURS, CONTACT, GOAL, REFERENCE, START, esc, facts, legend, num, page, slug, table,
)
from sagebench.report.run_facts import RunFacts, SceneFacts
from sagebench.report.svg import MapFrame, marker, svg_map

LABELS = {"sr": "SR", "osr": "OSR", "spl": "SPL", "ne": "NE", "ne_straight": "NE straight", "ndtw": "nDTW",
          "sdtw": "SDTW", "csr": "CSR", "icp": "ICP", "ps": "PS", "path_length": "length", "coverage": "coverage",
          "collisions": "collisions", "time": "time (s)"}
COMPARED = ("sr", "spl", "ne", "ndtw", "coverage", "icp")  # each agent's columns in the side-by-side table
SCENE_COLUMNS = ("sr", "ne", "coverage")  # each agent's columns in a scene's table of episodes
VALIDATION_FIGURES = {"csr": "CSR", "icp": "ICP", "ps": "PS", "ndtw": "nDTW", "final_distance": "NE",
                      "path_length": "length", "max_penetration": "deepest contact", "max_deviation": "pushed off",
                      "contact_steps": "steps with contact", "steps": "steps"}


def episode_href(root: str, episode_id: str) -> str:
    return f"{root}episodes/{slug(episode_id)}.html"


def scene_href(root: str, scene_id: str) -> str:
    return f"{root}scenes/{slug(scene_id)}.html"


def map_href(root: str, scene_id: str) -> str:
    return f"{root}img/{slug(scene_id)}/topdown.png"


def view_href(root: str, scene_id: str, trajectory_id: str, which: str) -> str:
    return f"{root}img/{slug(scene_id)}/{slug(trajectory_id)}_{which}.jpg"


def colour(i: int) -> str:
    return AGENT_COLOURS[i % len(AGENT_COLOURS)]


def tasks_scored(agents: Sequence[Agent]) -> list[str]:
    """The tasks of the episodes the agents were scored on, in TASK_METRICS' order."""
    present = {s.episode.task for a in agents for s in a.evaluation.scores}
    return [t for t in TASK_METRICS if t in present]


def columns(candidates: Sequence[str], agents: Sequence[Agent]) -> list[str]:
    """The metrics among `candidates` that some scored episode's task has (a VLN-only report: VLN's)."""
    names = {m for t in tasks_scored(agents) or ["vln"] for m in TASK_METRICS[t]}
    return [m for m in candidates if m in names]


def metric(sc: EpisodeScore | None, name: str) -> str:
    """An episode's metric as a cell: '-' without a score, for a missing prediction or where its task has none."""
    return num(None if sc is None or sc.missing else getattr(sc.metrics, name, None))


# ---------------------------------------------------------------- overview


def overview_page(run: RunFacts, agents: Sequence[Agent]) -> str:
    rows = [r for s in run.scenes for r in s.rows]
    trajectories = sum(len(s.trajectories()) for s in run.scenes)
    head = (f"<h1>{esc(run.run_dir.name or run.run_dir)}</h1>\n<p>{len(run.scenes)} scene(s), {trajectories} "
            f"trajectories, {len(rows)} episodes; run folder {esc(run.run_dir)}"
            + (f"; made by sagebench {esc(run.version)}" if run.version else "") + ".</p>")
    card = facts(run.card.items(), "card")
    return page(f"report: {run.run_dir.name}", "\n".join([
        head, "<h2>Scenes</h2>", _scenes_table(run), "<h2>Episodes</h2>", _counts_table(rows),
        "<h2>Validation</h2>", _validation_overview(run), *(["<h2>Agents</h2>", _agents_summary(agents),
                                                             '<p><a href="agents.html">every episode, side by side'
                                                             "</a></p>"] if agents else []),
        "<h2>Dataset card</h2>", card]), "")


def _scenes_table(run: RunFacts) -> str:
    rows = []
    for s in run.scenes:
        splits = ", ".join(sorted({r["split"] for r in s.rows}))
        passed = sum(bool(v["passed"]) for v in s.validation.values())
        checked = f"{passed} of {len(s.validation)} passed" if s.validation else "not validated"
        rows.append(f'<td><a href="{scene_href("", s.scene_id)}">{esc(s.scene_id)}</a></td>'
                    f'<td class="n">{len(s.trajectories())}</td><td class="n">{len(s.rows)}</td>'
                    f"<td>{esc(splits)}</td><td>{esc(checked)}</td>")
    return table(("scene", "trajectories", "episodes", "splits", "validation"), rows)


def _counts_table(rows: list[dict]) -> str:
    """Episodes by instruction level and type (rows) and split (columns)."""
    splits = sorted({r["split"] for r in rows})
    count = Counter((r["instruction_level"], r["instruction_type"], r["split"])
                    for r in rows)
    kinds = sorted({(lv, t) for lv, t, _ in count})
    body = [f"<td>{esc(lv)}</td><td>{esc(t)}</td>" + "".join(f'<td class="n">{count[(lv, t, s)]}</td>' for s in splits)
            + f'<td class="n">{sum(count[(lv, t, s)] for s in splits)}</td>' for lv, t in kinds]
    body.append('<th colspan="2">all</th>' + "".join(f'<td class="n">{sum(c for k, c in count.items() if k[2] == s)}'
                                                    "</td>" for s in splits) + f'<td class="n">{len(rows)}</td>')
    return table(("level", "instruction type", *splits, "all"), body)


def _validation_overview(run: RunFacts) -> str:
    checked = [(s, v) for s in run.scenes for v in s.validation.values()]
    if not checked:
        return '<p class="muted">Not validated: <code>sagebench validate RUN</code> replays every trajectory.</p>'
    passed = sum(bool(v["passed"]) for _, v in checked)
    reasons = Counter(r for _, v in checked for r in v["reasons"])
    out = [f"<p>{passed} of {len(checked)} trajectories passed ({100 * passed / len(checked):.1f} %).</p>",
           table(("failure reason", "trajectories"), (f'<td>{esc(r)}</td><td class="n">{n}</td>'
                                                      for r, n in sorted(reasons.items())))
           if reasons else '<p class="pass">No failures.</p>']
    failed = [(s, v) for s, v in checked if not v["passed"]]
    if failed:
        out.append(table(("scene", "trajectory", "reasons"), (
            f"<td>{esc(s.scene_id)}</td><td><a href=\"{episode_href('', v['episode_ids'][0])}\">"
            f"{esc(v['trajectory_id'])}</a></td><td>{esc(', '.join(v['reasons']))}</td>" for s, v in failed)))
    alignment = [s.scene_id for s in run.scenes if s.report and not s.report.get("alignment", {}).get("ok", True)]
    if alignment:
        out.append(f'<p class="fail">Splat and collider depths disagree in: {esc(", ".join(alignment))}.</p>')
    return "\n".join(out)


def _agents_summary(agents: Sequence[Agent]) -> str:
    """Each agent's means: one table, or one per task (by that task's metrics) when tasks other than VLN were
    scored."""
    tasks = tasks_scored(agents)
    if set(tasks) <= {"vln"}:
        return _agents_means(agents, "vln", "agents")
    return "\n".join(f"<h3>task {esc(t)}</h3>\n" + _agents_means(agents, t, f"agents-{t}") for t in tasks)


def _agents_means(agents: Sequence[Agent], task: str, ident: str) -> str:
    rows, names = [], TASK_METRICS[task]
    for i, a in enumerate(agents):
        ev = a.evaluation
        means = ev.summary.by_task.get(task)
        if means is None:
            continue
        missing = sum(s.missing for s in ev.scores if s.episode.task == task)
        rows.append(f'<td><span class="swatch" style="background:{colour(i)}"></span>{esc(a.name)}</td>'
                    f"<td>{esc(ev.predictions.name)}</td><td class=\"n\">{int(means['episodes'])}</td>"
                    f'<td class="n">{missing}</td>' + "".join(num(means[m]) for m in names))
    return table(("agent", "predictions", "episodes", "without prediction", *(LABELS[m] for m in names)),
                 rows, sortable=True, ident=ident)


# ---------------------------------------------------------------- agents side by side


def agents_page(run: RunFacts, agents: Sequence[Agent]) -> str:
    compared = columns(COMPARED, agents)
    head = ["episode", "scene", "split", "type"] + [f"{a.name} {LABELS[m]}" for a in agents for m in compared]
    rows = []
    for s in run.scenes:
        for r in s.rows:
            scores = [a.score(r["episode_id"]) for a in agents]
            if all(sc is None for sc in scores):
                continue
            cells = "".join(metric(sc, m) for sc in scores for m in compared)
            rows.append(f'<td><a href="{episode_href("", r["episode_id"])}">{esc(r["episode_id"])}</a></td>'
                        f"<td>{esc(s.scene_id)}</td><td>{esc(r['split'])}</td><td>{esc(r['instruction_type'])}</td>"
                        + cells)
    body = ["<h1>Agents</h1>", _agents_summary(agents),
            f"<h2>Every episode</h2>\n<p>{len(rows)} episodes; click a column to sort, '-' where an agent has no "
            "prediction.</p>", table(head, rows, sortable=True, ident="episodes")]
    return page("agents", "\n".join(body), "", [("index.html", "overview")])


# ---------------------------------------------------------------- scene


def scene_page(scene: SceneFacts, frame: MapFrame, agents: Sequence[Agent]) -> str:
    root = "../"
    items = []
    for tid, rows in scene.trajectories().items():
        path = np.asarray(rows[0]["reference_path"], dtype=np.float64)
        items.append(f'<g {_filter_attrs(rows)}><title>trajectory {esc(tid)}</title>'
                     f'<polyline class="reference" points="{frame.points(path)}"/>'
                     + marker(frame, rows[0]["start_position"], "start") + marker(frame, rows[0]["goal_position"],
                                                                                  "goal") + "</g>")
    splits = sorted({r["split"] for r in scene.rows})
    types = sorted({r["instruction_type"] for r in scene.rows})
    filters = (f"<p>Show split {_select('split', splits)} and instruction type {_select('type', types)}</p>")
    head = ["episode", "trajectory", "split", "level", "type", "instruction", "validation",
            *(f"{a.name} {LABELS[m]}" for a in agents for m in columns(SCENE_COLUMNS, agents))]
    rows = [f"<tr {_filter_attrs([r])}>" + _episode_cells(scene, r, agents) + "</tr>" for r in scene.rows]
    body = [f"<h1>Scene {esc(scene.scene_id)}</h1>",
            f"<p>{len(scene.trajectories())} trajectories, {len(scene.rows)} episodes.</p>", filters,
            svg_map(frame, map_href(root, scene.scene_id), items, title=f"trajectories of {scene.scene_id}",
                    cls="map scene"),
            legend([("reference path", REFERENCE), ("start", START), ("goal", GOAL)]),
            "<h2>Episodes</h2>", table(head, rows, sortable=True, ident="episodes")]
    return page(f"scene {scene.scene_id}", "\n".join(body), root, [("../index.html", "overview")])


def _filter_attrs(rows: list[dict]) -> str:
    splits = " ".join(sorted({r["split"] for r in rows}))
    types = " ".join(sorted({r["instruction_type"] for r in rows}))
    return f'data-split="{esc(splits)}" data-types="{esc(types)}"'


def _select(ident: str, values: list[str]) -> str:
    options = "".join(f'<option value="{esc(v)}">{esc(v)}</option>' for v in values)
    return f'<select class="filter" id="{ident}"><option value="">all</option>{options}</select>'


def _episode_cells(scene: SceneFacts, r: dict, agents: Sequence[Agent]) -> str:
    v = scene.validation.get(r["trajectory_id"])
    checked = "-" if v is None else ('<span class="pass">passed</span>' if v["passed"] else
                                     f'<span class="fail">{esc(", ".join(v["reasons"]))}</span>')
    text = r["instruction_text"] or ""
    cells = [f'<td><a href="{episode_href("../", r["episode_id"])}">{esc(r["episode_id"])}</a></td>',
             f"<td>{esc(r['trajectory_id'])}</td><td>{esc(r['split'])}</td><td>{esc(r['instruction_level'])}</td>",
             f"<td>{esc(r['instruction_type'])}</td><td>{esc(text[:120] + ('...' if len(text) > 120 else ''))}</td>",
             f"<td>{checked}</td>"]
    shown = columns(SCENE_COLUMNS, agents)
    cells += [metric(a.score(r["episode_id"]), m) for a in agents for m in shown]
    return "".join(cells)


# ---------------------------------------------------------------- episode


def episode_page(scene: SceneFacts, row: dict, frame: MapFrame, agents: Sequence[Agent], views: bool) -> str:
    root, eid, tid = "../", row["episode_id"], row["trajectory_id"]
    siblings = [r for r in scene.trajectories()[tid] if r["episode_id"] != eid]
    body = [f"<h1>Episode {esc(eid)}</h1>", _facts_table(row),
            "<h2>Instruction</h2>", f'<blockquote class="instruction" id="instruction">'
                                    f'{esc(row["instruction_text"] or "(no instruction: a bare trajectory)")}</blockquote>']
    if siblings:
        body += ["<h3>The other instructions of this trajectory</h3>", "<ul>" + "".join(
            f'<li><a href="{episode_href(root, r["episode_id"])}">{esc(r["instruction_level"])} / '
            f'{esc(r["instruction_type"])}</a>: {esc(r["instruction_text"] or "")}</li>' for r in siblings) + "</ul>"]
    body += ["<h2>Path</h2>", _episode_map(row, frame, agents)]
    if views:
        body += ["<h2>Views</h2>", *(f'<figure><img src="{view_href(root, scene.scene_id, tid, w)}" alt="{w} view" '
                                     f'width="160" height="120"><figcaption>{caption}</figcaption></figure>'
                                     for w, caption in (("start", "at the start, facing its heading"),
                                                        ("goal", "at the end of the reference path")))]
    body += ["<h2>Validation</h2>", _validation_result(scene.validation.get(tid))]
    if agents:
        body += ["<h2>Agents</h2>", _metrics_table(row, agents), _contact(row, agents)]
    crumbs = [("../index.html", "overview"), (scene_href(root, scene.scene_id), f"scene {scene.scene_id}")]
    return page(f"episode {eid}", "\n".join(body), root, crumbs)


def _facts_table(row: dict) -> str:
    def end(kind: str) -> str:
        inst = row[f"{kind}_instance_id"]
        return f"room {row[f'{kind}_room'] or '-'}" + (f", instance {inst}" if inst is not None else "")

    items = [("scene", row["scene_id"]), ("trajectory", row["trajectory_id"]), ("split", row["split"]),
             ("instruction", f"{row['instruction_level']} / {row['instruction_type']} "
                             f"({row['instruction_source'] or 'none'})"),
             ("start", end("start")), ("goal", end("goal")),
             ("geodesic distance", f"{row['geodesic_distance']:.2f} m"), ("goal radius", f"{row['goal_radius']:g} m"),
             ("seed", row["seed"])]
    return facts(items, "facts")


def _episode_map(row: dict, frame: MapFrame, agents: Sequence[Agent]) -> str:
    ref = np.asarray(row["reference_path"], dtype=np.float64)
    items = [f'<polyline class="reference" points="{frame.points(ref)}"><title>reference path</title></polyline>']
    shown = [frame.pixels(ref)]
    entries = [("reference path", REFERENCE), ("start", START), ("goal and its radius", GOAL)]
    for i, a in enumerate(agents):
        sc = a.score(row["episode_id"])
        if sc is None or sc.prediction is None:
            continue
        poses = np.asarray(sc.prediction.poses, dtype=np.float64)
        items.append(f'<polyline class="agent" data-agent="{esc(a.name)}" stroke="{colour(i)}" '
                     f'points="{frame.points(poses)}"><title>{esc(a.name)}</title></polyline>')
        if sc.intensity is not None:
            items += [marker(frame, p, "contact") for p in poses[np.asarray(sc.intensity) > 0]]
        shown.append(frame.pixels(poses))
        entries.append((a.name, colour(i)))
    items += [marker(frame, row["start_position"], "start"),
              marker(frame, row["goal_position"], "goal", row["goal_radius"])]
    goal, radius = frame.pixels(np.asarray([row["goal_position"]])), frame.metres(row["goal_radius"])
    around = np.concatenate([*shown, goal - radius, goal + radius])  # the goal's ring too
    if any(sc is not None and sc.intensity is not None for sc in (a.score(row["episode_id"]) for a in agents)):
        entries.append(("contact", CONTACT))
    return svg_map(frame, map_href("../", row["scene_id"]), items, around=around,
                   title=f"episode {row['episode_id']}") + legend(entries)


def _validation_result(v: dict | None) -> str:
    if v is None:
        return '<p class="muted">Not validated: <code>sagebench validate RUN</code> replays every trajectory.</p>'
    verdict = ('<p class="pass">The reference path replays in MuJoCo: passed.</p>' if v["passed"] else
               f'<p class="fail">The replay failed: {esc(", ".join(v["reasons"]))}.</p>')
    cells = "".join(num(float(v[k]), 0 if k.endswith("steps") else 3) for k in VALIDATION_FIGURES)
    return verdict + table(VALIDATION_FIGURES.values(), [cells])


def _metrics_table(row: dict, agents: Sequence[Agent]) -> str:
    """Each agent's scores of the episode, by its task's metrics."""
    rows, names = [], TASK_METRICS[row.get("task") or "vln"]
    for i, a in enumerate(agents):
        name = f'<td><span class="swatch" style="background:{colour(i)}"></span>{esc(a.name)}</td>'
        sc = a.score(row["episode_id"])
        if sc is None or sc.prediction is None:
            why = "not run (the rollout was not asked to)" if sc is None else "no prediction: every metric at its worst"
            rows.append(name + f'<td colspan="{len(names) + 3}">{esc(why)}</td>')
            continue
        rows.append(name + "".join(num(getattr(sc.metrics, m)) for m in names)
                    + f'<td class="n">{len(sc.prediction.poses)}</td><td>{"yes" if sc.prediction.stopped else "no"}</td>'
                    f"<td>{esc(sc.icp_source)}</td>")
    head = ("agent", *(LABELS[m] for m in names), "poses", "stopped", "c(t)")
    return table(head, rows, ident="metrics")


def _contact(row: dict, agents: Sequence[Agent]) -> str:
    """Each agent's c(t) per step as bars (a bar per step with contact, its height c)."""
    out = ["<h3>Contact per step</h3>"]
    for i, a in enumerate(agents):
        sc = a.score(row["episode_id"])
        if sc is None or sc.intensity is None:
            continue
        c = np.asarray(sc.intensity, dtype=np.float64)
        step = max(1.0, min(4.0, 600 / len(c)))
        bars = "".join(f'<rect x="{k * step:.1f}" y="{30 - 30 * v:.1f}" width="{max(step - 0.5, 1):.1f}" '
                       f'height="{30 * v:.1f}" fill="{CONTACT}"><title>step {k}: c = {v:.2f}</title></rect>'
                       for k, v in enumerate(c) if v > 0)
        out.append(f'<p><span class="swatch" style="background:{colour(i)}"></span>{esc(a.name)}: '
                   f"{int(np.count_nonzero(c > 0))} of {len(c)} steps with contact, ICP {sc.metrics.icp:.3f}<br>"
                   f'<svg class="contact-strip" width="{len(c) * step:.0f}" height="31" role="img" '
                   f'aria-label="contact per step of {esc(a.name)}"><line x1="0" y1="30.5" x2="{len(c) * step:.0f}" '
                   f'y2="30.5" stroke="#999"/>{bars}</svg></p>')
    return "\n".join(out) if len(out) > 1 else ""
