"""benchmarks/gpu_check.py on a machine without a GPU: the dry run goes through every section with the CPU renderer,
importing only what a GPU image has plus what gpu_pack.sh packs, and a section that fails or runs out of time is
reported in the table while the others still run."""

from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import re
import shutil
from pathlib import Path

import pytest

from benchmarks import gpu_check


@pytest.fixture(scope="module")
def small_run(tiny_run, tmp_path_factory) -> Path:
    """The tiny run with its first four episodes, as a .tgz like the one gpu_pack.sh makes."""
    import tarfile

    import pyarrow.parquet as pq

    run = tmp_path_factory.mktemp("gpu_run") / "run"
    shutil.copytree(tiny_run / "scenes", run / "scenes")
    part = sorted((tiny_run / "episodes").rglob("*.parquet"))[0]
    dest = run / part.relative_to(tiny_run)
    dest.parent.mkdir(parents=True)
    pq.write_table(pq.read_table(part).slice(0, 4), dest)
    tgz = run.parent / "run.tgz"
    with tarfile.open(tgz, "w:gz") as tar:
        for top in ("scenes", "episodes"):
            tar.add(run / top, arcname=top)
    return tgz


def _norm(dist: str) -> str:
    return re.sub(r"[-_.]+", "-", dist).lower()


def unavailable_modules() -> set[str]:
    """Top-level modules of sagebench's dependencies that neither a GPU image (gpu_check.IMAGE_HAS) nor
    gpu_pack.sh's wheels bring."""
    script = (Path(gpu_check.__file__).parent / "gpu_pack.sh").read_text()
    packed = {_norm(n) for n in re.findall(r"\$\(pin ([\w.-]+)\)", script) + re.findall(r'"([\w.-]+)==', script)}
    needed = {_norm(re.split(r"[<>=!~; \[]", r, maxsplit=1)[0]) for r in importlib.metadata.requires("sagebench")
              if "extra ==" not in r}
    missing = needed - packed - {_norm(d) for d in gpu_check.IMAGE_HAS}
    return {module for module, dists in importlib.metadata.packages_distributions().items()
            if dists and all(_norm(d) in missing for d in dists)}


@pytest.fixture
def gpu_image_imports(tmp_path_factory, monkeypatch) -> set[str]:
    """Sections (child processes) that import anything else fail with ModuleNotFoundError, as on the GPU machine."""
    site = tmp_path_factory.mktemp("gpu_image")
    blocked = unavailable_modules()
    (site / "sitecustomize.py").write_text(
        "import sys\n"
        f"BLOCKED = {sorted(blocked)!r}\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.partition('.')[0] in BLOCKED:\n"
        "            raise ModuleNotFoundError(f'No module named {name!r} (not on a GPU image)', name=name)\n"
        "sys.meta_path.insert(0, Block())\n")
    monkeypatch.setenv("PYTHONPATH", str(site))
    return blocked


def test_the_gpu_machine_lacks_what_is_not_packed():
    blocked = unavailable_modules()
    assert {"trimesh", "pxr", "coacd", "typer"} <= blocked  # the heavy ones stay home
    assert not {"shapely", "mujoco", "pydantic", "numpy", "numba"} & blocked


def _rows(out: Path) -> list[dict]:
    return json.loads((out / "gpu_check.json").read_text())


def test_the_dry_run_measures_every_section(small_run, tmp_path, gpu_image_imports):
    assert gpu_check.main(["--run", str(small_run), "--out", str(tmp_path), "--dry-run"]) == 0
    rows = _rows(tmp_path)
    assert {r["section"] for r in rows} == set(gpu_check.SECTIONS)
    assert all(r.get("status", "ok") == "ok" for r in rows), rows
    numbers = {r["what"]: r["value"] for r in rows if r.get("unit") in ("frames/s", "steps/s")}
    # 2 view counts (float frames and observations), 2 batches, export
    assert len(numbers) == 2 * 2 + 2 + 1 and all(v > 0 for v in numbers.values())
    same = next(r for r in rows if r["what"].startswith("observations vs float frames"))
    assert same["value"] == "100.00 %, 100.00 %"
    table = (tmp_path / "gpu_check.md").read_text()
    assert table.startswith("## GPU check (dry run on the CPU)") and "PSNR" in table
    assert "===== env" in (tmp_path / "gpu_check.log").read_text()


@pytest.mark.skipif(importlib.util.find_spec("torch") is not None, reason="torch is installed here")
def test_without_gsplat_each_gpu_section_fails_on_its_own_line(small_run, tmp_path):
    assert gpu_check.main(["--run", str(small_run), "--out", str(tmp_path), "--sections", "device,render"]) == 0
    rows = _rows(tmp_path)
    assert [(r["section"], r["status"]) for r in rows] == [("device", "FAILED"), ("render", "FAILED")]
    assert all("torch is not installed" in r["note"] for r in rows)


def test_a_section_out_of_time_is_reported_and_the_next_runs(small_run, tmp_path, monkeypatch):
    monkeypatch.setitem(gpu_check.LIMITS, "env", 0.5)
    rows = gpu_check.drive(small_run, tmp_path, budget=600, dry=True, sections=["env", "device"])
    failed = [r for r in rows if r.get("status") == "FAILED"]
    assert len(failed) == 1 and failed[0]["section"] == "env" and "timed out after 0.5 s" in failed[0]["note"]
    assert rows[-1]["section"] == "device" and rows[-1].get("status", "ok") == "ok"
