"""Water surfaces (issue 26): among the open glass meshes the scene read left out
(`core.lens.closed_mesh.OPEN_REASON`), those whose material refracts like water
(`core.scene.water.water_reason`: Principled or Glass BSDF, IOR ≈ 1.33, Volume
Absorption for the depth tint) are read as they render — the evaluated mesh (an
Ocean modifier, displacement, a shape key applied), its loop triangles and corner
normals in world space — into `core.scene.water.WaterRead`s.
"""

from __future__ import annotations

import numpy as np

from ...core.lens.closed_mesh import OPEN_REASON
from ...core.scene.water import water_read, water_reason
from .materials import main_material, material_optics
from .scene import read_local_mesh


def open_glass_names(read) -> set:
    """The names of the glass the read left out as open meshes."""
    return {name for name, why in getattr(read, "unmodelled_glass", []) if why == OPEN_REASON}


def read_water(depsgraph, read) -> tuple[list, list]:
    """(the water surfaces, the open glass that is not water as (name, why)) of the
    open glass meshes in ``read`` (`open_glass_names`), from ``depsgraph``."""
    names = open_glass_names(read)
    waters, not_water, seen = [], [], set()
    if not names:
        return waters, not_water
    for inst in depsgraph.object_instances:
        ob = inst.object
        if ob.type != "MESH" or inst.is_instance:
            continue
        orig = ob.original
        if orig.name not in names or orig.name in seen:
            continue
        seen.add(orig.name)
        optics = material_optics(main_material(ob, ob.data))
        why = water_reason(optics)
        if why:
            not_water.append((orig.name, why))
            continue
        local = read_local_mesh(ob.data)
        m = np.array(inst.matrix_world)
        lin = m[:3, :3]
        v = local.vertices @ lin.T + m[:3, 3]
        # normals by the inverse transpose (a scaled plane stays shaded right)
        nrm = local.corner_normals @ np.linalg.inv(lin)
        nrm /= np.maximum(np.linalg.norm(nrm, axis=-1, keepdims=True), 1e-300)
        waters.append(water_read(orig.name, orig, v, local.triangles, nrm, optics))
    return waters, not_water


def take_water(read, waters) -> None:
    """The water surfaces leave the read's lists of glass left out (they are taken:
    Cycles' own caustics need not stay on for them)."""
    taken = {w.name for w in waters}
    for attr in ("left_out", "left_out_lenses", "unmodelled_glass"):
        items = getattr(read, attr, None)
        if items is not None:
            items[:] = [(n, why) for n, why in items if n not in taken]
