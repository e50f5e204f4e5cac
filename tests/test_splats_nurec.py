"""NuRec USDZ: byte for byte what NVIDIA 3DGRUT's `ply_to_usd` writes, checked against a reference built here the
way 3DGRUT's code does (read in threedgrut/export/usd/nurec/{serializer,templates,exporter}.py,
usd/stage_utils.py, model/model.py init_from_ply and configs/apps/colmap_3dgut.yaml; written anew, not copied),
and opened with usd-core."""

from __future__ import annotations

import gzip
import io
import struct
import subprocess
import sys
import zipfile
from pathlib import Path

import msgpack
import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdUtils, UsdVol

from sagebench.render.gaussians import Gaussians
from sagebench.splats.nurec import nurec_usdz
from sagebench.splats.ply import write_ply


def gaussians(n: int, degree: int, seed: int) -> Gaussians:
    rng = np.random.default_rng(seed)
    return Gaussians(
        means=(rng.normal(size=(n, 3)) * [3, 2, 1] + [5, 4, 1]).astype(np.float32),
        quats_wxyz=rng.normal(size=(n, 4)).astype(np.float32),  # not unit: NuRec normalises, as the PLY holds them
        log_scales=rng.uniform(-5, -1, (n, 3)).astype(np.float32),
        opacity_logits=rng.normal(size=n).astype(np.float32),
        sh=rng.normal(size=(n, (degree + 1) ** 2, 3)).astype(np.float32),
        instance_id=rng.integers(0, 5, n).astype(np.int32),
    )


# ----------------------------------------------------------------------- the reference, step by step as 3DGRUT
def _read_ply_as_init_from_ply(path: Path) -> dict[str, np.ndarray]:
    """MixtureOfGaussians.init_from_ply with radiance degree 3: properties by name, f_rest / scale_ / rot sorted by
    their number, f_rest channel-major -> [N, 15, 3] -> [N, 45]; no f_rest: zeros; float32 like its parameters."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    names, count = [], 0
    kinds = {"float": "<f4", "int": "<i4", "uchar": "u1", "double": "<f8"}
    for line in data[:end].decode().splitlines():
        words = line.split()
        if words[:2] == ["element", "vertex"]:
            count = int(words[2])
        elif words[:1] == ["property"]:
            names.append((words[2], kinds[words[1]]))
    table = np.frombuffer(data, dtype=np.dtype(names), count=count, offset=end)

    def stacked(prefix: str) -> np.ndarray:
        cols = sorted((n for n, _ in names if n.startswith(prefix)), key=lambda n: int(n.split("_")[-1]))
        return np.stack([table[c] for c in cols], axis=1).astype(np.float32) if cols else np.zeros((count, 0), np.float32)

    rest = stacked("f_rest_")
    if rest.shape[1] == 45:
        specular = rest.reshape(count, 3, 15).transpose(0, 2, 1).reshape(count, 45)
    elif rest.shape[1] == 0:
        specular = np.zeros((count, 45), np.float32)
    else:
        raise ValueError("3DGRUT refuses partial SH")
    return {"positions": np.stack([table["x"], table["y"], table["z"]], axis=1).astype(np.float32),
            "rotations": stacked("rot"), "scales": stacked("scale_"),
            "densities": table["opacity"].astype(np.float32)[:, None], "albedo": stacked("f_dc_"), "specular": specular}


def _template(a: dict[str, np.ndarray]) -> dict:
    """fill_3dgut_template(...) with the colmap_3dgut render config (3dgut.yaml over 3dgrt.yaml, base_gs.yaml)."""
    template = {"nre_data": {
        "version": "0.2.576", "model": "nre",
        "config": {
            "layers": {"gaussians": {
                "name": "sh-gaussians", "device": "cuda", "density_activation": "sigmoid", "scale_activation": "exp",
                "rotation_activation": "normalize", "precision": 16,
                "particle": {"density_kernel_planar": False, "density_kernel_degree": 2,
                             "density_kernel_density_clamping": True, "density_kernel_min_response": 0.0113,
                             "radiance_sph_degree": 3},
                "transmittance_threshold": 0.0001}},
            "renderer": {
                "name": "3dgut-nrend", "log_level": 3, "force_update": False, "update_step_train_batch_end": False,
                "per_ray_features": False, "global_z_order": True,
                "projection": {"n_rolling_shutter_iterations": 5, "ut_dim": 3, "ut_alpha": 1.0, "ut_beta": 2.0,
                               "ut_kappa": 0.0, "ut_require_all_sigma_points": False, "image_margin_factor": 0.1,
                               "min_projected_ray_radius": 0.5477225575051661},
                "culling": {"rect_bounding": True, "tight_opacity_bounding": True, "tile_based": True,
                            "near_clip_distance": 1e-8, "far_clip_distance": 3.402823466e38},
                "render": {"mode": "kbuffer", "k_buffer_size": 0}},
            "name": "gaussians_primitive",
            "appearance_embedding": {"name": "skip-appearance", "embedding_dim": 0, "device": "cuda"},
            "background": {"name": "skip-background", "device": "cuda", "composite_in_linear_space": False}},
        "state_dict": {"._extra_state": {"obj_track_ids": {"gaussians": []}}}}}
    state = template["nre_data"]["state_dict"]
    p = ".gaussians_nodes.gaussians."
    names = ["positions", "rotations", "scales", "densities", "extra_signal", "features_albedo", "features_specular",
             "n_active_features"]
    for name in names + [f"{n}.shape" for n in names]:
        state[p + name] = None  # the template's key order
    extra = np.zeros((len(a["positions"]), 0), dtype=np.float16)
    for name, arr in (("positions", a["positions"]), ("rotations", a["rotations"]), ("scales", a["scales"]),
                      ("densities", a["densities"]), ("features_albedo", a["albedo"]),
                      ("features_specular", a["specular"])):
        state[p + name] = arr.astype(np.float16).tobytes()
        state[p + name + ".shape"] = list(arr.shape)
    state[p + "extra_signal"], state[p + "extra_signal.shape"] = extra.tobytes(), list(extra.shape)
    state[p + "n_active_features"] = np.array([3], dtype=np.int64).tobytes()
    state[p + "n_active_features.shape"] = []
    return template


def _stage() -> Usd.Stage:
    stage = Usd.Stage.CreateInMemory()  # initialize_usd_stage(up_axis="Z")
    stage.SetMetadata("metersPerUnit", 1.0)
    stage.SetMetadata("upAxis", "Z")
    stage.SetTimeCodesPerSecond(24.0)
    UsdGeom.Xform.Define(stage, "/World")
    stage.SetMetadata("defaultPrim", "World")
    stage.SetMetadataByDictKey("customLayerData", "renderSettings", {
        "rtx:rendermode": "RaytracedLighting", "rtx:directLighting:sampledLighting:samplesPerPixel": 8,
        "rtx:post:histogram:enabled": False, "rtx:post:registeredCompositing:invertToneMap": True,
        "rtx:post:registeredCompositing:invertColorCorrection": True, "rtx:material:enableRefraction": False,
        "rtx:post:tonemap:op": 2, "rtx:raytracing:fractionalCutoutOpacity": False,
        "rtx:matteObject:visibility:secondaryRays": True})
    return stage


def _gauss_stage(positions: np.ndarray, nurec: str) -> Usd.Stage:
    """serialize_nurec_usd with an identity normalizing transform (ply_to_usd passes no dataset)."""
    stage = _stage()
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    volume = UsdVol.Volume.Define(stage, "/World/gauss")
    prim = volume.GetPrim()
    volume.AddTransformOp().Set(Gf.Matrix4d(*np.linalg.inv(np.eye(4)).flatten()))
    prim.CreateAttribute("omni:nurec:isNuRecVolume", Sdf.ValueTypeNames.Bool).Set(True)
    prim.CreateAttribute("omni:nurec:useProxyTransform", Sdf.ValueTypeNames.Bool).Set(False)
    density = stage.DefinePrim("/World/gauss/density_field", "OmniNuRecFieldAsset")
    volume.CreateFieldRelationship("density", "/World/gauss/density_field")
    emissive = stage.DefinePrim("/World/gauss/emissive_color_field", "OmniNuRecFieldAsset")
    volume.CreateFieldRelationship("emissiveColor", "/World/gauss/emissive_color_field")
    for field, name, kind in ((density, "density", "float"), (emissive, "emissiveColor", "float3")):
        field.CreateAttribute("filePath", Sdf.ValueTypeNames.Asset).Set("./" + nurec)
        field.CreateAttribute("fieldName", Sdf.ValueTypeNames.Token).Set(name)
        field.CreateAttribute("fieldDataType", Sdf.ValueTypeNames.Token).Set(kind)
        field.CreateAttribute("fieldRole", Sdf.ValueTypeNames.Token).Set(name)
    emissive.CreateAttribute("omni:nurec:ccmR", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f([1.0, 0.0, 0.0, 0.0]))
    emissive.CreateAttribute("omni:nurec:ccmG", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f([0.0, 1.0, 0.0, 0.0]))
    emissive.CreateAttribute("omni:nurec:ccmB", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f([0.0, 0.0, 1.0, 0.0]))
    prim.GetAttribute("extent").Set([[float(v) for v in lo], [float(v) for v in hi]])
    prim.CreateAttribute("omni:nurec:offset", Sdf.ValueTypeNames.Float3).Set(Gf.Vec3d([0.0, 0.0, 0.0]))
    prim.CreateAttribute("omni:nurec:crop:minBounds", Sdf.ValueTypeNames.Float3).Set(Gf.Vec3d(*map(float, lo)))
    prim.CreateAttribute("omni:nurec:crop:maxBounds", Sdf.ValueTypeNames.Float3).Set(Gf.Vec3d(*map(float, hi)))
    prim.CreateRelationship("proxy")
    return stage


def _default_stage() -> Usd.Stage:
    """serialize_usd_default_layer: an over /World/gauss referencing gauss.usda, the render settings copied."""
    stage = _stage()
    delegate = UsdUtils.CoalescingDiagnosticDelegate()  # noqa: F841 - silences the dangling reference, as 3DGRUT
    stage.OverridePrim("/World/gauss").GetReferences().AddReference("gauss.usda")
    return stage


def _exported(stage: Usd.Stage, tmp: Path) -> bytes:
    path = tmp / "layer.usda"
    stage.GetRootLayer().Export(str(path))
    return path.read_bytes()


def reference_usdz(ply: Path, out: Path, tmp: Path) -> None:
    """python -m threedgrut.export.scripts.ply_to_usd PLY --output_file OUT, as its code runs (cameras off: it
    has no dataset), the gzip header's time 0 instead of the clock's."""
    attrs = _read_ply_as_init_from_ply(ply)
    buf = io.BytesIO()
    with gzip.GzipFile(fileobj=buf, mode="wb", compresslevel=0, mtime=0) as f:
        f.write(msgpack.packb(_template(attrs)))
    nurec = out.stem + ".nurec"
    entries = [("default.usda", _exported(_default_stage(), tmp)), (nurec, buf.getvalue()),
               ("gauss.usda", _exported(_gauss_stage(attrs["positions"], nurec), tmp))]
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_STORED) as z:  # write_to_usdz / _write_usdz_entry
        for name, data in entries:
            offset = z.fp.tell()
            pad = (-(offset + 30 + len(name.encode()))) % 64
            if 0 < pad < 4:
                pad += 64
            info = zipfile.ZipInfo(name)
            info.compress_type = zipfile.ZIP_STORED
            if pad:
                info.extra = struct.pack("<HH", 0x1986, pad - 4) + b"\0" * (pad - 4)
            z.writestr(info, data)


# ----------------------------------------------------------------------- the tests
@pytest.mark.parametrize("degree", [0, 3])
def test_nurec_usdz_is_byte_identical_to_3dgrut_ply_to_usd(tmp_path, degree):
    g = gaussians(300, degree, seed=degree)
    write_ply(tmp_path / "scene.ply", g)
    reference_usdz(tmp_path / "scene.ply", tmp_path / "gaussians.usdz", tmp_path)
    ours = nurec_usdz(g, "gaussians")
    want = (tmp_path / "gaussians.usdz").read_bytes()
    got, ref = zipfile.ZipFile(io.BytesIO(ours)), zipfile.ZipFile(io.BytesIO(want))
    assert got.namelist() == ref.namelist() == ["default.usda", "gaussians.nurec", "gauss.usda"]
    for name in ("default.usda", "gauss.usda"):
        assert got.read(name).decode() == ref.read(name).decode(), name
    mine, theirs = (msgpack.unpackb(gzip.decompress(z.read("gaussians.nurec"))) for z in (got, ref))
    assert mine["nre_data"]["config"] == theirs["nre_data"]["config"]
    for key in theirs["nre_data"]["state_dict"]:  # field by field, then the whole file
        assert mine["nre_data"]["state_dict"][key] == theirs["nre_data"]["state_dict"][key], key
    assert list(mine["nre_data"]["state_dict"]) == list(theirs["nre_data"]["state_dict"])
    assert ours == want


def test_lower_sh_degrees_are_zero_padded_to_degree_3(tmp_path):
    # 3DGRUT's init_from_ply refuses 9 or 24 f_rest values; NuRec carries degree 3, so the missing ones are zero
    g = gaussians(50, 1, seed=7)
    padded = np.zeros((g.count, 16, 3), np.float32)
    padded[:, :4] = g.sh
    as_three = Gaussians(g.means, g.quats_wxyz, g.log_scales, g.opacity_logits, padded, g.instance_id)
    assert nurec_usdz(g) == nurec_usdz(as_three)


def test_the_package_opens_with_usd_core_and_its_fields_read_the_payload(tmp_path):
    g = gaussians(100, 3, seed=3)
    path = tmp_path / "scene.usdz"
    path.write_bytes(nurec_usdz(g, "scene"))
    stage = Usd.Stage.Open(str(path))
    assert stage.GetDefaultPrim().GetPath() == "/World"
    volume = UsdVol.Volume(stage.GetPrimAtPath("/World/gauss/gauss"))
    assert volume and volume.GetPrim().GetAttribute("omni:nurec:isNuRecVolume").Get()
    lo, hi = np.array(volume.GetExtentAttr().Get())
    assert np.allclose(lo, g.means.min(axis=0)) and np.allclose(hi, g.means.max(axis=0))
    fields = volume.GetFieldPaths()
    assert sorted(fields) == ["density", "emissiveColor"]
    asset = stage.GetPrimAtPath(fields["density"]).GetAttribute("filePath").Get()
    assert asset.path == "./scene.nurec" and asset.resolvedPath.endswith("scene.usdz[scene.nurec]")
    with zipfile.ZipFile(path) as z:  # usdz: stored, each file's data 64-byte aligned
        for info in z.infolist():
            assert info.compress_type == zipfile.ZIP_STORED
            name_len, extra_len = struct.unpack_from("<HH", path.read_bytes(), info.header_offset + 26)
            assert (info.header_offset + 30 + name_len + extra_len) % 64 == 0
        state = msgpack.unpackb(gzip.decompress(z.read("scene.nurec")))["nre_data"]["state_dict"]
    pos = np.frombuffer(state[".gaussians_nodes.gaussians.positions"], np.float16).reshape(100, 3)
    assert np.allclose(pos, g.means, atol=5e-3 * np.abs(g.means).max())  # float16


def test_nvidia_asset_validator_cli_exits_0_on_the_package(tmp_path):
    (tmp_path / "gaussians.usdz").write_bytes(nurec_usdz(gaussians(20, 0, seed=1)))
    cli = Path(sys.executable).with_name("omni_asset_validate")
    run = subprocess.run([str(cli), str(tmp_path / "gaussians.usdz")], capture_output=True, text=True)
    problems = [line for line in (run.stdout + run.stderr).splitlines() if line.startswith(("WARNING", "ERROR"))]
    assert (run.returncode, problems) == (0, [])
