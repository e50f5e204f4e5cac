"""Sweet Home 3D furniture catalogues: their entries, and each OBJ model as a Z-up metre mesh at its catalogue size.

A catalogue is a directory or a `.sh3f` zip holding `PluginFurnitureCatalog.properties` (entries
`key#N=value`: name, model path, width/depth/height in cm, optional modelRotation and elevation) and the
OBJ + MTL files it names. Sweet Home 3D models are Y-up with their front towards +Z and in arbitrary units;
Sweet Home 3D stretches each to width x height x depth and stands it `elevation` above the floor, and so
does sagebench: `load_model` gives the model at that size, the scene places its bottom at the elevation.
"""

from __future__ import annotations

import io
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from sagebench.errors import SceneError

CATALOGUE_FILE = "PluginFurnitureCatalog.properties"

# The synth apartment's categories and the head nouns (last word of an entry's name) that can fill them.
CATEGORY_NOUNS: dict[str, frozenset[str]] = {
    "sofa": frozenset({"sofa", "couch"}),
    "armchair": frozenset({"armchair"}),
    "chair": frozenset({"chair"}),
    "office_chair": frozenset({"chair"}),
    "coffee_table": frozenset({"table"}),
    "dining_table": frozenset({"table"}),
    "desk": frozenset({"desk", "table"}),
    "bookshelf": frozenset({"bookcase", "shelves"}),
    "counter": frozenset({"cabinet"}),
    "nightstand": frozenset({"cabinet"}),
    "wardrobe": frozenset({"wardrobe", "cupboard"}),
    "fridge": frozenset({"refrigerator", "fridge"}),
    "trash_bin": frozenset({"dustbin"}),
    "bed": frozenset({"bed"}),
    "plant": frozenset({"plant"}),
    "floor_lamp": frozenset({"lantern", "lamp"}),
    "toilet": frozenset({"toilets"}),
    "sink": frozenset({"washbasin", "vanity"}),
}


@dataclass(frozen=True)
class CatalogueEntry:
    """One piece of furniture of a catalogue."""

    number: int  # N of its `key#N` lines
    id: str
    name: str
    model: str  # path of the OBJ inside the catalogue, without a leading '/'
    size_m: tuple[float, float, float]  # width (x), depth (y), height (z), metres
    rotation: tuple[float, ...] | None  # modelRotation, 3x3 row-major, applied before the size
    creator: str
    elevation_m: float = 0.0  # its bottom above the floor (a wall cabinet's, a washbasin's), metres

    def fits(self, slot: tuple[float, float, float], headroom: float, slack: float) -> bool:
        """Whether it fits a slot (width, depth, m) at its own size, up to `slack` (a fraction) wider or deeper,
        with its top under `headroom` (m above the slot's floor)."""
        w, d, h = self.size_m
        return w <= slot[0] * (1 + slack) and d <= slot[1] * (1 + slack) and self.elevation_m + h <= headroom

    @property
    def head_noun(self) -> str:
        words = re.findall(r"[a-z]+", self.name.lower())
        return words[-1] if words else ""


class Catalogue:
    """A catalogue directory or .sh3f/.zip file: its entries (OBJ models only) and their meshes."""

    def __init__(self, source: Path):
        self.source = Path(source)
        self._zip = zipfile.ZipFile(self.source) if self.source.is_file() else None
        try:
            text = self._read(CATALOGUE_FILE).decode("latin-1")
        except (KeyError, FileNotFoundError, IsADirectoryError):
            raise SceneError(f"no {CATALOGUE_FILE} (expected a Sweet Home 3D catalogue directory or .sh3f)",
                             path=self.source) from None
        self.entries = parse_entries(text, self.source / CATALOGUE_FILE)
        header = re.search(r"^\s*license\s*[=:]\s*(.*?)\s*$", text, re.MULTILINE)
        self.license = header[1] if header else None  # the catalogue's own `license=` line, as written

    @property
    def public_domain(self) -> bool:
        """Whether its `license=` says public domain or CC0 (Sweet Home 3D's CC-0 catalogues write "Public domain")."""
        return self.license is not None and re.search(r"public domain|cc-?0", self.license, re.IGNORECASE) is not None

    def _read(self, name: str) -> bytes:
        if self._zip is not None:
            return self._zip.read(name)
        return (self.source / name).read_bytes()

    def matching(self, category: str) -> list[CatalogueEntry]:
        """The entries whose head noun fits `category` (empty for a category no noun maps to)."""
        nouns = CATEGORY_NOUNS.get(category, frozenset())
        return [e for e in self.entries if e.head_noun in nouns]

    def load_model(self, entry: CatalogueEntry) -> trimesh.Trimesh:
        """The entry's mesh in metres, Z up, front towards -Y, stretched to its size, centred on x = y = 0 and
        standing on z = 0."""
        folder = str(Path(entry.model).parent)
        if self._zip is not None:
            prefix = f"{folder}/"  # only this model's folder is read out of the (tens of MB) zip
            resolver = trimesh.resolvers.ZipResolver(
                {n: io.BytesIO(self._zip.read(n)) for n in self._zip.namelist() if n.startswith(prefix)}, namespace=folder)
        else:
            resolver = trimesh.resolvers.FilePathResolver(self.source / entry.model)
        try:
            mesh = trimesh.load(trimesh.util.wrap_as_stream(self._read(entry.model)), file_type="obj",
                                resolver=resolver, force="mesh")
        except (KeyError, FileNotFoundError):
            raise SceneError(f"model {entry.model} not found", path=self.source / CATALOGUE_FILE,
                             field=f"model#{entry.number}") from None
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise SceneError(f"model {entry.model} has no triangles", path=self.source / CATALOGUE_FILE,
                             field=f"model#{entry.number}")
        return to_scene_frame(mesh, entry.size_m, entry.rotation)


def to_scene_frame(mesh: trimesh.Trimesh, size_m: tuple[float, float, float],
                   rotation: tuple[float, ...] | None = None) -> trimesh.Trimesh:
    """Y-up model -> Z-up (x, y, z) -> (x, -z, y), stretched per axis to `size_m` (w, d, h), standing on z = 0."""
    v = np.asarray(mesh.vertices, dtype=np.float64)
    if rotation is not None:
        v = v @ np.asarray(rotation, dtype=np.float64).reshape(3, 3).T
    v = np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1)
    lo, hi = v.min(axis=0), v.max(axis=0)
    extent = np.where(hi - lo > 0, hi - lo, 1.0)
    centre = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    v = (v - centre) / extent * np.asarray(size_m, dtype=np.float64)
    out = mesh.copy()
    out.vertices = v
    return out


def parse_entries(text: str, path: Path) -> list[CatalogueEntry]:
    """Entries with an OBJ model, ordered by number; a missing or bad size is an error naming the key."""
    fields: dict[int, dict[str, str]] = {}
    for line in text.splitlines():
        m = re.match(r"^\s*(\w+)#(\d+)\s*[=:]\s*(.*?)\s*$", line)
        if m:
            fields.setdefault(int(m[2]), {})[m[1]] = m[3]
    entries = []
    for n, f in sorted(fields.items()):
        model = f.get("model", "").lstrip("/")
        if not model.lower().endswith(".obj") or f.get("doorOrWindow") == "true":
            continue
        size = []
        for key in ("width", "depth", "height"):
            try:
                value = float(f[key]) / 100.0
            except (KeyError, ValueError):
                raise SceneError(f"{key} is missing or not a number", path=path, field=f"{key}#{n}") from None
            if not value > 0:
                raise SceneError(f"{key} must be > 0 cm", path=path, field=f"{key}#{n}")
            size.append(value)
        rotation = None
        if "modelRotation" in f:
            rotation = tuple(float(x) for x in f["modelRotation"].split())
            if len(rotation) != 9:
                raise SceneError("modelRotation needs 9 numbers", path=path, field=f"modelRotation#{n}")
        try:
            elevation = float(f.get("elevation", "0")) / 100.0
        except ValueError:
            raise SceneError("elevation is not a number", path=path, field=f"elevation#{n}") from None
        if not elevation >= 0:
            raise SceneError("elevation must be >= 0 cm", path=path, field=f"elevation#{n}")
        entries.append(CatalogueEntry(n, f.get("id", str(n)), f.get("name", ""), model, (size[0], size[1], size[2]),
                                      rotation, f.get("creator", ""), elevation))
    return entries

