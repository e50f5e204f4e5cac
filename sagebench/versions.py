"""The versions of Python and of the libraries that shape output bytes, for stamps, the manifest and verify.

The same inputs, seed and sagebench version give the same bytes only with the same libraries: Parquet
embeds its writer's version, and numpy/numba/scipy kernels, trimesh, shapely, CoACD, usd-core, MuJoCo,
pillow and OpenCV can change results between releases. A version change therefore makes every stamp
stale, and `verify --regenerate` names it as the likely cause of a difference. Versions are read from the
installed distributions' metadata, without importing the libraries.
"""

from __future__ import annotations

import functools
import platform
from importlib import metadata

# distribution names as installed (pip's names)
OUTPUT_LIBRARIES = ("numpy", "scipy", "numba", "pyarrow", "trimesh", "shapely", "coacd", "usd-core", "mujoco",
                    "pillow", "opencv-python-headless")


@functools.cache
def output_versions() -> dict[str, str]:
    """{"python": "3.11.2", "numpy": "2.1.3", ...}: Python's version and each of OUTPUT_LIBRARIES'
    ("not installed" for one that is absent)."""
    versions = {"python": platform.python_version()}
    for name in OUTPUT_LIBRARIES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return versions


def likely_cause(recorded: object, current: dict[str, str]) -> str:
    """Why a regeneration may differ from a run whose manifest recorded `recorded` ("" when the versions match)."""
    if not isinstance(recorded, dict):
        return "unknown, the manifest records no library versions (an older sagebench wrote it)"
    changes = version_changes(recorded, current)
    return "other library versions than the run was made with: " + ", ".join(changes) if changes else ""


def version_changes(recorded: dict[str, str], current: dict[str, str]) -> list[str]:
    """'numpy 1.26.4 -> 2.1.3' for each library whose recorded version differs from the current one."""
    return [f"{name} {recorded.get(name, 'not recorded')} -> {current.get(name, 'not recorded')}"
            for name in sorted(recorded.keys() | current.keys()) if recorded.get(name) != current.get(name)]
