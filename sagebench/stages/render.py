"""`render`: one view of a built scene's Gaussians from the agent's camera, written as PNG (+ depth, ids).

Reads RUN/scenes/<scene_id>/scene.json (floor height) and gaussians.ply; writes only the files asked for.
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
from numpy.lib import format as npy_format

from sagebench.errors import ConfigError, DataError
from sagebench.fileio import write_bytes
from sagebench.input_files import read_regular
from sagebench.png_mark import is_marked, marked
from sagebench.render.backends import open_renderer
from sagebench.render.camera import agent_camera
from sagebench.render.splat_reference import Frame
from sagebench.run_folder import Output, claim_output_file
from sagebench.run_layout import CONTRACT, GAUSSIANS, SCENE_FILE, run_scene_dir
from sagebench.scene.loader import parse_spec
from sagebench.settings.render import RenderConfig


def parse_pose(text: str) -> tuple[float, float, float]:
    """'X,Y,YAW' (metres, metres, radians) -> floats; a ConfigError otherwise."""
    parts = text.split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ConfigError(f"expected X,Y,YAW (three numbers: metres, metres, radians), got {text!r}", field="--pose")
    return values  # type: ignore[return-value]


def render_view(run_dir: Path, scene_id: str, pose: tuple[float, float, float], config: RenderConfig, *,
                needs: tuple[str, ...] = ("rgb",)) -> Frame:
    """Render RUN/scenes/<scene_id>'s Gaussians from the agent camera at `pose` (x, y, yaw); `needs` names the
    images wanted (rgb, depth, instance), which decides what `auto` may pick."""
    return render_views(run_dir, scene_id, [pose], config, needs=needs)[0]


def render_views(run_dir: Path, scene_id: str, poses: Sequence[tuple[float, float, float]], config: RenderConfig, *,
                 needs: tuple[str, ...] = ("rgb",)) -> list[Frame]:
    """render_view of every pose, the Gaussians read once (the report's start and goal views)."""
    from sagebench.splats.ply import read_ply

    scene_dir = run_scene_dir(run_dir, scene_id)
    spec_path, ply_path = scene_dir / SCENE_FILE, scene_dir / GAUSSIANS
    for path in (scene_dir / p.rel for p in CONTRACT["render"].reads):
        if not path.is_file():
            raise DataError(f"missing; run `sagebench build-scene ... --out {run_dir}` first", path=path)
    spec = parse_spec(spec_path.read_text(encoding="utf-8"), spec_path)
    cams = [agent_camera(x, y, yaw, floor_z=spec.floor_height, camera_height=config.camera.height,
                         pitch_deg=config.pitch_deg, hfov_deg=config.camera.hfov_deg, width=config.width,
                         height=config.height) for x, y, yaw in poses]
    return open_renderer(read_ply(ply_path), config.renderer, needs=needs).render(cams) if cams else []


def png_bytes(rgb: np.ndarray) -> bytes:
    """[H, W, 3] float colour -> PNG bytes (clipped to [0, 1], 8 bits)."""
    return _encoded(rgb, ".png")


def jpeg_bytes(rgb: np.ndarray, quality: int = 85) -> bytes:
    """[H, W, 3] float colour -> JPEG bytes (clipped to [0, 1], 8 bits): a small view (the report's)."""
    return _encoded(rgb, ".jpg", [cv2.IMWRITE_JPEG_QUALITY, quality])


def _encoded(rgb: np.ndarray, ext: str, params: list[int] | None = None) -> bytes:
    bgr = (np.clip(rgb, 0.0, 1.0)[:, :, ::-1] * 255.0 + 0.5).astype(np.uint8)
    ok, buf = cv2.imencode(ext, bgr, params or [])
    if not ok:
        raise RuntimeError(f"{ext} encoding failed")
    return buf.tobytes()


def npy_bytes(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, array, allow_pickle=False)
    return buf.getvalue()


def render_files(run_dir: Path, scene_id: str, pose: tuple[float, float, float], config: RenderConfig, out: Path, *,
                 depth_out: Path | None = None, instance_out: Path | None = None, force: bool = False) -> list[Path]:
    """Render the view and write OUT (PNG) and the arrays asked for, each claimed first
    (run_folder.claim_output_file: never in a run, never over a file sagebench did not write unless `force`)."""
    needs = ("rgb", *(["depth"] if depth_out else []), *(["instance"] if instance_out else []))
    arrays = [Output(Path(p), is_render_array, field)
              for p, field in ((depth_out, "--depth-out"), (instance_out, "--instance-out")) if p is not None]
    with claim_output_file(Output(Path(out), is_marked), "render", force=force, sidecars=arrays):
        frame = render_view(run_dir, scene_id, pose, config, needs=needs)
        return write_frame(frame, out, depth_out=depth_out, instance_out=instance_out)


def is_render_array(path: Path) -> bool:
    """Whether `path` holds what --depth-out or --instance-out writes: a .npy of one 2-D float32 or int32 array."""
    head = read_regular(path, limit=None, size=4096)
    try:
        buf = io.BytesIO(head or b"")
        major, _ = npy_format.read_magic(buf)
        read = npy_format.read_array_header_1_0 if major == 1 else npy_format.read_array_header_2_0
        shape, _, dtype = read(buf)
    except (ValueError, EOFError, SyntaxError, TypeError):
        return False
    return len(shape) == 2 and dtype in (np.dtype("<f4"), np.dtype("<i4"))


def write_frame(frame: Frame, out: Path, *, depth_out: Path | None = None, instance_out: Path | None = None) -> list[Path]:
    """Write the PNG (marked as sagebench's), and the depth (float32, m) and instance-id (int32) arrays when
    asked; returns the paths."""
    files = [(out, marked(png_bytes(frame.rgb)))]
    if depth_out is not None:
        files.append((depth_out, npy_bytes(frame.depth.astype(np.float32))))
    if instance_out is not None:
        files.append((instance_out, npy_bytes(frame.instance.astype(np.int32))))
    for path, data in files:
        write_bytes(Path(path), data)
    return [Path(p) for p, _ in files]
