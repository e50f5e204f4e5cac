"""The recorded versions are the installed ones, and differences are named library by library."""

from __future__ import annotations

import sys

import mujoco
import numpy
import pyarrow

from sagebench.versions import OUTPUT_LIBRARIES, likely_cause, output_versions, version_changes


def test_output_versions_are_the_imported_libraries_versions():
    v = output_versions()
    assert list(v) == ["python", *OUTPUT_LIBRARIES]
    assert v["python"] == "{}.{}.{}".format(*sys.version_info[:3])
    assert (v["numpy"], v["pyarrow"], v["mujoco"]) == (numpy.__version__, pyarrow.__version__, mujoco.__version__)
    assert {"numpy", "pyarrow", "trimesh", "coacd", "usd-core", "mujoco", "shapely", "numba"} <= set(v)
    assert "not installed" not in v.values()


def test_version_changes_name_each_difference():
    now = {"python": "3.11.7", "numpy": "2.1.0", "pyarrow": "18.0.0"}
    assert version_changes(now, now) == []
    assert version_changes({"python": "3.11.7", "numpy": "1.26.4", "pyarrow": "18.0.0"}, now) == ["numpy 1.26.4 -> 2.1.0"]
    assert version_changes({"python": "3.11.7", "numpy": "2.1.0"}, now) == ["pyarrow not recorded -> 18.0.0"]


def test_likely_cause_names_the_changed_libraries_or_says_none_were_recorded():
    now = {"python": "3.11.7", "numpy": "2.1.0", "pyarrow": "18.0.0"}
    assert likely_cause(now, now) == ""
    assert likely_cause(now | {"numpy": "1.26.4", "pyarrow": "15.0.0"}, now) == (
        "other library versions than the run was made with: numpy 1.26.4 -> 2.1.0, pyarrow 15.0.0 -> 18.0.0")
    assert likely_cause(None, now).startswith("unknown, the manifest records no library versions")
