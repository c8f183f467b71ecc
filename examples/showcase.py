"""The showcase: glass marbles on a wooden table, lit by two low point lights.

    build_showcase(scene)          builds it into `scene` (bpy), any engine
    python examples/showcase.py [--out docs] [--engines cycles,eevee]
                                   [--resolution 480x270] [--samples 32]
                                   renders it without and with lens lights:
                                   OUT/showcase_before_<engine>.png, showcase_after_<engine>.png

The lights stand low (about 15° above the table), as at a window late in the day,
so each marble's beam runs obliquely and meets the table beyond its focus: the
caustics are the bright, elongated spots inside the marbles' shadows. Cycles
cannot find them by path tracing from point lights, and EEVEE has no refractive
caustics at all; "Generate lens lights" adds one spot light per light × marble.

Sizes are real: marbles 3–5 cm in radius, the lights 0.7–0.9 m away.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: (name, centre on the table (x, y), radius, base colour: the tint of a path)
MARBLES = (
    ("Marble clear", (-0.10, 0.02), 0.045, (1.0, 1.0, 1.0)),
    ("Marble blue", (0.09, 0.08), 0.035, (0.55, 0.75, 1.0)),
    ("Marble amber", (0.04, -0.11), 0.03, (1.0, 0.7, 0.3)),
)
#: (name, azimuth °, elevation °, distance from the table's centre, power W, colour)
LIGHTS = (
    ("Warm lamp", 200.0, 14.0, 0.85, 120.0, (1.0, 0.78, 0.55)),
    ("Cool lamp", -35.0, 17.0, 0.75, 80.0, (0.7, 0.85, 1.0)),
)


def plain_material(name, color, roughness=0.5):
    import bpy

    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True  # Blender 4.x: no node tree until then
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    return mat, bsdf


def glass_material(name, tint):
    mat, bsdf = plain_material(name, tint, roughness=0.0)
    bsdf.inputs["Transmission Weight"].default_value = 1.0
    bsdf.inputs["IOR"].default_value = 1.5
    # EEVEE: refract through the scene (ray traced), the marble's thickness a sphere.
    for attr, value in (("use_raytrace_refraction", True), ("thickness_mode", "SPHERE")):
        if hasattr(mat, attr):
            setattr(mat, attr, value)
    return mat


def build_showcase(scene):
    """Build the showcase into `scene` (objects linked to its collection; world,
    camera and light render settings set; engine and samples left to the caller
    except for sensible defaults). Returns a dict of the objects made."""
    import bpy

    made = {}
    coll = scene.collection

    # The table: a wide plane with a warm wood colour.
    mesh = bpy.data.meshes.new("Table")
    s = 1.2
    mesh.from_pydata([(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], [], [(0, 1, 2, 3)])
    table = bpy.data.objects.new("Table", mesh)
    coll.objects.link(table)
    wood, bsdf = plain_material("Wood", (0.42, 0.27, 0.15), roughness=0.55)
    table.data.materials.append(wood)
    made["table"] = table

    for name, (x, y), radius, tint in MARBLES:
        m = bpy.data.meshes.new(name)
        ob = bpy.data.objects.new(name, m)
        coll.objects.link(ob)
        uv_sphere(m, radius, 48, 24)
        ob.location = (x, y, radius)  # resting on the table
        ob.data.materials.append(glass_material(f"Glass {name.split()[-1]}", tint))
        made[name] = ob

    for name, azimuth, elevation, dist, power, color in LIGHTS:
        data = bpy.data.lights.new(name, "POINT")
        data.energy = power
        data.color = color
        data.shadow_soft_size = 0.01
        ob = bpy.data.objects.new(name, data)
        coll.objects.link(ob)
        a, e = math.radians(azimuth), math.radians(elevation)
        ob.location = (
            dist * math.cos(e) * math.cos(a),
            dist * math.cos(e) * math.sin(a),
            dist * math.sin(e),
        )
        made[name] = ob

    made["camera"] = add_camera(scene, (0.05, -0.62, 0.48), (0.0, -0.02, 0.02))
    set_world(scene, "Dim room", (0.02, 0.022, 0.025))

    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 480, 270, 100
    scene.cycles.caustics_refractive = False  # path-traced caustics: noise only
    scene.cycles.caustics_reflective = False
    scene.eevee.use_raytracing = True  # glass that refracts in EEVEE
    scene.eevee.taa_render_samples = 32
    return made


def add_camera(scene, location, target, lens_mm=50.0):
    """A camera at `location` looking at `target`, the scene's camera."""
    import bpy

    data = bpy.data.cameras.new("Camera")
    data.lens = lens_mm
    cam = bpy.data.objects.new("Camera", data)
    scene.collection.objects.link(cam)
    cam.location = location
    _look_at(cam, target)
    scene.camera = cam
    return cam


def set_world(scene, name, color):
    """A plain world of `color` for `scene`."""
    import bpy

    world = bpy.data.worlds.new(name)
    bg = world.node_tree.nodes.get("Background") if world.node_tree else None
    if bg is not None:
        bg.inputs["Color"].default_value = (*color, 1.0)
        bg.inputs["Strength"].default_value = 1.0
    else:
        world.color = color
    scene.world = world


def uv_sphere(mesh, radius, segments, rings):
    import bmesh

    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=radius)
    # the operator's face order follows memory addresses (it differs build to build,
    # and so did the glass showcase's layer, a pebble of it): one order by vertices
    bm.verts.index_update()
    nv = len(bm.verts)

    def by_vertices(f):  # a face's three least vertices name it
        a, b, c = sorted(v.index for v in f.verts)[:3]
        return (a * nv + b) * nv + c

    bm.faces.sort(key=by_vertices)
    for f in bm.faces:
        f.smooth = True
    bm.to_mesh(mesh)
    bm.free()


def _look_at(ob, target):
    from mathutils import Vector

    direction = Vector(target) - ob.location
    ob.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()


# --------------------------------------------------------------------------- script


def _load_extension():
    """The repository as the package `lens_lights`, registered (as Blender would
    load the installed extension); reuses an already registered one."""
    import bpy

    if hasattr(bpy.types.Scene, "lens_lights") and hasattr(bpy.ops.lens_lights, "generate"):
        return
    name = "lens_lights"
    module = sys.modules.get(name)
    if module is None:
        spec = importlib.util.spec_from_file_location(
            name, ROOT / "__init__.py", submodule_search_locations=[str(ROOT)]
        )
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    module.register()


ENGINES = {"cycles": "CYCLES", "eevee": "BLENDER_EEVEE"}


def _engine_id(scene, engine):
    """Blender's identifier for `engine` ("BLENDER_EEVEE_NEXT" in 4.2–4.5)."""
    ident = ENGINES[engine]
    known = {i.identifier for i in scene.render.bl_rna.properties["engine"].enum_items}
    if ident not in known and f"{ident}_NEXT" in known:
        return f"{ident}_NEXT"
    return ident


def render_before_after(
    out_dir,
    engines=("eevee", "cycles"),
    resolution=(480, 270),
    samples=32,
    build=None,
    name="showcase",
):
    """Render the showcase (or the scene `build(scene)` makes, as OUT/<name>_…) without
    and with lens lights per engine; returns the paths."""
    import bpy

    _load_extension()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for engine in engines:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        _load_extension()
        scene = bpy.context.scene
        (build or build_showcase)(scene)
        scene.render.engine = _engine_id(scene, engine)
        scene.render.resolution_x, scene.render.resolution_y = resolution
        scene.render.image_settings.file_format = "PNG"
        if engine == "cycles":
            scene.cycles.device = "CPU"
            scene.cycles.samples = samples
            scene.cycles.use_denoising = True
        else:
            scene.eevee.taa_render_samples = samples
        for stage in ("before", "after"):
            if stage == "after":
                bpy.ops.lens_lights.generate()
                print(scene.lens_lights.last_report, flush=True)
            path = out_dir / f"{name}_{stage}_{engine}.png"
            scene.render.filepath = str(path)
            t = time.perf_counter()
            bpy.ops.render.render(write_still=True)
            print(f"{path} ({time.perf_counter() - t:.1f} s)", flush=True)
            paths.append(path)
    return paths


def main(argv=None, build=None, name="showcase", samples=32, doc=__doc__) -> int:
    """The command line: render the scene `build` makes (the showcase's by default)
    without and with lens lights, as OUT/<name>_<stage>_<engine>.png."""
    parser = argparse.ArgumentParser(
        description=doc, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", default=str(ROOT / "docs"), help="output folder (default: docs/)")
    parser.add_argument(
        "--engines", default="eevee,cycles", help="comma-separated: eevee, cycles (default: both)"
    )
    parser.add_argument("--resolution", default="480x270", help="WxH (default 480x270)")
    parser.add_argument(
        "--samples", type=int, default=samples, help=f"samples per pixel (default {samples})"
    )
    args = parser.parse_args(argv)
    engines = [e.strip().lower() for e in args.engines.split(",") if e.strip()]
    if any(e not in ENGINES for e in engines):
        parser.error(f"engines: choose from {', '.join(ENGINES)}")
    w, h = (int(v) for v in args.resolution.lower().split("x"))
    for path in render_before_after(args.out, engines, (w, h), args.samples, build, name):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
