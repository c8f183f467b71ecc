"""Issue 26 in Blender: Generate takes an open glass mesh with water's IOR as a water
surface and lays its caustic on the floor under it (EEVEE and Cycles), reading the
evaluated mesh (a Subdivision modifier's triangles); the report names the water and
the receivers under it; open glass that is not water-like stays left out as before.

The flux is checked against the closed form for flat water under a sun (zenith angle
θ, strength S, water area A, floor far beyond): S·cos θ·A·T(θ)/n², T the unpolarised
Fresnel transmittance computed here from the amplitude coefficients, 1/n² the
brightness Cycles renders under water (SPEC §9).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender

bpy = pytest.importorskip("bpy")

from blender_scene_helpers import (  # noqa: E402
    add_point_light,
    caustic_layers,
    generate,
    glass_material,
    layer_flux,
    layer_triangle_flux,
    set_engine,
)
from glass_meshes import unpolarised_t  # noqa: E402

N, STRENGTH, ZENITH, HALF = 1.333, 3.0, math.radians(30.0), 1.0


def _t(theta):
    return unpolarised_t(theta, 1.0, N)


def pool(ior=N, subdivide=False):
    bpy.ops.mesh.primitive_plane_add(size=20.0, location=(0.0, 0.0, 0.0))
    bpy.context.object.name = "Floor"
    bpy.ops.mesh.primitive_grid_add(
        x_subdivisions=8, y_subdivisions=8, size=2.0 * HALF, location=(0.0, 0.0, 0.8)
    )
    water = bpy.context.object
    water.name = "Water"
    water.data.materials.append(glass_material("Water", ior=ior))
    if subdivide:
        sub = water.modifiers.new("Subdivision", "SUBSURF")
        sub.levels = sub.render_levels = 1
    sun = add_point_light("Sun", (0.0, 0.0, 5.0), energy=STRENGTH, kind="SUN")
    sun.rotation_euler = (0.0, -ZENITH, 0.0)  # travels toward +x, 30° off the vertical
    bpy.ops.object.camera_add(location=(0.0, -5.0, 6.0), rotation=(math.radians(40.0), 0.0, 0.0))
    bpy.context.scene.camera = bpy.context.object
    bpy.context.scene.render.resolution_x = bpy.context.scene.render.resolution_y = 64
    return water


@pytest.mark.parametrize("engine", ["BLENDER_EEVEE", "CYCLES"])
def test_flat_water_lays_its_light_on_the_floor(empty_blend, engine):
    water = pool(subdivide=True)
    set_engine(engine)
    level, message, _ = generate()
    assert level == "INFO", message
    assert "(1 light × 1 lens)" in message  # the water counts as a lens
    # the evaluated mesh: each quad subdivided once into four, two triangles each
    tris = f"{8 * len(water.data.polygons):,}".replace(",", "\u2009")
    assert f"water: Water ({tris} triangles) over Floor" in message
    assert "open mesh" not in message
    obs = caustic_layers()
    assert obs and all("Floor" in o.lens_lights.receiver for o in obs)
    expect = STRENGTH * math.cos(ZENITH) * (2 * HALF) ** 2 * _t(ZENITH) / N**2
    assert sum(layer_flux(o) for o in obs) == pytest.approx(expect, rel=0.02)
    if engine == "CYCLES":  # the water's caustic is the layer's now: Cycles' is off
        assert not bpy.context.scene.cycles.caustics_refractive


def test_open_glass_that_is_not_water_stays_left_out(empty_blend):
    pool(ior=1.5)
    set_engine("CYCLES")
    level, message, _ = generate()
    assert "water:" not in message
    assert "Water (open mesh" in message
    assert not caustic_layers()


def channel_flux(ob):
    """(R, G, B) of the irradiance drawn, integrated over the layer mesh."""
    return layer_triangle_flux(ob).sum(axis=0)


def test_volume_absorption_tints_the_light_by_depth(empty_blend):
    """Volume Absorption (colour (0.5, 0.8, 1), density 1: σ = (0.5, 0.2, 0) per metre)
    under a sun overhead, floor 0.8 m below the water: R/B = exp(−0.4), G/B = exp(−0.16)."""
    water = pool()
    mat = water.data.materials[0]
    nt = mat.node_tree
    vol = nt.nodes.new("ShaderNodeVolumeAbsorption")
    vol.inputs["Color"].default_value = (0.5, 0.8, 1.0, 1.0)
    vol.inputs["Density"].default_value = 1.0
    nt.links.new(vol.outputs[0], nt.nodes["Material Output"].inputs["Volume"])
    bpy.data.objects["Sun"].rotation_euler = (0.0, 0.0, 0.0)  # straight down
    set_engine("BLENDER_EEVEE")
    level, message, _ = generate()
    assert level == "INFO", message
    r, g, b = sum(channel_flux(o) for o in caustic_layers())
    assert r / b == pytest.approx(math.exp(-0.4), rel=0.01)
    assert g / b == pytest.approx(math.exp(-0.16), rel=0.01)
    expect = STRENGTH * (2 * HALF) ** 2 * _t(0.0) / N**2  # the blue channel: no absorption
    assert b == pytest.approx(expect, rel=0.02)


def test_an_ocean_modifier_pool(empty_blend):
    """A plane with an Ocean modifier (its own grid, waves and choppiness) over a floor:
    read as it renders, named with its receivers, and all the light into it lands:
    S·cos θ·A·T(θ)/n² within 3 % (A: the evaluated surface's area seen from above, its
    triangles' projected areas summed here; the waves' slopes move T a little)."""
    bpy.ops.mesh.primitive_plane_add(size=20.0, location=(0.0, 0.0, 0.0))
    bpy.context.object.name = "Floor"
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0.0, 0.0, 0.8))
    sea = bpy.context.object
    sea.name = "Sea"
    sea.data.materials.append(glass_material("Water", ior=N))
    ocean = sea.modifiers.new("Ocean", "OCEAN")
    ocean.geometry_mode = "GENERATE"
    ocean.resolution = ocean.viewport_resolution = 4  # the render reads the first
    ocean.spatial_size = 2
    ocean.size = 1.0
    ocean.wave_scale = 0.05
    ocean.choppiness = 0.5
    sun = add_point_light("Sun", (0.0, 0.0, 5.0), energy=STRENGTH, kind="SUN")
    sun.rotation_euler = (0.0, -ZENITH, 0.0)
    bpy.ops.object.camera_add(location=(0.0, -5.0, 6.0), rotation=(math.radians(40.0), 0.0, 0.0))
    bpy.context.scene.camera = bpy.context.object
    bpy.context.scene.render.resolution_x = bpy.context.scene.render.resolution_y = 64
    set_engine("BLENDER_EEVEE")
    dg = bpy.context.evaluated_depsgraph_get()
    me = sea.evaluated_get(dg).data
    co = np.empty(len(me.vertices) * 3)
    me.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    me.calc_loop_triangles()
    n_tris = len(me.loop_triangles)
    tri = np.empty(n_tris * 3, dtype=np.int64)
    me.loop_triangles.foreach_get("vertices", tri)
    c = co[tri.reshape(-1, 3)]
    e1, e2 = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]
    area = float(np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum() / 2.0)
    assert np.ptp(co[:, 2]) > 0.005  # there are waves
    level, message, _ = generate()
    assert level == "INFO", message
    tris = f"{n_tris:,}".replace(",", "\u2009")
    assert f"water: Sea ({tris} triangles) over Floor" in message
    expect = STRENGTH * math.cos(ZENITH) * area * _t(ZENITH) / N**2
    assert sum(layer_flux(o) for o in caustic_layers()) == pytest.approx(expect, rel=0.03)
