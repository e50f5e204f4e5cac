"""3D Gaussians as a NuRec USDZ: the package NVIDIA 3DGRUT's `ply_to_usd` writes and Isaac Sim 5 renders.

Layout, as read in 3DGRUT's threedgrut/export/ (usd/nurec/serializer.py, templates.py, exporter.py,
usd/stage_utils.py, model.init_from_ply, configs/apps/colmap_3dgut.yaml), entries in this order:

  default.usda    package root: /World (Xform, defaultPrim) and `over` /World/gauss referencing gauss.usda;
                  metersPerUnit 1, upAxis Z, timeCodesPerSecond 24, customLayerData renderSettings
  <name>.nurec    gzip (level 0) of msgpack of {"nre_data": renderer settings + state_dict}: the Gaussians'
                  pre-activation arrays as float16 bytes (positions; rotations w x y z as in the PLY; log
                  scales; density logits [N, 1]; albedo = SH DC [N, 3]; specular = SH degrees 1..3
                  coefficient-major [N, 45], zero where the PLY has fewer) with their shapes, an empty
                  extra_signal [N, 0] and n_active_features 3 (int64)
  gauss.usda      /World/gauss, a UsdVol.Volume: omni:nurec:* flags, an identity transform (world frame: no
                  normalizing transform without cameras), extent and crop bounds = the positions' box,
                  density and emissiveColor fields (OmniNuRecFieldAsset prims) reading ./<name>.nurec

Every entry is stored uncompressed, its data aligned to 64 bytes by a padding extra field (id 0x1986), and
dated 1980-01-01 like 3DGRUT's. The one difference: the gzip header's time is 0 where 3DGRUT writes the
clock's, so the same Gaussians give the same bytes.
"""

from __future__ import annotations

import gzip
import io
import struct
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from sagebench.render.gaussians import Gaussians

GAUSS_LAYER = "gauss.usda"  # what SAGE-3D's template references inside the package: @<scene>.usdz[gauss.usda]@
DEFAULT_LAYER = "default.usda"
VOLUME_PATH = "/World/gauss"
NUREC_SH_DEGREE = 3  # 3DGRUT's render.particle_radiance_sph_degree: every payload carries degree 3
USDZ_ALIGNMENT = 64
PADDING_EXTRA_ID = 0x1986  # the zip extra field id 3DGRUT pads with
FRAMES_PER_SECOND = 24.0
RENDER_SETTINGS = {  # customLayerData renderSettings of both layers (ply_to_usd: no post-processing)
    "rtx:rendermode": "RaytracedLighting",
    "rtx:directLighting:sampledLighting:samplesPerPixel": 8,
    "rtx:post:histogram:enabled": False,
    "rtx:post:registeredCompositing:invertToneMap": True,
    "rtx:post:registeredCompositing:invertColorCorrection": True,
    "rtx:material:enableRefraction": False,
    "rtx:post:tonemap:op": 2,
    "rtx:raytracing:fractionalCutoutOpacity": False,
    "rtx:matteObject:visibility:secondaryRays": True,
}
STATE_ARRAYS = ("positions", "rotations", "scales", "densities", "extra_signal", "features_albedo",
                "features_specular", "n_active_features")  # the state dict's order of keys


def nurec_usdz(g: Gaussians, name: str = "gaussians") -> bytes:
    """The NuRec USDZ of `g` (world frame, Z up, metres) whose payload is `name`.nurec."""
    payload = f"{name}.nurec"
    positions = np.asarray(g.means, dtype=np.float32)
    entries = [(DEFAULT_LAYER, _default_layer()), (payload, nurec_payload(g)), (GAUSS_LAYER, _gauss_layer(positions, payload))]
    return packed_usdz(entries)


def nurec_payload(g: Gaussians) -> bytes:
    """The .nurec file: gzip (stored, time 0) of msgpack of nurec_template(g)."""
    import msgpack

    buf = io.BytesIO()
    with gzip.GzipFile(fileobj=buf, mode="wb", compresslevel=0, mtime=0) as f:
        f.write(msgpack.packb(nurec_template(g)))
    return buf.getvalue()


def nurec_template(g: Gaussians) -> dict:
    """{"nre_data": ...}: the 3DGUT renderer settings 3DGRUT's colmap_3dgut config gives, and the state dict."""
    layer = {"name": "sh-gaussians", "device": "cuda", "density_activation": "sigmoid", "scale_activation": "exp",
             "rotation_activation": "normalize", "precision": 16,
             "particle": {"density_kernel_planar": False, "density_kernel_degree": 2,
                          "density_kernel_density_clamping": True, "density_kernel_min_response": 0.0113,
                          "radiance_sph_degree": NUREC_SH_DEGREE},
             "transmittance_threshold": 0.0001}
    renderer = {"name": "3dgut-nrend", "log_level": 3, "force_update": False, "update_step_train_batch_end": False,
                "per_ray_features": False, "global_z_order": True,
                "projection": {"n_rolling_shutter_iterations": 5, "ut_dim": 3, "ut_alpha": 1.0, "ut_beta": 2.0,
                               "ut_kappa": 0.0, "ut_require_all_sigma_points": False, "image_margin_factor": 0.1,
                               "min_projected_ray_radius": 0.5477225575051661},
                "culling": {"rect_bounding": True, "tight_opacity_bounding": True, "tile_based": True,
                            "near_clip_distance": 1e-8, "far_clip_distance": 3.402823466e38},
                "render": {"mode": "kbuffer", "k_buffer_size": 0}}
    config = {"layers": {"gaussians": layer}, "renderer": renderer, "name": "gaussians_primitive",
              "appearance_embedding": {"name": "skip-appearance", "embedding_dim": 0, "device": "cuda"},
              "background": {"name": "skip-background", "device": "cuda", "composite_in_linear_space": False}}
    return {"nre_data": {"version": "0.2.576", "model": "nre", "config": config, "state_dict": _state_dict(g)}}


def nurec_arrays(g: Gaussians) -> dict[str, np.ndarray]:
    """The state dict's arrays before their float16 conversion: pre-activation, as 3DGRUT reads them from a PLY."""
    n = g.count
    rest = (NUREC_SH_DEGREE + 1) ** 2 - 1
    specular = np.zeros((n, rest, 3), dtype=np.float32)
    specular[:, : g.sh.shape[1] - 1] = g.sh[:, 1:]  # a lower degree's missing coefficients are zero
    return {"positions": g.means, "rotations": g.quats_wxyz, "scales": g.log_scales,
            "densities": g.opacity_logits.reshape(n, 1), "extra_signal": np.zeros((n, 0), dtype=np.float32),
            "features_albedo": g.sh[:, 0], "features_specular": specular.reshape(n, rest * 3)}


def _state_dict(g: Gaussians) -> dict:
    arrays = nurec_arrays(g)
    prefix = ".gaussians_nodes.gaussians."
    state: dict = {"._extra_state": {"obj_track_ids": {"gaussians": []}}}
    for key in STATE_ARRAYS:
        state[prefix + key] = (np.array([NUREC_SH_DEGREE], dtype=np.int64) if key == "n_active_features"
                               else np.asarray(arrays[key]).astype(np.float16)).tobytes()
    for key in STATE_ARRAYS:
        state[f"{prefix}{key}.shape"] = [] if key == "n_active_features" else list(arrays[key].shape)
    return state


def _new_stage():
    """An in-memory stage as 3DGRUT starts each layer: metres, Z up, 24 frames/s, /World the default prim."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateInMemory()
    stage.SetMetadata("metersPerUnit", 1.0)
    stage.SetMetadata("upAxis", "Z")
    stage.SetTimeCodesPerSecond(FRAMES_PER_SECOND)
    UsdGeom.Xform.Define(stage, "/World")
    stage.SetMetadata("defaultPrim", "World")
    stage.SetMetadataByDictKey("customLayerData", "renderSettings", RENDER_SETTINGS)
    return stage


def _gauss_layer(positions: np.ndarray, payload: str) -> bytes:
    """gauss.usda: the NuRec Volume over the positions' box, its fields reading ./`payload`."""
    from pxr import Gf, Sdf, UsdVol

    stage = _new_stage()
    lo = [float(v) for v in positions.min(axis=0)]
    hi = [float(v) for v in positions.max(axis=0)]
    volume = UsdVol.Volume.Define(stage, VOLUME_PATH)
    prim = volume.GetPrim()
    volume.AddTransformOp().Set(Gf.Matrix4d(1.0))
    prim.CreateAttribute("omni:nurec:isNuRecVolume", Sdf.ValueTypeNames.Bool).Set(True)
    prim.CreateAttribute("omni:nurec:useProxyTransform", Sdf.ValueTypeNames.Bool).Set(False)
    for field, data_type in (("density", "float"), ("emissiveColor", "float3")):
        path = f"{VOLUME_PATH}/{'density_field' if field == 'density' else 'emissive_color_field'}"
        asset = stage.DefinePrim(path, "OmniNuRecFieldAsset")
        volume.CreateFieldRelationship(field, path)
        asset.CreateAttribute("filePath", Sdf.ValueTypeNames.Asset).Set(f"./{payload}")
        asset.CreateAttribute("fieldName", Sdf.ValueTypeNames.Token).Set(field)
        asset.CreateAttribute("fieldDataType", Sdf.ValueTypeNames.Token).Set(data_type)
        asset.CreateAttribute("fieldRole", Sdf.ValueTypeNames.Token).Set(field)
        if field == "emissiveColor":  # an identity colour correction matrix, one row each
            for row, axis in zip("RGB", np.eye(3)):
                asset.CreateAttribute(f"omni:nurec:ccm{row}", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(*axis, 0.0))
    prim.GetAttribute("extent").Set([lo, hi])
    prim.CreateAttribute("omni:nurec:offset", Sdf.ValueTypeNames.Float3).Set(Gf.Vec3f(0.0, 0.0, 0.0))
    prim.CreateAttribute("omni:nurec:crop:minBounds", Sdf.ValueTypeNames.Float3).Set(Gf.Vec3f(*lo))
    prim.CreateAttribute("omni:nurec:crop:maxBounds", Sdf.ValueTypeNames.Float3).Set(Gf.Vec3f(*hi))
    prim.CreateRelationship("proxy")
    return _layer_bytes(stage)


def _default_layer() -> bytes:
    """default.usda: the package root, /World/gauss an `over` referencing gauss.usda."""
    from pxr import UsdUtils

    stage = _new_stage()
    quiet = UsdUtils.CoalescingDiagnosticDelegate()  # gauss.usda is not beside this in-memory layer yet
    stage.OverridePrim(VOLUME_PATH).GetReferences().AddReference(GAUSS_LAYER)
    del quiet
    return _layer_bytes(stage)


def _layer_bytes(stage) -> bytes:
    with tempfile.TemporaryDirectory(prefix="sagebench-nurec-") as tmp:
        path = Path(tmp) / "layer.usda"
        stage.GetRootLayer().Export(str(path))
        return path.read_bytes()


def packed_usdz(entries: list[tuple[str, bytes]]) -> bytes:
    """A zip of `entries` (name, data) in order, stored, each entry's data at a multiple of 64 bytes (USDZ's
    rule) by a padding extra field of at least 4 bytes, dated 1980-01-01."""
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_STORED) as z:
        for name, data in entries:
            header = out.tell()
            pad = (-(header + 30 + len(name.encode()))) % USDZ_ALIGNMENT  # 30: the local header's fixed part
            if 0 < pad < 4:  # an extra field needs its 4-byte header
                pad += USDZ_ALIGNMENT
            info = zipfile.ZipInfo(name)  # date_time 1980-01-01 00:00:00
            info.compress_type = zipfile.ZIP_STORED
            if pad:
                info.extra = struct.pack("<HH", PADDING_EXTRA_ID, pad - 4) + bytes(pad - 4)
            z.writestr(info, data)
    return out.getvalue()
