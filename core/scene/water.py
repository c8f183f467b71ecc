"""Water surfaces read from the scene (issue 26; pure): an open glass mesh (a plane
displaced by an Ocean modifier, geometry nodes or a shape key) whose material refracts
with an index near water's is a water surface with the water below it
(`core.lens.water`), its receivers under it. The Blender side finds the candidates
(the open glass the scene read left out, `closed_mesh.OPEN_REASON`) and hands each
one's world triangles, corner normals and material optics here.

The material gives what one crossing into the water does to the light: the
transmission weight (Principled's Transmission Weight and the like, once: the light
crosses one surface, not a glass volume's two), the colour of one crossing (the
square root of `glass`'s path tint, which is of two crossings) and Volume
Absorption's Beer per unit length (the depth tint).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..lens.glass import WATER_IOR_RANGE, MaterialOptics


def water_reason(optics: MaterialOptics | None) -> str:
    """ "" when the material is water-like (refracting, its index within
    `WATER_IOR_RANGE`, no Thin Wall), else why not, in words."""
    if optics is None or not optics.is_transmissive:
        return "its material does not refract"
    if optics.thin_wall > 0.0:
        return "its material is a thin wall"
    lo, hi = WATER_IOR_RANGE
    if not lo <= optics.ior <= hi:
        return f"IOR {optics.ior:.3g}, not water's ({lo:g}–{hi:g})"
    return ""


@dataclass
class WaterRead:
    """One water surface: its name, the original object, its world triangles
    (``vertices`` (V, 3), ``triangles`` (T, 3), ``corner_normals`` (T, 3, 3)), the
    index, the transmission weight, the colour of one crossing and the absorption per
    unit length (RGB)."""

    name: str
    orig: object
    vertices: np.ndarray
    triangles: np.ndarray
    corner_normals: np.ndarray
    ior: float
    transmission_weight: float
    tint: tuple[float, float, float]
    absorption: tuple[float, float, float]

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)


def water_read(name, orig, vertices, triangles, corner_normals, optics: MaterialOptics):
    """The `WaterRead` of a water-like material's surface (`water_reason` is "")."""
    tint = np.sqrt(np.clip(np.asarray(optics.tint, dtype=float).reshape(3), 0.0, 1.0))
    return WaterRead(
        name=name,
        orig=orig,
        vertices=np.asarray(vertices, dtype=float).reshape(-1, 3),
        triangles=np.asarray(triangles, dtype=np.int64).reshape(-1, 3),
        corner_normals=np.asarray(corner_normals, dtype=float).reshape(-1, 3, 3),
        ior=float(optics.ior),
        transmission_weight=min(max(float(optics.transmission), 0.0), 1.0),
        tint=tuple(float(x) for x in tint),
        absorption=tuple(float(x) for x in np.maximum(optics.absorption, 0.0)),
    )


def water_text(taken, unlit=()) -> str:
    """The report's words on the water surfaces: ``taken`` (name, triangles, the
    receivers its caustic lies on) of those with a caustic layer, ``unlit`` names of
    those no light reaches from above ("" for none): "water: Pool (20 000 triangles)
    over Floor, Wall"."""
    parts = []
    for name, tris, receivers in taken:
        count = f"{tris:,}".replace(",", "\u2009")
        under = ", ".join(receivers) if receivers else "nothing under it"
        parts.append(f"water: {name} ({count} triangles) over {under}")
    if unlit:
        parts.append(f"no light above the water of {', '.join(unlit)}")
    return "; ".join(parts)
