"""The glass meshes that are lenses of their own (issue 25): a closed glass object that
is no sphere (a rod, a cube, a pebble, a magnifying glass, a sphere scaled into an
ellipsoid) is traced through its triangles (`core.lens.mesh`) in the caustic layer,
in both engines. Pure: the Blender side hands each glass record's local mesh over
lazily (`GeometryRecord.lens_mesh`, read only for the records asked), and
`assembly.assemble` asks `local_lens_mesh` for it and places each instance
(`place`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..lens.closed_mesh import LocalMesh, WorldMesh, problem, world_mesh
from ..lens.glass import LensOptics


@dataclass
class MeshLensRead:
    """One instance of a glass mesh read as a lens: its name (an instance's as the
    report names it), the original object (for a geometry-nodes instance: its
    instancer), the mesh in world space, the lens' IOR, transmission and optics."""

    name: str
    orig: object
    mesh: WorldMesh
    ior: float
    kt: float
    optics: LensOptics = field(default_factory=LensOptics)

    @property
    def n_triangles(self) -> int:
        return self.mesh.n_triangles


def local_lens_mesh(source) -> tuple[LocalMesh | None, str]:
    """(the local mesh, "") when `source` (`GeometryRecord.lens_mesh`: a LocalMesh, or
    a callable giving one or a reason, or None) is a closed outward glass volume,
    else (None, why not)."""
    if source is None:
        return None, ""
    local = source() if callable(source) else source
    if isinstance(local, str):
        return None, local
    why = problem(local.vertices, local.triangles)
    return (None, why) if why else (local, "")


def place(name, orig, local: LocalMesh, matrix, ior, kt, optics) -> MeshLensRead:
    """One instance of `local` at `matrix` (world)."""
    return MeshLensRead(
        name, orig, world_mesh(local, np.asarray(matrix, dtype=float)), float(ior), float(kt),
        optics or LensOptics(),
    )  # fmt: skip
