"""topdown.npz, written and read back in one place: what it holds, and the checks of the arrays every consumer
needs."""

from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from sagebench.errors import DataError
from sagebench.topdown.passages import PASSAGE

if TYPE_CHECKING:
    from sagebench.topdown.builder import Topdown


@dataclass(frozen=True)
class TopdownGrids:
    navigable: np.ndarray  # [H, W] uint8, 1 = the agent's centre may stand here, PASSAGE = at its anchor
    occupancy: np.ndarray  # [H, W] uint8, 1 = blocked in the agent's height band
    resolution: float  # metres per cell
    origin: tuple[float, float]  # world (x, y) of cell (0, 0)'s lower-left corner
    anchors: dict[tuple[int, int], tuple[float, float]] = field(default_factory=dict)  # PASSAGE cell -> world (x, y)


def read_topdown_grids(npz_path: Path) -> TopdownGrids:
    """navigable, occupancy, resolution and origin of a topdown.npz; a missing or malformed one is a DataError."""
    if not Path(npz_path).is_file():
        raise DataError("missing: run build-scene first", path=npz_path)
    try:
        with np.load(npz_path) as npz:
            arrays = {k: npz[k] for k in ("navigable", "occupancy", "resolution", "origin", "passage_cells",
                                          "passage_xy") if k in npz.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as err:
        raise DataError(f"cannot read: {err}", path=npz_path) from None
    for key in ("navigable", "occupancy", "resolution", "origin"):
        if key not in arrays:
            raise DataError("array missing", path=npz_path, field=key)
    nav, occ = arrays["navigable"], arrays["occupancy"]
    if nav.ndim != 2 or occ.shape != nav.shape:
        raise DataError(f"navigable {nav.shape} and occupancy {occ.shape} must be the same [H, W] shape",
                        path=npz_path, field="navigable")
    for key, grid, allowed in (("navigable", nav, (0, 1, PASSAGE)), ("occupancy", occ, (0, 1))):
        problem = _off_values(grid, allowed)
        if problem is not None:
            raise DataError(f"{key} must hold {'/'.join(map(str, allowed))} only: {problem}; run build-scene again",
                            path=npz_path, field=key)
    if not nav.any():
        raise DataError("no navigable cell: run build-scene again (with a smaller agent radius if it says so)",
                        path=npz_path, field="navigable")
    origin = np.asarray(arrays["origin"], dtype=np.float64).ravel()
    resolution = float(np.asarray(arrays["resolution"]).ravel()[0])
    if origin.shape != (2,) or not np.isfinite(origin).all() or not 0 < resolution < np.inf:
        raise DataError(f"origin must be finite [x, y] and resolution > 0 (got {origin.tolist()}, {resolution})",
                        path=npz_path, field="origin")
    cells, xy = arrays.get("passage_cells", np.zeros((0, 2))), arrays.get("passage_xy", np.zeros((0, 2)))
    if cells.shape != xy.shape or (len(cells) and not np.all(nav[tuple(cells.astype(np.int64).T)] == PASSAGE)):
        raise DataError("passage_cells must be PASSAGE cells of navigable, one passage_xy each", path=npz_path,
                        field="passage_cells")
    nav = np.where(nav == PASSAGE, PASSAGE, nav != 0).astype(np.uint8)
    anchors = {(int(r), int(c)): (float(x), float(y)) for (r, c), (x, y) in zip(cells, xy)}
    return TopdownGrids(np.ascontiguousarray(nav), np.asarray(occ, dtype=np.uint8), resolution,
                        (float(origin[0]), float(origin[1])), anchors)


def topdown_bytes(td: Topdown) -> bytes:
    """build-scene's topdown.npz: the maps, the passages judged on exact geometry, the grid and the category
    names, with fixed zip timestamps, so equal maps give equal bytes."""
    return _npz_bytes({
        "instance": td.instance,
        "category": td.category,
        "occupancy": td.occupancy,
        "navigable": td.navigable,
        "passage_cells": td.passages.cells,
        "passage_xy": td.passages.anchors,
        "region": td.region,
        "resolution": np.float64(td.grid.resolution),
        "origin": np.asarray(td.grid.origin, dtype=np.float64),
        "category_names": np.asarray(td.categories, dtype=np.str_),
    })


def _off_values(grid: np.ndarray, allowed: tuple[int, ...]) -> str | None:
    """What makes a [H, W] map hold other than the `allowed` cell values (non-numbers, NaN, other values); None
    when it holds only those."""
    if grid.dtype.kind not in "biuf":
        return f"dtype {grid.dtype}"
    if grid.dtype.kind == "f" and not np.isfinite(grid).all():
        return f"{int((~np.isfinite(grid)).sum()):,} non-finite cells"
    other = int((~np.isin(grid, allowed)).sum())
    return f"{other:,} cells hold other values" if other else None


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    """An .npz (np.load reads it) with fixed zip timestamps, so equal arrays give equal bytes."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, arr in arrays.items():
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            data = io.BytesIO()
            np.lib.format.write_array(data, np.asarray(arr), allow_pickle=False)
            zf.writestr(info, data.getvalue())
    return buf.getvalue()
