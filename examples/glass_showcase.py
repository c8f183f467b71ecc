"""The glass showcase: glass that is not a sphere, on a wooden table in the sun.

    build_glass_showcase(scene)    builds it into `scene` (bpy), any engine
    python examples/glass_showcase.py [--out docs] [--engines cycles,eevee]
                                   [--resolution 480x270] [--samples 64]
                                   renders it without and with lens lights:
                                   OUT/glass_before_<engine>.png, glass_after_<engine>.png

A magnifying glass held in the sun (a biconvex lens, R 10 cm, 7 cm across, its axis on
the sun so that its focal spot lies on the table), an ice cube, a glass rod lying on
the table and an oblate pebble; a marble beside them. The sun stands 50° high with an
angle of 1°. "Before" is each engine as it is: Cycles with its own refractive caustics
on (its defaults), EEVEE with none. Generate traces every glass mesh onto the table.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from showcase import (  # noqa: E402
    add_camera,
    glass_material,
    plain_material,
    set_world,
    uv_sphere,
)
from showcase import main as showcase_main  # noqa: E402

SUN_AZIMUTH, SUN_ELEVATION = 35.0, 50.0  # degrees
#: The magnifier: radius of its two faces, thickness, diameter, and where on the table
#: its focal spot falls.
LENS_R, LENS_T, LENS_D, SPOT = 0.10, 0.014, 0.07, (-0.02, 0.06)


def _sun_dir():
    a, e = math.radians(SUN_AZIMUTH), math.radians(SUN_ELEVATION)
    return (math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e))


def _biconvex(mesh, rings=24, segments=96):
    """A biconvex lens along z: two spherical caps of radius LENS_R, LENS_T thick at
    the centre, cut at LENS_D by a thin rim band (sharp edges at the rim)."""
    import bmesh

    rim, h = 0.5 * LENS_D, 0.5 * LENS_T

    def cap_z(rho):
        return h - (LENS_R - math.sqrt(LENS_R**2 - rho**2))

    front = [(rim * i / rings, cap_z(rim * i / rings)) for i in range(rings + 1)]
    profile = front + [(rho, -z) for rho, z in reversed(front)]
    bm = bmesh.new()
    rows = []
    for rho, z in profile:
        if rho == 0.0:
            rows.append([bm.verts.new((0.0, 0.0, z))])
            continue
        ring = []
        for k in range(segments):
            phi = 2.0 * math.pi * k / segments
            ring.append(bm.verts.new((rho * math.cos(phi), rho * math.sin(phi), z)))
        rows.append(ring)
    for a, b in zip(rows[:-1], rows[1:], strict=True):
        for k in range(segments):
            k1 = (k + 1) % segments
            if len(a) == 1:
                bm.faces.new((a[0], b[k], b[k1]))
            elif len(b) == 1:
                bm.faces.new((a[k], b[0], a[k1]))
            else:
                bm.faces.new((a[k], b[k], b[k1], a[k1]))
    bmesh.ops.recalc_face_normals(bm, faces=bm.faces)
    for f in bm.faces:
        f.smooth = True
    rim_rows = {v for v in rows[rings] + rows[rings + 1]}
    for e in bm.edges:  # the caps' rims: a crease, not smoothed into the band
        if all(v in rim_rows for v in e.verts) and abs(e.verts[0].co.z - e.verts[1].co.z) < 1e-9:
            e.smooth = False
    bm.to_mesh(mesh)
    bm.free()


def build_glass_showcase(scene):
    """Build the glass showcase into `scene`; returns a dict of the objects made."""
    import bpy
    from mathutils import Vector

    made = {}
    coll = scene.collection

    def add(name, mesh):
        ob = bpy.data.objects.new(name, mesh)
        coll.objects.link(ob)
        made[name] = ob
        return ob

    s = 0.6
    table = bpy.data.meshes.new("Table")
    table.from_pydata([(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], [], [(0, 1, 2, 3)])
    add("Table", table).data.materials.append(plain_material("Wood", (0.42, 0.27, 0.15), 0.55)[0])
    glass = glass_material("Glass", (1.0, 1.0, 1.0))

    sun = Vector(_sun_dir())
    lens = add("Magnifier", bpy.data.meshes.new("Magnifier"))
    _biconvex(lens.data)
    f = LENS_R / (2.0 * 0.5)  # thin lens, n = 1.5
    lens.location = Vector((*SPOT, 0.0)) + f * sun
    lens.rotation_euler = sun.to_track_quat("Z", "Y").to_euler()

    # 0.2 mm above the table: a glass face lying on the receiver renders wrongly in
    # Cycles itself (SPEC §9)
    bpy.ops.mesh.primitive_cube_add(size=0.03, location=(0.12, -0.06, 0.015 + 0.0002))
    cube = bpy.context.object
    cube.name = "Ice cube"
    cube.rotation_euler = (0.0, 0.0, math.radians(25.0))
    made["Ice cube"] = cube

    bpy.ops.mesh.primitive_cylinder_add(
        vertices=48, radius=0.01, depth=0.14, location=(-0.10, -0.10, 0.0101)
    )
    rod = bpy.context.object
    rod.name = "Rod"
    rod.rotation_euler = (0.0, math.pi / 2.0, math.radians(-20.0))
    bpy.ops.object.shade_smooth_by_angle()
    made["Rod"] = rod

    pebble = add("Pebble", bpy.data.meshes.new("Pebble"))
    uv_sphere(pebble.data, 1.0, 64, 32)
    pebble.scale = (0.03, 0.025, 0.012)
    pebble.location = (0.10, 0.10, 0.0121)

    marble = add("Marble", bpy.data.meshes.new("Marble"))
    uv_sphere(marble.data, 0.02, 48, 24)
    marble.location = (-0.14, 0.10, 0.02)

    for ob in (lens, cube, rod, pebble, marble):
        ob.data.materials.clear()
        ob.data.materials.append(glass)

    sun_data = bpy.data.lights.new("Sun", "SUN")
    sun_data.energy = 2.5
    sun_data.angle = math.radians(1.0)
    sun_ob = bpy.data.objects.new("Sun", sun_data)
    coll.objects.link(sun_ob)
    sun_ob.rotation_euler = (-sun).to_track_quat("-Z", "Y").to_euler()
    made["Sun"] = sun_ob

    made["camera"] = add_camera(scene, (0.0, -0.36, 0.30), (0.0, 0.0, 0.0))
    set_world(scene, "Sky", (0.05, 0.06, 0.08))
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 480, 270, 100
    scene.eevee.use_raytracing = True  # glass that refracts in EEVEE
    return made


def main(argv=None) -> int:
    return showcase_main(argv, build_glass_showcase, "glass", samples=64, doc=__doc__)


if __name__ == "__main__":
    sys.exit(main())
