"""What a renderer hands an agent: a batch of views as arrays, converted from its float frames in one place.

Keys and what each holds for C views of H x W pixels:
- `rgb` [C, H, W, 3] uint8: the colour clipped to [0, 1], times 255, plus 0.5, truncated (rounds half up, as the
  render stage's PNGs);
- `depth` [C, H, W] float32 m: the expected depth where anything was drawn (alpha > 0), else 0;
- `alpha` [C, H, W] float32: 1 - the final transmittance;
- `instance` [C, H, W] int32: the instance id drawn (from a backend that draws ids: the CPU renderer).

The conversion is written once against an array namespace `xp`: numpy for the CPU renderer, torch for gsplat,
where it runs on the GPU before anything is copied back. It uses only what both give with the same meaning:
`clip`, `where`, `zeros_like`, `asarray(x, dtype=...)` (a float to uint8 cast truncates in both), the dtypes
and the operators; a Python float does not widen a float32 array in either (numpy 2's NEP 50, torch's type
promotion), and every step is its own elementwise IEEE operation, so float32 frames give the same bytes on both.
"""

from __future__ import annotations

from collections.abc import Collection
from typing import Any

import numpy as np

IMAGE_KEYS = ("rgb", "depth", "alpha", "instance")
FIELDS = {"rgb": ("rgb",), "depth": ("depth", "alpha"), "alpha": ("alpha",), "instance": ("instance",)}


def fields_for(keys: Collection[str]) -> tuple[str, ...]:
    """The float frame fields (rgb, depth, alpha, instance) the observation `keys` are made from."""
    unknown = sorted(set(keys) - set(IMAGE_KEYS))
    if unknown:
        raise ValueError(f"unknown image {unknown[0]!r}; images are {', '.join(IMAGE_KEYS)}")
    return tuple(f for f in IMAGE_KEYS if any(f in FIELDS[k] for k in keys))


def to_uint8(rgb: Any, xp: Any = np) -> Any:
    """[..., 3] float colour -> uint8: clipped to [0, 1], * 255, + 0.5, truncated."""
    return xp.asarray(xp.clip(rgb, 0.0, 1.0) * 255.0 + 0.5, dtype=xp.uint8)


def masked_depth(depth: Any, alpha: Any, xp: Any = np) -> Any:
    """[...] depth where anything was drawn (alpha > 0), else 0."""
    return xp.where(alpha > 0.0, depth, xp.zeros_like(depth))


def observation_arrays(fields: dict[str, Any], keys: Collection[str], xp: Any = np) -> dict[str, Any]:
    """The observation images `keys` (module docstring) from float frame fields [C, H, W(, 3)] by name (those
    `fields_for(keys)` names), in the namespace `xp` the fields belong to."""
    make = {"rgb": lambda: to_uint8(fields["rgb"], xp),
            "depth": lambda: masked_depth(fields["depth"], fields["alpha"], xp),
            "alpha": lambda: fields["alpha"], "instance": lambda: xp.asarray(fields["instance"], dtype=xp.int32)}
    return {k: make[k]() for k in keys}
