"""Live update's cost per frame → reports/live_update.md (or ``--report NAME``).

Builds, in the bpy module, a floor, two point lights (one keyed to move every frame)
and N glass spheres (separate objects sharing one mesh, on a grid 1 above the floor),
turns ``scene.lens_lights.live_update`` on, and times ``scene.frame_set(k)`` over a
few frames: the update itself (`blender.commands.live_update.LAST_FIGURES`: reading the
viewport depsgraph, phase 1, planning, applying to the Blender lights in place) and
the whole ``frame_set`` with and without live update (Blender's own evaluation).

    ./lens-lights bench live_update [--counts 10 100 1000] [--frames 6]
        [--tiers FITTED EXACT_PROFILE CAUSTIC_LAYER] [--layer-max 10] [--profile-max 10]
        [--unrelated 20] [--drags 20] [--resting 1 10] [--layer-resting 1 10]
        [--render-px 32]

Targets (issue 15): ≤ 20 ms per frame for 10 lenses × 2 lights, ≤ 200 ms for 1000
lenses. Each count runs with the default maximum of 64 lens lights and, when there
are more sources, with every source lit (max_lights = 2 N). The Caustic layer runs
for ``--layer-counts`` up to ``--layer-max`` lenses (its own section, below), the Exact profile (a new profile table for every
new D/R, i.e. for every light whose distance to its lens changed) up to
``--profile-max``.

The Caustic layer (issue 27) runs as in Blender's window (`live_update.INTERACTIVE`):
a coarse layer per update while frames follow each other, the full one when they stop
(`live_update.refine`, the timer's work, called here at once). Its own section
(``--layer-counts``, 1 10 100 by default; the main table's CAUSTIC_LAYER rows come from
it): per frame change and per light drag (Lamp B moved by a depsgraph update, no frame
change), the coarse state's L1 against the full layer of that frame, the refine's
time, and whether the state after it equals a fresh Generate (the layer meshes'
positions and irradiance, array for array). ``--layer-resting`` (lens counts, 1 10 by
default): the same with the marbles resting on the floor (issue 27's case: their
caustics in the near field).

Resting marbles (issue 27, ``--resting``: lens counts): the Exact profile in Cycles
with the marbles on the floor (the near field), as in Blender's window (coarse tables
while frames and drags follow each other), per frame change and per drag of the
other lamp, the coarse state after them and the refined one (the timer's exact
tables) against a fresh Generate (`run_resting`).

Unrelated edits (issue 28): with ``--unrelated`` lenses (20 by default), a cube no
light path touches is dragged with live update off and on; the difference is what
live update costs per edit it need not follow (target ≤ 5 ms in EEVEE).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
sys.path.insert(0, str(ROOT))

import bpy
import numpy as np
from dev_extension import load_extension

REPORTS = ROOT / "reports"
SPACING = 1.0
RADIUS = 0.3
ENGINE = {"FITTED": "BLENDER_EEVEE", "EXACT_PROFILE": "CYCLES", "CAUSTIC_LAYER": "BLENDER_EEVEE"}


def glass_material():
    mat = bpy.data.materials.new("Glass")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Transmission Weight"].default_value = 1.0
    bsdf.inputs["IOR"].default_value = 1.5
    return mat


def build_scene(n, frames, resting=False):
    """`resting`: the spheres lie on the floor (their centre R above it: the Exact
    profile's near field, its table's rows on the floor and tilted as the lamp moves)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    side = int(math.ceil(math.sqrt(n)))
    bpy.ops.mesh.primitive_plane_add(size=SPACING * side + 4)
    bpy.context.object.name = "Floor"
    bpy.ops.mesh.primitive_uv_sphere_add(radius=RADIUS)
    bead = bpy.context.object
    bead.data.materials.append(glass_material())
    half = SPACING * (side - 1) / 2
    beads = [bead]
    for k in range(1, n):
        ob = bpy.data.objects.new(f"Bead.{k:05d}", bead.data)
        scene.collection.objects.link(ob)
        beads.append(ob)
    height = RADIUS if resting else 1.0
    for k, ob in enumerate(beads):
        ob.location = (SPACING * (k % side) - half, SPACING * (k // side) - half, height)
    lamps = []
    for name, loc in (
        ("Lamp A", (0.3 * side, 0.2 * side, 12.0)),
        ("Lamp B", (-0.25 * side, -0.1 * side, 9.0)),
    ):
        data = bpy.data.lights.new(name, "POINT")
        data.energy = 1000.0
        data.shadow_soft_size = 0.1
        ob = bpy.data.objects.new(name, data)
        scene.collection.objects.link(ob)
        ob.location = loc
        lamps.append(ob)
    a = lamps[0]
    a.keyframe_insert("location", frame=1)
    a.location.x -= 0.5 * side
    a.keyframe_insert("location", frame=frames + 1)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.location = (0.0, -1.2 * side, 0.8 * side)
    cam.rotation_euler = (math.radians(55), 0.0, 0.0)
    scene.camera = cam
    scene.frame_start, scene.frame_end = 1, frames + 1


def set_engine(engine):
    if engine == "BLENDER_EEVEE" and bpy.app.version < (5, 0, 0):
        engine = "BLENDER_EEVEE_NEXT"
    bpy.context.scene.render.engine = engine


def run_case(n, tier, max_lights, frames):
    from lens_lights.blender.commands import live_update
    from lens_lights.core.tiers import exact_profile

    # Each case from cold caches: a row must not reuse the profiles of the one before.
    exact_profile.cached_profile.cache_clear()
    exact_profile._beam_summary.cache_clear()
    build_scene(n, frames)
    scene = bpy.context.scene
    set_engine(ENGINE[tier])
    settings = scene.lens_lights
    settings.energy_model = tier
    settings.max_lights = max_lights
    scene.frame_set(1)
    base = []
    for k in range(2, frames + 2):
        t = time.perf_counter()
        scene.frame_set(k)
        base.append(time.perf_counter() - t)
    scene.frame_set(1)
    t = time.perf_counter()
    settings.live_update = True  # the first update creates the lights
    first = time.perf_counter() - t
    lights = [ob for ob in bpy.data.objects if ob.lens_lights.is_lens_light]
    pointers = {ob.as_pointer() for ob in lights if ob.type == "LIGHT"}
    total, upd, plan, apply = [], [], [], []
    steps: dict = {}
    for k in range(2, frames + 2):
        t = time.perf_counter()
        scene.frame_set(k)
        total.append(time.perf_counter() - t)
        f = live_update.LAST_FIGURES
        if "error" in f:
            raise RuntimeError(f["error"])
        upd.append(f["seconds"])
        plan.append(f["plan_seconds"])
        apply.append(f["apply_seconds"])
        for key, v in f["timings"].items():
            steps.setdefault(key, []).append(v)
    lights = [ob for ob in bpy.data.objects if ob.lens_lights.is_lens_light]
    kept = pointers <= {ob.as_pointer() for ob in lights} if pointers else None
    return dict(
        **_timing_row(n, tier, max_lights, lights, first, upd, plan, apply, total, base, steps),
        kept=kept,
        last=dict(live_update.LAST_FIGURES),
    )


def _timing_row(n, tier, max_lights, lights, first, upd, plan, apply, total, base, steps):
    """A report row's case and timings (medians over the frames; the slowest update)."""
    med = statistics.median
    return dict(
        n=n,
        tier=tier,
        max_lights=max_lights,
        lights=len(lights),
        first=first,
        update=med(upd),
        update_max=max(upd),
        plan=med(plan),
        apply=med(apply),
        frame=med(total),
        base=med(base),
        steps={k: med(v) for k, v in steps.items() if not k.startswith("bake ")},
    )


def _layer_arrays():
    """The caustic layers' meshes (not the reflection copies): name → (positions,
    irradiance, object pointer, mesh pointer)."""
    import numpy as np

    out = {}
    for ob in bpy.data.objects:
        if (
            ob.type != "MESH"
            or not ob.lens_lights.is_lens_light
            or ob.get("lens_lights_reflection")
        ):
            continue
        me = ob.data
        co = np.zeros(3 * len(me.vertices), np.float32)
        me.vertices.foreach_get("co", co)
        irr = np.zeros(4 * len(me.vertices), np.float32)
        me.attributes["lens_irradiance"].data.foreach_get("color", irr)
        out[ob.name] = (co, irr, ob.as_pointer(), me.as_pointer())
    return out


def _sampled(layer, pts):
    """The irradiance of `layer` (a core `CausticLayer`) at points on the floor (each
    texel's value; the fine raster over its coarse one)."""
    import numpy as np

    out = np.zeros((len(pts), 3))
    for pl in sorted(layer.patches, key=lambda p: not p.coarse):
        x = (pts - pl.origin) @ pl.axis_u
        y = (pts - pl.origin) @ pl.axis_v
        ix = np.searchsorted(pl.edges_u, x) - 1
        iy = np.searchsorted(pl.edges_v, y) - 1
        ok = (ix >= 0) & (ix < pl.resolution) & (iy >= 0) & (iy < pl.resolution)
        out[ok] = pl.irradiance[iy[ok], ix[ok]]
    return out


def layer_l1(layer, truth, n):
    """L1 of `layer`'s irradiance against `truth`'s over the floor (relative: the sum
    of |difference| over the sum of |truth|), sampled every `L1_STEP` (1 cm)."""
    import numpy as np

    half = 0.5 * (SPACING * int(math.ceil(math.sqrt(n))) + 4)
    g = np.arange(-half, half, L1_STEP)
    x, y = np.meshgrid(g, g)
    pts = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    a, t = _sampled(layer, pts), _sampled(truth, pts)
    return float(np.abs(a - t).sum() / max(np.abs(t).sum(), 1e-300))


L1_STEP = 0.01


def _fresh_layer(scene):
    """The full layer of the scene as it is now (the pipeline Generate runs, on the
    viewport's depsgraph: the reference for the coarse state's L1)."""
    from lens_lights.blender.commands import pipeline

    dg = bpy.context.evaluated_depsgraph_get()
    work = pipeline.plan_scene(dg, scene, pipeline.options_from(scene.lens_lights))
    return work.layer_bake.layer


def run_layer_case(n, max_lights, frames, drags, resting=False):
    """Issue 27: the Caustic layer's live update as in Blender's window: per frame
    change and per light drag (coarse), the refine after them, the states' accuracy;
    ``resting``: the marbles on the floor."""
    from lens_lights.blender.commands import live_update
    from lens_lights.blender.commands.generate import generate

    live_update.INTERACTIVE = True
    try:
        build_scene(n, frames, resting=resting)
        scene = bpy.context.scene
        set_engine(ENGINE["CAUSTIC_LAYER"])
        settings = scene.lens_lights
        settings.energy_model = "CAUSTIC_LAYER"
        settings.max_lights = max_lights
        scene.frame_set(1)
        base = []
        for k in range(2, frames + 2):
            t = time.perf_counter()
            scene.frame_set(k)
            base.append(time.perf_counter() - t)
        scene.frame_set(1)
        t = time.perf_counter()
        settings.live_update = True  # the first update: the full layer
        first = time.perf_counter() - t
        before = _layer_arrays()
        total, upd, plan, apply, coarse, cpu = [], [], [], [], [], []
        steps: dict = {}
        for k in range(2, frames + 2):
            t, c = time.perf_counter(), time.process_time()
            scene.frame_set(k)
            total.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
            f = live_update.LAST_FIGURES
            if "error" in f:
                raise RuntimeError(f["error"])
            upd.append(f["seconds"])
            plan.append(f["plan_seconds"])
            apply.append(f["apply_seconds"])
            coarse.append(bool(f.get("coarse")))
            for key, v in f["timings"].items():
                steps.setdefault(key, []).append(v)
        traced, reused = f.get("traced", 0), f.get("reused", 0)
        coarse_layer = f.get("layer")
        truth = _fresh_layer(scene)
        l1_frame = layer_l1(coarse_layer, truth, n)
        t = time.perf_counter()
        live_update.refine(scene, wait=False)  # the timer's work, at once
        refine = time.perf_counter() - t
        l1_refined = layer_l1(live_update.LAST_FIGURES["layer"], truth, n)
        after = _layer_arrays()
        kept = {k: v[2:] for k, v in before.items()} == {k: v[2:] for k, v in after.items()}
        # a light dragged (no frame change): Lamp B, a depsgraph update per step
        lamp = bpy.data.objects["Lamp B"]
        drag, drag_cpu = [], []
        for _ in range(drags):
            lamp.location.x += 0.02
            t, c = time.perf_counter(), time.process_time()
            bpy.context.view_layer.update()
            drag.append(time.perf_counter() - t)
            drag_cpu.append(time.process_time() - c)
        f = live_update.LAST_FIGURES
        drag_coarse = bool(f.get("coarse"))
        l1_drag = layer_l1(f["layer"], _fresh_layer(scene), n)
        live_update.refine(scene, wait=False)
        final = _layer_arrays()
        settings.live_update = False
        level, message, _ = generate(bpy.context)  # a fresh Generate of the dragged state
        fresh = _layer_arrays()
        equal = sorted(final) == sorted(fresh) and all(
            final[k][0].shape == fresh[k][0].shape
            and final[k][0].tobytes() == fresh[k][0].tobytes()
            and final[k][1].tobytes() == fresh[k][1].tobytes()
            for k in fresh
        )
    finally:
        live_update.INTERACTIVE = None
    med = statistics.median
    lights = [ob for ob in bpy.data.objects if ob.lens_lights.is_lens_light]
    return dict(
        **_timing_row(
            n, "CAUSTIC_LAYER", max_lights, lights, first, upd, plan, apply, total, base, steps
        ),
        resting=resting,
        kept=kept,
        coarse=sum(coarse),
        frames=frames,
        traced=traced,
        reused=reused,
        l1_frame=l1_frame,
        l1_refined=l1_refined,
        refine=refine,
        drag=med(drag),
        drag_max=max(drag),
        cpu=med(cpu),
        drag_cpu=med(drag_cpu),
        drag_coarse=drag_coarse,
        l1_drag=l1_drag,
        equal=equal,
    )


def run_unrelated(n, tier, drags):
    """Issue 28: dragging a cube that no light path touches (beyond the floor's edge,
    1.5 m and more from every beam) with live update on: the extra cost per
    depsgraph update over the same drag with it off, and how many updates ran."""
    from lens_lights.blender.commands import live_update

    build_scene(n, 1)
    scene = bpy.context.scene
    set_engine(ENGINE[tier])
    scene.lens_lights.energy_model = tier
    side = int(math.ceil(math.sqrt(n)))
    bpy.ops.mesh.primitive_cube_add(size=0.5, location=(SPACING * side / 2 + 3.5, 0.0, 0.25))
    cube = bpy.context.object
    scene.frame_set(1)

    def drag():
        times = []
        for k in range(drags):
            cube.location.y = 0.01 * k
            t = time.perf_counter()
            bpy.context.view_layer.update()
            times.append(time.perf_counter() - t)
        return statistics.median(times)

    off = drag()
    scene.lens_lights.live_update = True
    bpy.context.view_layer.update()  # the echo of its own build (once per real update)
    before = live_update.LAST_FIGURES
    on = drag()
    ran = live_update.LAST_FIGURES is not before
    # The same cube moved into a beam (over a lens): seen.
    cube.location = (0.0, 0.0, 1.6)
    t = time.perf_counter()
    bpy.context.view_layer.update()
    into = time.perf_counter() - t
    seen = live_update.LAST_FIGURES is not before
    scene.lens_lights.live_update = False
    return dict(n=n, tier=tier, off=off, on=on, ran=ran, into=into, seen=seen)


def _profile_state():
    """Each Exact profile lens light's numbers (by its source light and lens): its
    transform and light values, its tree's Value nodes, its table's pixels."""
    from lens_lights.blender.build import lights as bl

    out = {}
    for ob in bpy.data.objects:
        if not ob.lens_lights.is_lens_light or ob.type != "LIGHT":
            continue
        d = ob.data
        nt = d.node_tree
        nums = [*ob.location, *ob.rotation_quaternion, d.energy, *d.color, d.spot_size]
        nums += [d.shadow_soft_size, d.cutoff_distance]
        values = {
            n.name: n.outputs[0].default_value for n in nt.nodes if n.bl_idname == "ShaderNodeValue"
        }
        tex = nt.nodes.get(bl.PROFILE_TEX_NODE)
        px = np.zeros(0)
        if tex is not None and tex.image is not None:
            px = np.empty(len(tex.image.pixels), dtype=np.float32)
            tex.image.pixels.foreach_get(px)
        key = (ob.lens_lights.source_light, ob.lens_lights.source_lens)
        out[key] = (np.array(nums, float), values, px)
    return out


def _state_difference(a, b):
    """(same lights?, largest relative difference of the numbers, of the Value nodes,
    of the pixels (over each table's largest texel))."""
    if a.keys() != b.keys():
        return False, math.inf, math.inf, math.inf
    nums = vals = pix = 0.0
    for k in a:
        (na, va, pa), (nb, vb, pb) = a[k], b[k]
        nums = max(nums, float(np.max(np.abs(na - nb) / np.maximum(np.abs(nb), 1e-6))))
        if va.keys() != vb.keys() or pa.shape != pb.shape:
            return False, nums, math.inf, math.inf
        for n in va:
            vals = max(vals, abs(va[n] - vb[n]) / max(abs(vb[n]), 1e-6))
        if pb.size:
            pix = max(pix, float(np.max(np.abs(pa - pb)) / max(float(np.max(np.abs(pb))), 1e-30)))
    return True, nums, vals, pix


def _tiny_render(path, px):
    """A `px` × `px` Cycles render (16 samples, fixed seed, no denoising): its RGB."""
    sc = bpy.context.scene
    sc.render.resolution_x = sc.render.resolution_y = px
    sc.render.resolution_percentage = 100
    sc.cycles.samples = 16
    sc.cycles.seed = 0
    sc.cycles.use_denoising = False
    sc.cycles.device = "CPU"
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(path))
    rgb = np.array(img.pixels[:], dtype=float).reshape(px, px, 4)[..., :3]
    bpy.data.images.remove(img)
    return rgb


def run_resting(n, frames, drags, render_px):
    """Issue 27: `n` marbles resting on the floor, Cycles, the Exact profile; live update
    on as in Blender's window (`live_update.INTERACTIVE`: coarse tables while frames
    and drags follow each other), the lamp keyed to move: per frame change
    (`frame_set`) and per drag of the other lamp (a transform update without a frame
    change, `view_layer.update()`), the update's time; the coarse state after them
    against a fresh Generate's; then the refine (the timer's work, called at once) and
    the state after it against a fresh Generate on that frame (the lights' numbers,
    their trees' Value nodes, their tables' pixels, and a tiny Cycles render of
    each)."""
    import tempfile

    from lens_lights.blender.commands import live_update
    from lens_lights.blender.commands.generate import generate
    from lens_lights.core.tiers import exact_profile

    exact_profile.cached_profile.cache_clear()  # from cold caches
    live_update.INTERACTIVE = True  # as in Blender's window
    build_scene(n, frames, resting=True)
    scene = bpy.context.scene
    set_engine("CYCLES")
    settings = scene.lens_lights
    settings.energy_model = "EXACT_PROFILE"
    scene.frame_set(1)
    t = time.perf_counter()
    settings.live_update = True
    first = time.perf_counter() - t
    lights0 = {ob.as_pointer() for ob in bpy.data.objects if ob.lens_lights.is_lens_light}
    images0 = {i.as_pointer() for i in bpy.data.images}
    frame_t, frame_wall, drag_t, frame_cpu, drag_cpu, coarse = [], [], [], [], [], []
    for k in range(2, frames + 2):
        t, c = time.perf_counter(), time.process_time()
        scene.frame_set(k)
        frame_wall.append(time.perf_counter() - t)
        frame_cpu.append(time.process_time() - c)
        f = live_update.LAST_FIGURES
        if "error" in f:
            raise RuntimeError(f["error"])
        frame_t.append(f["seconds"])
        coarse.append(f.get("coarse", 0))
    lamp = bpy.data.objects["Lamp B"]
    for _ in range(drags):
        before = live_update.LAST_FIGURES
        lamp.location.x += 0.05
        lamp.location.y += 0.03
        c = time.process_time()
        bpy.context.view_layer.update()
        drag_cpu.append(time.process_time() - c)
        f = live_update.LAST_FIGURES
        if f is before:
            raise RuntimeError("a drag of the lamp was not followed")
        if "error" in f:
            raise RuntimeError(f["error"])
        drag_t.append(f["seconds"])
        coarse.append(f.get("coarse", 0))
    shown = _profile_state()  # what the user sees while working (no render: it refines)
    t, c = time.perf_counter(), time.process_time()
    live_update.refine(scene, wait=False)  # the timer's work once the burst is over
    refine_wall, refine_cpu = time.perf_counter() - t, time.process_time() - c
    if live_update.LAST_FIGURES.get("why") != "refined":
        raise RuntimeError("no refine after coarse tables")
    live_update.INTERACTIVE = None
    lights1 = {ob.as_pointer() for ob in bpy.data.objects if ob.lens_lights.is_lens_light}
    images1 = {i.as_pointer() for i in bpy.data.images}
    live = _profile_state()
    tmp = Path(tempfile.mkdtemp(prefix="lens-lights-bench-"))
    render_live = _tiny_render(tmp / "live.exr", render_px)
    t = time.perf_counter()
    generate(bpy.context)  # on the same frame, lamp B where the drags left it
    gen_seconds = time.perf_counter() - t
    fresh = _profile_state()
    render_fresh = _tiny_render(tmp / "fresh.exr", render_px)
    same, nums, vals, pix = _state_difference(live, fresh)
    coarse_same, _n, _v, coarse_pix = _state_difference(shown, fresh)
    l1 = float(np.abs(render_live - render_fresh).mean() / max(render_fresh.mean(), 1e-30))
    med = statistics.median
    return dict(
        n=n,
        lights=len(live),
        first=first,
        frame=med(frame_t),
        frame_max=max(frame_t),
        frame_wall=med(frame_wall),
        frame_cpu=med(frame_cpu),
        drag_cpu=med(drag_cpu),
        drag=med(drag_t),
        drag_max=max(drag_t),
        kept=lights0 <= lights1,
        new_images=len(images1 - images0),
        generate=gen_seconds,
        same=same,
        nums=nums,
        vals=vals,
        pix=pix,
        l1=l1,
        coarse=statistics.median(coarse),
        coarse_pix=coarse_pix if coarse_same else math.inf,
        refine=refine_wall,
        refine_cpu=refine_cpu,
    )


def ms(x):
    return f"{1000 * x:.1f}"


def layer_section(rows, args) -> list[str]:
    """The Caustic layer's section (issue 27)."""
    if not rows:
        return []
    lines = [
        "",
        "## Caustic layer: coarse while working, full when it stops (issue 27)",
        "",
        "As in Blender's window (`live_update.INTERACTIVE`): every update of a frame "
        "change or a drag shows the coarse layer (each (light, lens) pair's beam on an "
        "8 × 32 grid, at most 4 samples of an extended light, splatted alone into the "
        "last full layer's rasters; a pair whose inputs did not change is not traced "
        "again), written into the same meshes; the full layer follows when the updates "
        "stop (`live_update.refine`, a timer 0.3 s after the last update; here called "
        "at once).",
        "",
        "* **frame**: median `update` per frame change (one lamp of two moving; "
        "**coarse**: how many frames got the coarse layer); **drag**: median "
        "`view_layer.update()` per step of Lamp B moved 2 cm (no frame change); "
        "**cpu**: the same in CPU time of this process (`time.process_time`: on a "
        "machine shared with other work, closer to what a quiet one takes; numpy's "
        "threads count twice);",
        "* **traced / reused**: pairs' coarse beams traced and reused over the frames "
        "(the first coarse update traces all);",
        "* **L1 frame / drag**: the coarse layer after the last frame / drag step "
        "against the full layer of that state (irradiance over the floor sampled every "
        f"{L1_STEP * 100:.0f} cm, relative); **L1 refined**: after `refine` (0: the same);",
        "* **refine**: the full layer's update after the burst (timer); **= Generate**: "
        "after the drag and its refine, every layer mesh's positions and irradiance "
        "equal, byte for byte, a fresh Generate's; **kept**: the same objects and "
        "meshes from the first update to the refine.",
        "",
        "Target (issue 27): ≤ 100 ms per frame for 10 lenses resting on the floor, "
        "≤ 30 ms for one (**marbles**: floating 1 above the floor, or resting on it).",
        "",
        "| lenses | marbles | max lights | frame ms (max) | frame cpu ms | coarse | drag ms (max) "
        "| drag cpu ms | traced / reused | L1 frame | L1 drag | L1 refined | refine ms "
        "| first ms | = Generate | kept |",
        "| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: "
        "| ---: | ---: | --- | --- |",
    ]
    for r in rows:
        lines.append(
            f"| {r['n']} | {'resting' if r['resting'] else 'floating'} | {r['max_lights']} | "
            f"{ms(r['update'])} ({ms(r['update_max'])}) | "
            f"{ms(r['cpu'])} | {r['coarse']}/{r['frames']} | "
            f"{ms(r['drag'])} ({ms(r['drag_max'])}) | {ms(r['drag_cpu'])} | "
            f"{r['traced']} / {r['reused']} | {r['l1_frame']:.3f} | {r['l1_drag']:.3f} | "
            f"{r['l1_refined']:.3f} | {ms(r['refine'])} | {ms(r['first'])} | "
            f"{'yes' if r['equal'] else 'NO'} | {'yes' if r['kept'] else 'no'} |"
        )
    return lines


def write_report(rows, args, unrelated=(), layer_rows=(), resting=()):
    lines = [
        "# Live update: cost per frame",
        "",
        "`./lens-lights bench live_update "
        + " ".join(
            [f"--counts {' '.join(map(str, args.counts))}", f"--frames {args.frames}"]
            + [f"--tiers {' '.join(args.tiers)}", f"--layer-max {args.layer_max}"]
            + [f"--profile-max {args.profile_max}"]
            + [f"--layer-counts {' '.join(map(str, args.layer_counts))}"]
            + [f"--unrelated {' '.join(map(str, args.unrelated))}", f"--drags {args.drags}"]
            + [f"--resting {' '.join(map(str, args.resting))}"]
            + [f"--layer-resting {' '.join(map(str, args.layer_resting))}"]
            + [f"--render-px {args.render_px}"]
            + ([f"--report {args.report}"] if args.report != "live_update" else [])
        )
        + "`",
        "",
        f"Blender {bpy.app.version_string}, Python {platform.python_version()}, "
        f"{platform.machine()}, {os.cpu_count()} CPUs, shared with other work: load "
        f"average {args.load_before:.1f} at the start, {os.getloadavg()[0]:.1f} at the end "
        "(above the CPU count, every figure is inflated by about load / CPUs). N glass spheres (separate objects, one shared mesh) 1 above a "
        "floor, two point lights, one keyed to move every frame; medians over "
        f"{args.frames} frames of `scene.frame_set(k)`.",
        "",
        "* **update**: live update's handler (read the viewport depsgraph, phase 1, "
        "plan, apply in place); **plan** / **apply**: its two halves;",
        "* **frame_set**: the whole call with live update on; **without**: the same "
        "call with it off (Blender's own evaluation);",
        "* **first**: turning live update on (creates the lights);",
        "* **kept**: the Blender light objects of the first update are still the ones "
        "after the last frame (updated in place, not re-created).",
        "",
        "Targets (issue 15): ≤ 20 ms per frame for 10 lenses × 2 lights, ≤ 200 ms for 1000 lenses.",
        "",
        "| lenses | tier | max lights | lens lights | update ms (max) | plan ms | apply ms "
        "| frame_set ms | without ms | first ms | kept |",
        "| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for r in rows:
        lines.append(
            f"| {r['n']} | {r['tier']} | {r['max_lights']} | {r['lights']} | "
            f"{ms(r['update'])} ({ms(r['update_max'])}) | {ms(r['plan'])} | "
            f"{ms(r['apply'])} | {ms(r['frame'])} | {ms(r['base'])} | {ms(r['first'])} | "
            f"{'—' if r['kept'] is None else ('yes' if r['kept'] else 'no')} |"
        )
    lines += [
        "",
        "Where the time goes (the steps below): `read` walks the viewport depsgraph "
        "(per object: it grows with separate objects), `phase1` and `budget` are "
        "vectorised, `plan first` is the pre-selection's lights as columns (the tier's "
        "table maker), `plan` (which includes it) adds the kept sources' rays (the free "
        "distance and the receiver behind each lens, every kept source in one batched "
        "cast) and their lights (columns for Fitted and the Caustic layer, the "
        "per-source maker for the other tiers; a Fitted near-field fit is remembered "
        "per distinct geometry), `bake` is the Caustic layer's trace. **apply** writes "
        "the Blender lights. The Exact profile's **apply** includes its profile tables "
        "(made lazily on first use): one per new D/R, so every frame a light moves "
        "relative to a lens costs a table for that pair. Frames whose inputs equal the "
        "last update's are not planned at all (not measured here: a light moves on "
        "every frame).",
        "",
        "Steps of the update (median ms):",
        "",
    ]
    keys = sorted({k for r in rows for k in r["steps"]})
    lines.append("| lenses | tier | max lights | " + " | ".join(keys) + " |")
    lines.append("| ---: | --- | ---: |" + " ---: |" * len(keys))
    for r in rows:
        cells = [ms(r["steps"][k]) if k in r["steps"] else "" for k in keys]
        lines.append(f"| {r['n']} | {r['tier']} | {r['max_lights']} | " + " | ".join(cells) + " |")
    lines += layer_section(layer_rows, args)
    if unrelated:
        lines += [
            "",
            "## Unrelated edits (issue 28)",
            "",
            f"The scene above (one frame), plus a cube 0.5 beyond the floor's edge, 1.5 m "
            f"and more from every path of the light (lamp → lens, lens axis, the layer's "
            f"landings): it is dragged ({args.drags} depsgraph updates, median) with live "
            "update off, then on. **extra** = on − off: what live update costs per update "
            "of an object it need not follow (its filter: `core/plan/watch.py`). Then the "
            "cube is put over a lens (in the beam): that edit is followed.",
            "",
            "Target (issue 28): extra ≤ 5 ms with 20 marbles in EEVEE.",
            "",
            "| lenses | tier | off ms | on ms | extra ms | updates run while dragging | "
            "into the beam: followed (ms) |",
            "| ---: | --- | ---: | ---: | ---: | --- | --- |",
        ]
        for r in unrelated:
            lines.append(
                f"| {r['n']} | {r['tier']} | {ms(r['off'])} | {ms(r['on'])} | "
                f"{ms(r['on'] - r['off'])} | {'yes' if r['ran'] else 'none'} | "
                f"{'yes' if r['seen'] else 'NO'} ({ms(r['into'])}) |"
            )
    if resting:
        lines += [
            "",
            "## The Exact profile while working (issue 27)",
            "",
            "N glass marbles resting on the floor (their tables in the near field, the "
            "floor tilted against each lens' axis as the lamp moves), Cycles, the Exact "
            f"profile tier; live update on as in Blender's window (`live_update.INTERACTIVE`: "
            "a light whose exact table is not made yet shows a coarse one while frames and "
            "drags follow each other, `exact_profile.prepare_tables`; **coarse**: lights "
            "with a coarse table per update, median). **frame**: live update's time per frame change "
            f"(median over {args.frames} frames of `frame_set`, the keyed lamp moving; max; "
            "**CPU**: the process's CPU time per `frame_set`, less sensitive to the other "
            "work on the machine than the wall time); "
            f"**drag**: per transform update without a frame change (the other lamp moved, "
            f"`view_layer.update()`, median over {args.drags}; max); **first**: turning live "
            "update on; **kept**: the same light objects after all of it; **new images**: "
            "images made by the frames and drags (the tables are written into each light's "
            "own image in place). **coarse Δ pixels**: the coarse state after the last drag "
            "against Generate's exact tables (the largest difference over each table's "
            "largest texel); **refine**: the timer's exact tables once the burst is over "
            "(wall, CPU). Then Generate on the refined state: **Δ numbers** the largest "
            "relative difference of the lights' values (transform, power, colour, cone, "
            "radius), **Δ nodes** of their trees' Value nodes (distances, tilts), **Δ pixels** "
            "of their tables (over each table's largest texel), **render L1** the relative "
            f"L1 difference of a {args.render_px} × {args.render_px} Cycles render (16 "
            "samples, same seed) of the live state and of Generate's.",
            "",
            "Target (issue 27): frame ≤ 100 ms for 10 marbles, ≤ 30 ms for one; the state "
            "equal to a fresh Generate's.",
            "",
            "| lenses | lens lights | coarse | frame ms (max) | CPU ms | drag ms (max) | CPU ms "
            "| coarse Δ pixels | refine ms | CPU ms "
            "| first ms | kept | new images | Generate ms | Δ numbers | Δ nodes | Δ pixels "
            "| render L1 |",
            "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- "
            "| ---: | ---: | ---: | ---: | ---: | ---: |",
        ]
        for r in resting:
            lines.append(
                f"| {r['n']} | {r['lights']} | {r['coarse']:g} | {ms(r['frame'])} "
                f"({ms(r['frame_max'])}) | "
                f"{ms(r['frame_cpu'])} | {ms(r['drag'])} ({ms(r['drag_max'])}) | "
                f"{ms(r['drag_cpu'])} | {r['coarse_pix']:.1e} | {ms(r['refine'])} | "
                f"{ms(r['refine_cpu'])} | {ms(r['first'])} | "
                f"{'yes' if r['kept'] else 'no'} | {r['new_images']} | {ms(r['generate'])} | "
                + (
                    f"{r['nums']:.1e} | {r['vals']:.1e} | {r['pix']:.1e} | {r['l1']:.1e} |"
                    if r["same"]
                    else "other lights | | | |"
                )
            )
    report = REPORTS / f"{args.report}.md"
    report.write_text("\n".join(lines) + "\n")
    print(f"wrote {report.relative_to(ROOT)}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--counts", type=int, nargs="*", default=[10, 100, 1000])
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--tiers", nargs="+", default=["FITTED", "EXACT_PROFILE", "CAUSTIC_LAYER"])
    ap.add_argument("--layer-max", type=int, default=100)
    ap.add_argument("--profile-max", type=int, default=10)
    ap.add_argument("--unrelated", type=int, nargs="*", default=[20], help="lens counts")
    ap.add_argument("--drags", type=int, default=20)
    ap.add_argument(
        "--layer-counts", type=int, nargs="*", default=[1, 10, 100], help="issue 27's layer rows"
    )
    ap.add_argument("--resting", type=int, nargs="*", default=[1, 10], help="lens counts")
    ap.add_argument(
        "--layer-resting", type=int, nargs="*", default=[1, 10], help="lens counts (layer)"
    )
    ap.add_argument("--render-px", type=int, default=32)
    ap.add_argument("--report", default="live_update", help="report name in reports/")
    args = ap.parse_args(argv)
    load_extension().register()
    args.load_before = os.getloadavg()[0]
    rows, layer_rows = [], []
    if "CAUSTIC_LAYER" in args.tiers:
        for n in [c for c in args.layer_counts if c <= args.layer_max]:
            r = run_layer_case(n, 64, args.frames, args.drags)
            layer_rows.append(r)
            rows.append(r)
            print(
                f"{n} lenses CAUSTIC_LAYER: frame {ms(r['update'])} ms ({r['coarse']} coarse), "
                f"drag {ms(r['drag'])} ms, L1 {r['l1_frame']:.3f} / {r['l1_drag']:.3f}, "
                f"refine {ms(r['refine'])} ms, = Generate: {r['equal']}",
                flush=True,
            )
        for n in [c for c in args.layer_resting if c <= args.layer_max]:
            r = run_layer_case(n, 64, args.frames, args.drags, resting=True)
            layer_rows.append(r)
            print(
                f"{n} resting lenses CAUSTIC_LAYER: frame {ms(r['update'])} ms "
                f"({r['coarse']} coarse), drag {ms(r['drag'])} ms, L1 {r['l1_frame']:.3f} / "
                f"{r['l1_drag']:.3f}, refine {ms(r['refine'])} ms, = Generate: {r['equal']}",
                flush=True,
            )
    for n in args.counts:
        for tier in args.tiers:
            if tier == "CAUSTIC_LAYER":  # its rows: `run_layer_case` above
                continue
            if tier == "EXACT_PROFILE" and n > args.profile_max:
                continue
            for max_lights in (64, 2 * n) if 2 * n > 64 else (64,):  # 64: the default
                r = run_case(n, tier, max_lights, args.frames)
                rows.append(r)
                print(
                    f"{n} lenses {tier} max {max_lights}: {r['lights']} lights, update "
                    f"{ms(r['update'])} ms (plan {ms(r['plan'])}, apply {ms(r['apply'])}), "
                    f"frame_set {ms(r['frame'])} ms, without {ms(r['base'])} ms",
                    flush=True,
                )
    unrelated = []
    for n in args.unrelated:
        for tier in args.tiers:
            r = run_unrelated(n, tier, args.drags)
            unrelated.append(r)
            print(
                f"unrelated edit, {n} lenses {tier}: off {ms(r['off'])} ms, on {ms(r['on'])} "
                f"ms, updates run: {r['ran']}, into the beam followed: {r['seen']}",
                flush=True,
            )
    resting = []
    for n in args.resting:
        r = run_resting(n, args.frames, args.drags, args.render_px)
        resting.append(r)
        print(
            f"resting, {n} lenses EXACT_PROFILE: {r['lights']} lights, frame {ms(r['frame'])} ms "
            f"(CPU {ms(r['frame_cpu'])}), drag {ms(r['drag'])} ms (CPU {ms(r['drag_cpu'])}), "
            f"coarse pixels {r['coarse_pix']:.1e}, refine {ms(r['refine'])} ms; against "
            f"Generate: numbers {r['nums']:.1e}, nodes "
            f"{r['vals']:.1e}, pixels {r['pix']:.1e}, render L1 {r['l1']:.1e}",
            flush=True,
        )
    write_report(rows, args, unrelated, layer_rows, resting)


if __name__ == "__main__":
    main(sys.argv[1:])
    sys.stdout.flush()
    os._exit(0)  # bpy 4.x crashes at exit
