"""Scale on the Blender side (bpy module, small counts): instanced spheres are
fitted once per instanced mesh, phase 1's sources are pre-selected by flux before
any Python object is made for them, merging, and what the report says was left out
(the 10 000 / 100 000 figures: `./lens-lights bench operator_scale`)."""

import math
from types import SimpleNamespace

import bpy
import numpy as np
import pytest
from blender_scene_helpers import (
    add_point_light,
    add_sphere,
    collection_instance,
    collection_of,
    generate,
    glass_material,
    gn_instances,
    grid,
    lens_lights,
)

# The light pipeline: AUTO builds lights here (the Caustic layer: test_blender_layer.py).
pytestmark = [pytest.mark.blender, pytest.mark.usefixtures("auto_builds_lights")]


def floor(size=60):
    bpy.ops.mesh.primitive_plane_add(size=size)
    bpy.context.object.name = "Floor"


def count_calls(monkeypatch, module, name):
    calls = []
    real = getattr(module, name)

    def counted(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(module, name, counted)
    return calls


@pytest.mark.parametrize("kind", ["geometry", "object", "collection"])
def test_200_instances_are_fitted_once(empty_blend, monkeypatch, kind):
    from lens_lights.blender.read import scene as scene_reader

    glass = glass_material()
    points = grid(200, spacing=1.0)
    bead = add_sphere("Bead", (0, 0, -50), radius=0.2, material=glass)
    if kind == "geometry":
        gn_instances("Beads", points, radius=0.2, material=glass, location=(0, 0, 1))
    elif kind == "object":
        gn_instances("Beads", points, instance_object=bead, location=(0, 0, 1))
    else:
        beads = collection_of("Bead", bead)
        bead.location = (0, 0, 0)
        for k, (x, y, _z) in enumerate(points):
            collection_instance(f"Beads.{k:03d}", beads, location=(x, y, 1))
    if kind == "collection":
        assert bead.name not in bpy.context.scene.collection.objects
    add_point_light("Lamp", (7.0, 7.0, 12.0))
    monkeypatch.setattr(scene_reader, "_FITS", {})  # nothing remembered from other tests
    fits = count_calls(monkeypatch, scene_reader, "fit_sphere")
    materials = count_calls(monkeypatch, scene_reader, "material_optics")
    r = scene_reader.read_blender_scene(bpy.context)
    n = 200 if kind == "collection" else 201  # the bead itself is in the scene too
    assert len(r.sphere_sources) == n == len(r.arrays.radius) == len(r.lens_optics)
    # one fit per distinct mesh (geometry instances: the node tree's UV sphere and
    # the bead), one material evaluation per material
    assert len(fits) == (2 if kind == "geometry" else 1) and len(materials) == 1
    np.testing.assert_allclose(r.arrays.radius, 0.2, rtol=1e-5)
    centers = sorted(map(tuple, np.round(r.arrays.center[r.arrays.center[:, 2] > 0], 5)))
    assert centers == sorted((x, y, 1.0) for x, y, _ in points)
    assert r.lens_candidates.all() and len(set(r.sphere_sources)) == n
    # read again: the meshes did not change, their fits are remembered (no new fit)
    again = scene_reader.read_blender_scene(bpy.context)
    assert len(fits) == (2 if kind == "geometry" else 1)
    np.testing.assert_array_equal(again.arrays.radius, r.arrays.radius)


def test_preselection_makes_few_python_objects(empty_blend, monkeypatch):
    """200 lenses × 2 lights = 400 sources, at most 8 lights: only the 4 × 8 = 32
    strongest by flux become `SecondarySource` objects; the report counts the rest
    by reason and gives the flux without a light."""
    from lens_lights.blender.commands import pipeline
    from lens_lights.core.phase1.point_lights import SourceTable

    glass = glass_material()
    floor()
    gn_instances("Beads", grid(200, spacing=1.2), radius=0.2, material=glass, location=(-8, -8, 1))
    add_point_light("Lamp A", (0.0, 0.0, 10.0))
    add_point_light("Lamp B", (-3.0, 2.0, 8.0), energy=500.0)
    bpy.context.scene.lens_lights.max_lights = 8
    made = count_calls(monkeypatch, SourceTable, "source")
    works = []
    real_plan = pipeline.plan_scene
    monkeypatch.setattr(
        pipeline, "plan_scene", lambda *a, **k: works.append(real_plan(*a, **k)) or works[-1]
    )
    level, message, figures = generate()
    (work,) = works
    assert figures["sources"] == 400 and figures["created"] == 8 == len(lens_lights())
    assert len(made) == 32 and work.result._sources is None  # never all 400
    by = figures["skipped_by_reason"]
    assert by["not among the 32 strongest by flux"] == 368
    assert by["beyond the maximum of 8 lens lights"] == 24
    assert figures["skipped"] == 392
    assert (
        "by reason: 368 not among the 32 strongest by flux, 24 beyond the maximum of 8" in message
    )
    # flux without a light = 1 − (flux of the 8 built) / (flux of all 400)
    from lens_lights.core.plan.budget import source_flux

    flux = source_flux(work.result.table, work.read.arrays.light_brightness)
    built = {(ll.lens_lights.source_light, ll.lens_lights.source_lens) for ll in lens_lights()}
    t = work.result.table
    mask = np.array(
        [
            (work.read.light_sources[j], work.read.sphere_sources[i]) in built
            for j, i in zip(t.light, t.lens, strict=False)
        ]
    )
    want = 1.0 - flux[mask].sum() / flux.sum()
    assert figures["flux_left_out"] == pytest.approx(want, rel=1e-9)
    assert f"{100 * want:.3g} % of the lenses' flux has no lens light" in message
    # the lights are the brightest of the pre-selected, brightest first
    irr = [p.light.reference_irradiance for p in work.plan.lights]
    assert irr == sorted(irr, reverse=True)


def test_preselection_keeps_the_strongest_by_flux(empty_blend):
    """The pre-selection ranks by estimated flux (power × the share of it the lens
    catches): of a near small lens and a far big one, the one catching more."""
    glass = glass_material()
    floor()
    add_point_light("Lamp", (0.0, 0.0, 10.0))
    # caught share ≈ (R/D)²/4: big far 1.5/8 beats small near 0.1/3
    add_sphere("Big far", (0, 6.0, 4.7), radius=1.5, material=glass)
    add_sphere("Small near", (0, 0, 7.0), radius=0.1, material=glass)
    s = bpy.context.scene.lens_lights
    s.max_lights = 1
    from lens_lights.blender.commands import pipeline

    pipeline.PRESELECT_FACTOR, old = 1, pipeline.PRESELECT_FACTOR
    try:
        level, message, figures = generate()
    finally:
        pipeline.PRESELECT_FACTOR = old
    (ll,) = lens_lights()
    assert ll.lens_lights.source_lens == "Big far"
    assert figures["skipped_by_reason"] == {"not among the 1 strongest by flux": 1}


def test_merging_nearby_sources(empty_blend):
    glass = glass_material()
    floor()
    for k in range(4):  # tiny droplets side by side: their images nearly coincide
        add_sphere(f"Drop {k}", (0.3 + 0.12 * k, 0.5, 2.5), radius=0.05, material=glass)
    add_point_light("Lamp", (0.45, 0.5, 9.0))
    s = bpy.context.scene.lens_lights
    level, message, figures = generate()
    singles = {ll.lens_lights.source_lens: ll.data.energy for ll in lens_lights()}
    assert len(singles) == 4 and figures["merged"] == 0
    s.use_merge, s.merge_distance = True, 1.0
    level, message, figures = generate()
    (ll,) = lens_lights()
    assert figures["merged"] == 3 and figures["created"] == 1 and figures["skipped"] == 0
    assert "merged 3 sources into nearby lens lights" in message
    assert ll.data.energy == pytest.approx(sum(singles.values()), rel=0.02)
    assert "merged: energy ×" in ll.lens_lights.note
    assert figures["flux_left_out"] == pytest.approx(0.0, abs=1e-12)
    # the merge distance is a scene setting, drawn in the panel
    from blender_scene_helpers import draw_panel
    from lens_lights.blender.ui.panel import VIEW3D_PT_lens_lights

    log = draw_panel(VIEW3D_PT_lens_lights, SimpleNamespace(scene=bpy.context.scene, object=None))
    assert ("prop", "use_merge") in log and ("prop", "merge_distance") in log


def test_select_sources_without_a_cap_keeps_everything(empty_blend):
    from lens_lights.core.phase1.point_lights import compute_phase1
    from lens_lights.core.plan.planning import select_sources
    from lens_lights.core.scene.arrays import SceneArrays

    d = np.array([3.0, 6.0, 12.0])
    ang = np.radians(25.0) * np.arange(3)
    centers = np.stack([d * np.cos(ang), d * np.sin(ang), np.zeros(3)], 1)
    a = SceneArrays(
        np.zeros((1, 3)),
        np.ones(1),
        np.ones((1, 3)),
        centers,
        np.full(3, 0.5),
        np.full(3, 1.5),
        np.full(3, 1.0),
    )
    result = compute_phase1(a)
    sel = select_sources(result, [100.0], max_lights=None)
    assert len(sel.sources) == 3 and sel.budget.over_cap == 0 and sel.preselect is None
    np.testing.assert_allclose(sel.flux_kept.sum(), sel.flux_total, rtol=1e-12)
    sel = select_sources(result, [100.0], max_lights=0)  # at least one light
    assert len(sel.sources) == 3 and sel.preselect == 4


def test_many_instances_are_all_read(empty_blend):
    """2 000 geometry-node instances × 2 lights: every instance is a lens, and the 64
    lights kept are the cap (their speed is bench/operator_scale.py's, not a test's)."""
    glass = glass_material()
    floor(100)
    gn_instances(
        "Beads", grid(2000, spacing=1.0), radius=0.3, material=glass, location=(-22, -22, 1)
    )
    add_point_light("Lamp A", (5.0, 5.0, 12.0))
    add_point_light("Lamp B", (-5.0, 0.0, 9.0))
    level, message, figures = generate()
    assert figures["lenses"] == 2000 and figures["created"] == 64
    made = {(ob.lens_lights.source_light, ob.lens_lights.source_lens) for ob in lens_lights()}
    assert len(made) == 64  # 64 distinct (light, instance) pairs


def test_generate_on_empties_renders_no_probe_and_updates_the_depsgraph_once(
    empty_blend, monkeypatch
):
    """300 collection-instance empties, nothing set apart for the render: Generate
    reads the viewport depsgraph (no probe render), and the operator with its undo
    step makes one depsgraph update (the lights added in one go, nothing evaluated
    inside), whose read is the probe's."""
    from lens_lights.blender.read import render_probe

    glass = glass_material()
    floor(40)
    bead = add_sphere("Bead", (0, 0, 0), radius=0.3, material=glass)
    beads = collection_of("Bead", bead)
    for k, (x, y, _z) in enumerate(grid(300, spacing=1.0)):
        collection_instance(f"Beads.{k:03d}", beads, location=(x - 8, y - 8, 1))
    add_point_light("Lamp A", (3.0, 2.0, 12.0))
    add_point_light("Lamp B", (-2.5, -1.0, 9.0))
    bpy.context.view_layer.update()
    bpy.ops.ed.undo_push(message="scene")
    probes = count_calls(monkeypatch, render_probe, "_probe")
    updates = []

    def note(scene, depsgraph=None):
        updates.append(scene.name)

    bpy.app.handlers.depsgraph_update_post.append(note)
    try:
        assert bpy.ops.lens_lights.generate("EXEC_DEFAULT", True) == {"FINISHED"}
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(note)
    from lens_lights.blender.commands import generate as gen

    figures = gen.LAST_FIGURES
    assert figures["how"] == render_probe.VIEWPORT_AS_RENDER and probes == []
    assert updates == [bpy.context.scene.name]
    assert figures["lenses"] == 300 and figures["created"] == 64 == len(lens_lights())
    # the same read through the probe render: the same lenses and lights
    from lens_lights.blender.read.scene import read_blender_scene, read_depsgraph

    fast = read_blender_scene(bpy.context)
    probed, how = render_probe.rendered_depsgraph(
        bpy.context, lambda dg: read_depsgraph(dg, bpy.context.scene)
    )
    assert how == "render" and fast.how == render_probe.VIEWPORT_AS_RENDER
    assert fast.sphere_sources == probed.sphere_sources
    assert fast.light_sources == probed.light_sources == ["Lamp A", "Lamp B"]
    np.testing.assert_array_equal(fast.arrays.center, probed.arrays.center)


def test_occluders_match_brute_force_and_blender():
    """Rays against 2 000 random spheres: the same first hits as a plain loop; a
    rotated, scaled plane (box test, then BVH) as `Scene.ray_cast` sees it."""
    from lens_lights.blender.read.occluders import MeshSource, Occluders

    rng = np.random.default_rng(3)
    C = rng.uniform(-20, 20, (2000, 3)) + 1e5  # far from the world origin
    R = rng.uniform(0.05, 1.0, 2000)
    occ = Occluders(C, R, np.zeros((0, 4, 4)), np.zeros((0, 3)), np.zeros((0, 3)), [], [])
    for _ in range(20):
        o0 = rng.uniform(-20, 20, 3) + 1e5
        origins = o0 + rng.uniform(-0.5, 0.5, (5, 3))
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        want = []
        for o in origins:
            oc = C - o
            b = oc @ d
            disc = b * b - ((oc * oc).sum(1) - R**2)
            with np.errstate(invalid="ignore"):
                t = np.where(
                    b - np.sqrt(disc) > 0,
                    b - np.sqrt(disc),
                    np.where(b + np.sqrt(disc) > 0, b + np.sqrt(disc), np.inf),
                )
            want.append(np.where(disc >= 0, t, np.inf).min())
        got = occ.first_hit(origins, d, 1e9)
        np.testing.assert_allclose(got, np.where(np.array(want) <= 1e9, want, np.inf), rtol=1e-9)
    # A 2 × 2 plane turned 30° about x, scaled 3, centred at (0, 0, 5).
    from mathutils import Matrix

    m = np.array(
        Matrix.Translation((0, 0, 5))
        @ Matrix.Rotation(math.radians(30), 4, "X")
        @ Matrix.Scale(3, 4)
    )
    verts = np.array([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], float)
    tris = np.array([(0, 1, 2), (0, 2, 3)])
    w = verts @ m[:3, :3].T + m[:3, 3]
    occ = Occluders(
        np.zeros((0, 3)),
        np.zeros(0),
        m[None],
        w.min(0)[None],
        w.max(0)[None],
        [0],
        [MeshSource(arrays=(verts, tris))],
    )
    hits = occ.first_hit([(0, 0, 0), (0.5, 0.2, 0), (10, 0, 0)], (0, 0, 1), 100.0)
    # the plane z' = 0 in world: z = 5 + y·tan 30°
    assert hits[0] == pytest.approx(5.0, rel=1e-6)  # the BVH is single precision
    assert hits[1] == pytest.approx(5.0 + 0.2 * math.tan(math.radians(30)), rel=1e-6)
    assert hits[2] == math.inf
    assert occ.first_hit([(0, 0, 0)], (0, 0, 1), 4.0)[0] == math.inf  # beyond the limit
