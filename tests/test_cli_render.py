"""`sagebench render`: a view of a built scene as PNG, depth and instance ids; clear errors, nothing written."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from sagebench.render.gaussians import Gaussians, logit, rgb_to_sh_dc
from sagebench.splats.ply import write_ply


@pytest.fixture
def run_dir(tmp_path):
    """A minimal run: scenes/s/ with a floor at z = 0.5 and one red Gaussian (id 5) 3 m ahead of (1, 1) along +Y."""
    scene = tmp_path / "run" / "scenes" / "s"
    scene.mkdir(parents=True)
    (scene / "scene.json").write_text(json.dumps({
        "scene_id": "s", "floor_height": 0.5,
        "objects": [{"instance_id": 5, "category": "ball", "mesh": "meshes/ball.ply"}],
    }))
    g = Gaussians(np.array([[1.0, 4.0, 1.7]], np.float32), np.array([[1.0, 0, 0, 0]], np.float32),
                  np.log(np.full((1, 3), 0.2, np.float32)), logit(np.array([0.99])),
                  rgb_to_sh_dc(np.array([[1.0, 0.0, 0.0]]))[:, None, :], np.array([5], np.int32))
    write_ply(scene / "gaussians.ply", g)
    return tmp_path / "run"


def test_render_writes_png_depth_and_instances(run_cli, run_dir, tmp_path):
    out, depth, inst = tmp_path / "f.png", tmp_path / "d.npy", tmp_path / "i.npy"
    code, stdout, _ = run_cli("render", run_dir, "--scene", "s", "--pose", f"1,1,{np.pi / 2}", "--width", "41",
                              "--height", "31", "--out", out, "--depth-out", depth, "--instance-out", inst)
    assert code == 0
    assert stdout.splitlines() == [f"wrote {out}", f"wrote {depth}", f"wrote {inst}"]
    img = cv2.imread(str(out))[:, :, ::-1]
    assert img.shape == (31, 41, 3)
    assert img[15, 20].tolist() == [252, 0, 0]  # 0.99 red over black, at the image centre
    d, i = np.load(depth), np.load(inst)
    assert d.dtype == np.float32 and i.dtype == np.int32
    assert d[15, 20] == pytest.approx(3.0, abs=1e-4) and i[15, 20] == 5
    assert i[0, 0] == 0 and d[0, 0] == 0


def test_camera_height_and_pitch_move_the_view(run_cli, run_dir, tmp_path):
    inst = tmp_path / "i.npy"
    code, _, _ = run_cli("render", run_dir, "--scene", "s", "--pose", f"1,1,{np.pi / 2}", "--width", "41",
                         "--height", "31", "--camera-height", "0.6", "--pitch", "-20", "--out", tmp_path / "f.png",
                         "--instance-out", inst)
    assert code == 0
    ids = np.load(inst)
    rows = np.flatnonzero((ids == 5).any(axis=1))
    assert rows.max() < 15  # camera below the ball and looking down: the ball is in the top half


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--pose", "1,2"], "error: --pose: expected X,Y,YAW (three numbers: metres, metres, radians), got '1,2'"),
        (["--pose", "1,2,x"], "error: --pose: expected X,Y,YAW"),
        (["--pose", "1,2,3", "--hfov", "180"], "error: --hfov: Input should be less than 180"),
        (["--pose", "1,2,3", "--width", "0"], "error: --width: Input should be greater than or equal to 1"),
        (["--pose", "1,2,3", "--pitch", "95"], "error: --pitch: Input should be less than 90"),
        (["--pose", "1,2,3", "--renderer", "vulkan"], "error: --renderer: Input should be 'auto', 'cpu' or 'gsplat'"),
        (["--pose", "1,2,3", "--renderer", "gsplat", "--instance-out", "i.npy"],
         "error: --renderer: the gsplat renderer draws no instance images; use --renderer cpu or auto"),
    ],
)
def test_bad_options_exit_2_and_write_nothing(run_cli, run_dir, tmp_path, args, message):
    out = tmp_path / "f.png"
    code, _, err = run_cli("render", run_dir, "--scene", "s", "--out", out, *args)
    assert code == 2 and err.startswith(message)
    assert not out.exists()


def test_auto_renders_the_cpu_frame_where_gsplat_cannot_run(run_cli, run_dir, tmp_path, monkeypatch):
    from sagebench.render import backends

    monkeypatch.setattr(backends, "gsplat_missing", lambda: "torch is not installed (pip install 'sagebench[gpu]')")
    a, b = tmp_path / "auto.png", tmp_path / "cpu.png"
    assert run_cli("render", run_dir, "--scene", "s", "--pose", "0,0,0", "--out", a, "--renderer", "auto")[0] == 0
    assert run_cli("render", run_dir, "--scene", "s", "--pose", "0,0,0", "--out", b)[0] == 0
    assert a.read_bytes() == b.read_bytes()
    code, _, err = run_cli("render", run_dir, "--scene", "s", "--pose", "0,0,0", "--out", tmp_path / "g.png",
                           "--renderer", "gsplat")
    assert (code, err.strip()) == (2, "error: --renderer: the gsplat renderer cannot run here: torch is not "
                                      "installed (pip install 'sagebench[gpu]')")
    assert not (tmp_path / "g.png").exists()


def test_missing_scene_names_the_file(run_cli, run_dir, tmp_path):
    out = tmp_path / "f.png"
    code, _, err = run_cli("render", run_dir, "--scene", "nope", "--pose", "0,0,0", "--out", out)
    assert code == 2
    assert err.strip() == (f"error: {run_dir}/scenes/nope/scene.json: missing; run `sagebench build-scene ... "
                           f"--out {run_dir}` first")
    assert not out.exists()
