"""The report's HTML pieces: the page around a body, tables, and its one style sheet and one script (local
files beside the pages, no network). Every text put into a page goes through `esc`."""

from __future__ import annotations

import hashlib
import html
import re
from collections.abc import Iterable, Sequence

CSS_FILE, JS_FILE = "report.css", "report.js"
REFERENCE, START, GOAL, CONTACT = "#1f77b4", "#00aa00", "#c80000", "#d62728"
AGENT_COLOURS = ("#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22", "#7f7f7f", "#2ca02c")

CSS = f"""body {{ font: 14px/1.4 system-ui, sans-serif; margin: 0 auto; max-width: 1200px; padding: 0 16px 40px; }}
nav {{ padding: 10px 0; border-bottom: 1px solid #ddd; margin-bottom: 8px; }}
table {{ border-collapse: collapse; margin: 8px 0 16px; }}
th, td {{ border: 1px solid #ddd; padding: 3px 8px; text-align: left; vertical-align: top; }}
td.n {{ text-align: right; font-variant-numeric: tabular-nums; }}
table.sortable th {{ cursor: pointer; background: #f4f4f4; }}
table.sortable th:after {{ content: " \\2195"; color: #999; }}
.off {{ display: none; }}
.instruction {{ font-size: 18px; background: #f6f8fa; border-left: 4px solid {REFERENCE}; padding: 8px 12px; }}
.pass {{ color: #1a7f37; }} .fail {{ color: #cf222e; }}
svg.map {{ max-width: 100%; height: auto; border: 1px solid #ddd; }}
polyline {{ fill: none; stroke-linejoin: round; stroke-linecap: round; }}
polyline.reference {{ stroke: {REFERENCE}; stroke-width: 4; stroke-opacity: 0.8; }}
svg.scene polyline.reference {{ stroke-width: 2; }}
svg.scene g:hover polyline.reference {{ stroke: #ff7f0e; stroke-width: 4; stroke-opacity: 1; }}
polyline.agent {{ stroke-width: 2.5; }}
.swatch {{ display: inline-block; width: 12px; height: 12px; margin: 0 4px 0 12px; vertical-align: -1px; }}
figure {{ display: inline-block; margin: 0 16px 8px 0; }}
figcaption {{ color: #555; }}
.muted {{ color: #666; }}
"""

# sorting any table.sortable by a header click (numbers by data-v), and the split/type filter of scene pages
JS = """document.querySelectorAll('table.sortable th').forEach((th) => th.addEventListener('click', () => {
  const body = th.closest('table').tBodies[0], i = th.cellIndex, up = th.dataset.dir !== 'up';
  th.dataset.dir = up ? 'up' : 'down';
  const key = (row) => {
    const c = row.cells[i];
    return c.dataset.v !== undefined ? parseFloat(c.dataset.v) : c.textContent;
  };
  const order = (a, b) => { const x = key(a), y = key(b); return (x < y ? -1 : x > y ? 1 : 0) * (up ? 1 : -1); };
  Array.from(body.rows).sort(order).forEach((r) => body.appendChild(r));
}));
function applyFilter() {
  const split = document.getElementById('split').value, type = document.getElementById('type').value;
  document.querySelectorAll('[data-split]').forEach((el) => {
    const has = (values, v) => !v || values.split(' ').includes(v);
    el.classList.toggle('off', !(has(el.dataset.split, split) && has(el.dataset.types, type)));
  });
}
document.querySelectorAll('select.filter').forEach((s) => s.addEventListener('change', applyFilter));
"""


def esc(text: object) -> str:
    return html.escape(str(text), quote=True)


def slug(name: str) -> str:
    """A file name for `name` (an episode, trajectory or scene id): itself when it is a plain name, else a hash."""
    if re.fullmatch(r"[A-Za-z0-9_-][A-Za-z0-9_.-]{0,99}", name):
        return name
    return "x" + hashlib.sha256(name.encode()).hexdigest()[:16]


def page(title: str, body: str, root: str, crumbs: Sequence[tuple[str, str]] = ()) -> str:
    """A whole page: `root` is the way from it to the report's top folder ("" or "../"); `crumbs` (href, text)
    are the pages above it."""
    nav = " / ".join(f'<a href="{esc(h)}">{esc(t)}</a>' for h, t in crumbs)
    return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n<title>{esc(title)}</title>\n'
            f'<link rel="icon" href="data:,">\n<link rel="stylesheet" href="{root}{CSS_FILE}">\n</head>\n<body>\n'
            f'<nav>{nav or "sagebench report"}</nav>\n{body}\n<script src="{root}{JS_FILE}"></script>\n</body>\n'
            "</html>\n")


def num(value: float | None, digits: int = 3) -> str:
    """A table cell with a number (sortable by its value); '-' for none."""
    if value is None or value != value:
        return '<td class="n" data-v="-1e300">-</td>'
    return f'<td class="n" data-v="{value:.6g}">{value:.{digits}f}</td>'


def table(head: Iterable[str], rows: Iterable[str], *, sortable: bool = False, ident: str = "") -> str:
    """A table; each of `rows` is a row's cells (HTML), or a whole '<tr ...>' element where the row carries
    attributes (a filter's data-split)."""
    cls = ' class="sortable"' if sortable else ""
    ident = f' id="{esc(ident)}"' if ident else ""
    head_html = "".join(f"<th>{esc(h)}</th>" for h in head)
    body = "\n".join(r if r.startswith("<tr") else f"<tr>{r}</tr>" for r in rows)
    return f"<table{cls}{ident}>\n<thead><tr>{head_html}</tr></thead>\n<tbody>\n{body}\n</tbody>\n</table>"


def facts(items: Iterable[tuple[str, object]], ident: str = "") -> str:
    """A table of names and values, one pair a row."""
    ident = f' id="{esc(ident)}"' if ident else ""
    rows = "\n".join(f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>" for k, v in items)
    return f'<table class="facts"{ident}>\n<tbody>\n{rows}\n</tbody>\n</table>'


def legend(items: Iterable[tuple[str, str]]) -> str:
    return '<p class="legend">' + "".join(f'<span class="swatch" style="background:{c}"></span>{esc(n)}'
                                          for n, c in items) + "</p>"
