"""What the `.bi` importer and exporter (`blender/bi/scene_data.py`,
`blender/bi/operators.py`) need besides Blender: the names of imported objects, the
`.bi` numbers stored on them (a surface as a dict), Blender's float32 storage read
back as the shortest decimal, the order objects are written in, the scene's
extent (for the camera's clipping) and the texts of the operators' reports.

Pure (numpy only).
"""

from __future__ import annotations

import re

import numpy as np

from ..scene.model import Scene, Surface
from .conversions import header_line


def sphere_name(index: int) -> str:
    """Name of the imported sphere `index` (0-based, as `lens-lights phase1` counts)."""
    return f"Sphere {index}"


def light_name(index: int) -> str:
    return f"Light {index}"


def surface_dict(surface: Surface) -> dict:
    return {
        "color": list(surface.color),
        "ka": surface.ambient,
        "kd": surface.diffuse,
        "ks": surface.specular,
        "kt": surface.transmission,
        "E": surface.exponent,
        "n": surface.ior,
    }


def surface_from_dict(d) -> Surface:
    return Surface(
        color=tuple(float(c) for c in d["color"]),
        ambient=float(d["ka"]),
        diffuse=float(d["kd"]),
        specular=float(d["ks"]),
        transmission=float(d["kt"]),
        exponent=float(d["E"]),
        ior=float(d["n"]),
    )


def f32(x: float) -> float:
    """The shortest decimal that reads back to the same float32 as `x` (Blender's
    storage), as a double: 0.30000001192092896 → 0.3."""
    value = np.float32(x)
    return float(str(value)) if np.isfinite(value) else float(x)


def f32v(v) -> tuple:
    return tuple(f32(c) for c in v)


def as_tuple(v):
    return tuple(v) if v is not None else None


def natural_key(name: str):
    """Sort key that orders "Sphere 2" before "Sphere 10"."""
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", name)]


def order_key(stored: dict, name: str):
    """Where an object goes in the written file: by the index it was imported with
    (`stored`: its stored `.bi` numbers), then the others by name."""
    index = stored.get("index")
    return (
        (0, int(index), natural_key(name)) if isinstance(index, int) else (1, 0, natural_key(name))
    )


def scene_extent(scene: Scene) -> float:
    """Largest distance from the camera to its target, any light or a sphere's far side."""
    cam = np.asarray(scene.camera.position, dtype=float)

    def dist(p):
        return float(np.linalg.norm(np.asarray(p, dtype=float) - cam))

    far = dist(scene.camera.target)
    for light in scene.lights:
        far = max(far, dist(light.position))
    for sphere in scene.objects:
        far = max(far, dist(sphere.center) + sphere.radius)
    return far


def file_line(path: str, key: str) -> int:
    """The line of the header record `key` in the file `path` (1 when unknown)."""
    try:
        with open(path, encoding="utf-8-sig", errors="replace") as f:
            return header_line(f.read(), key) or 1
    except OSError:
        return 1


def summary(items: list, limit: int = 8) -> str:
    """The first `limit` items, comma-separated, and how many more."""
    text = ", ".join(items[:limit])
    return text + (f", … ({len(items) - limit} more)" if len(items) > limit else "")
