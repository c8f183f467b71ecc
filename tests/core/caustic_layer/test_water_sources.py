"""The water's (light, water) pairs (`core.caustic_layer.water_sources`): each
Blender light type as its own emitter (a sun stays parallel), the water's tint and
transmission weight on it, lights under the water left out; the rays a camera's
pixel asks for; and the bake's flux for a spot and an area light over flat water
against closed forms worked out here."""

import math

import numpy as np
import pytest
from glass_meshes import unpolarised_t

from core.caustic_layer.emitters import AreaLight, PointLight, SpotLight, SunLight
from core.caustic_layer.receiver_bvh import ReceiverMesh
from core.caustic_layer.water_sources import (
    MAX_WATER_RAYS,
    MIN_WATER_RAYS,
    emitter_of,
    rays_for,
    surface_of,
    water_bake,
    water_sources,
)
from core.lens.glass import MaterialOptics
from core.scene.primaries import AreaPrimary, PointPrimary, SpotPrimary, SunPrimary
from core.scene.water import water_read, water_reason, water_text
from reference.water_tracer import layer_on_bins

N = 1.333


def _t(theta):
    return unpolarised_t(theta, 1.0, N)


def _water(half=1.0, n=4, z=0.0, optics=None):
    xs = np.linspace(-half, half, n + 1)
    gx, gy = np.meshgrid(xs, xs)
    v = np.stack([gx, gy, np.full_like(gx, z)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).reshape(-1)
    t = np.concatenate([np.stack([a, a + 1, a + n + 2], 1), np.stack([a, a + n + 2, a + n + 1], 1)])
    cn = np.broadcast_to([0.0, 0.0, 1.0], (len(t), 3, 3))
    return water_read("Pool", None, v, t, cn, optics or MaterialOptics(ior=N, transmission=1.0))


def _floor(z, half=20.0):
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]])
    return ReceiverMesh(v, np.array([[0, 1, 2], [0, 2, 3]]))


def test_water_like_materials():
    assert water_reason(MaterialOptics(ior=1.333, transmission=1.0)) == ""
    assert water_reason(MaterialOptics(ior=1.33, transmission=0.5)) == ""
    assert "not water's" in water_reason(MaterialOptics(ior=1.5, transmission=1.0))
    assert "does not refract" in water_reason(MaterialOptics(ior=1.33, transmission=0.0))
    assert "thin wall" in water_reason(MaterialOptics(ior=1.33, transmission=1.0, thin_wall=1.0))


def test_one_crossing_tint_and_weight():
    """Glass's path tint is of two crossings (colour²): water's one crossing is its
    square root; a Transmission Weight of 0.6 passes 0.6 of the light, once."""
    w = _water(optics=MaterialOptics(ior=N, transmission=0.6, tint=(0.64, 0.81, 1.0)))
    np.testing.assert_allclose(w.tint, (0.8, 0.9, 1.0))
    sun = SunPrimary((0.0, 0.0, -1.0), 4.0, 0.01, (1.0, 0.5, 1.0))
    e = emitter_of(sun, w.tint, w.transmission_weight)
    assert isinstance(e, SunLight) and e.strength == pytest.approx(2.4) and e.angle == 0.01
    np.testing.assert_allclose(e.color, (0.8, 0.45, 1.0))


def test_every_light_type_and_what_is_left_out():
    w = _water()
    lights = [
        PointPrimary((0.0, 0.0, 2.0), 100.0),
        SpotPrimary((0.0, 0.0, 2.0), (0.0, 0.0, -1.0), 100.0, 1.0),
        SunPrimary((0.3, 0.0, -1.0), 2.0),
        AreaPrimary((0.0, 0.0, 2.0), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0), 50.0),
        PointPrimary((0.0, 0.0, -1.0), 100.0),  # under the water
        SunPrimary((0.0, 0.0, 1.0), 2.0),  # shining up
    ]
    sources, pairs, left = water_sources(lights, [w])
    kinds = [type(s.emitter) for s in sources]
    assert kinds == [PointLight, SpotLight, SunLight, AreaLight]
    assert pairs == [(0, 0), (1, 0), (2, 0), (3, 0)]
    assert [(j, k) for j, k, _why in left] == [(4, 0), (5, 0)]
    assert all("not above the water" in why for *_p, why in left)


def test_rays_follow_the_pixel():
    s = surface_of(_water(half=1.0))  # 2 × 2 m
    assert rays_for(s, 0.01) == int(4.0 * (2.0 / 0.01) ** 2)  # 2 rays per pixel side
    assert rays_for(s, 1.0) == MIN_WATER_RAYS
    assert rays_for(s, 1e-5) == MAX_WATER_RAYS


def test_spot_over_flat_water_lands_its_cone():
    """A spot (cone 60°, no blend) 1 m over flat water wider than its cone: the flux in
    the water is (P/4π) ∫₀^30° T(θ) 2π sin θ dθ, over n² (the cone's edge dimmed by
    the blend's default 0.15 aside: blend 0 here)."""
    power = 200.0
    spot = SpotPrimary((0.0, 0.0, 1.0), (0.0, 0.0, -1.0), power, math.radians(60.0), 0.0)
    sources, _, _ = water_sources([spot], [_water(half=2.0)])
    bake = water_bake(sources, _floor(-0.5), n_rays=300 * 300, resolution=128)
    th = (np.arange(4000) + 0.5) / 4000 * math.radians(30.0)
    flux = sum(_t(a) * math.sin(a) for a in th) * 2 * math.pi * math.radians(30.0) / 4000
    expect = power / (4 * math.pi) * flux / N**2
    assert bake.layer.flux_in_rasters + bake.layer.flux_outside == pytest.approx(expect, rel=0.01)


def test_report_words():
    assert water_text([("Pool", 20000, ["Floor", "Wall"])], ["Pond"]) == (
        "water: Pool (20\u2009000 triangles) over Floor, Wall; no light above the water of Pond"
    )


def test_a_sun_with_an_angle_blurs_the_edge_of_the_waters_light():
    """A sun overhead with a 10° disc over a 1 m square of flat water, floor 1 m down:
    the light's edge under the water's edge (x = 0.5) is blurred over ±D·tan θ_w,
    sin θ_w = sin 5°/n (6.5 cm): half the interior at the edge (the disc's samples
    are symmetric), all of it 8 cm inside, none 8 cm outside."""
    sun = SunPrimary((0.0, 0.0, -1.0), 2.0, math.radians(10.0))
    sources, _, _ = water_sources([sun], [_water(half=0.5, n=8)], n_source=16)
    assert sources[0].n_source == 16
    bake = water_bake(sources, _floor(-1.0, half=3.0), n_rays=16 * 100 * 100, resolution=256)
    (patch,) = bake.layer.patches

    def mean_at(x, w=0.01):  # the layer's mean over x ± w, |y| < 0.2
        return float(layer_on_bins(patch, [x - w, x + w], [-0.2, 0.2])[0, 0])

    inner = mean_at(0.0, 0.1)
    assert inner == pytest.approx(2.0 * _t(0.0) / N**2, rel=0.02)
    assert mean_at(0.5) == pytest.approx(0.5 * inner, rel=0.1)
    assert mean_at(0.42) == pytest.approx(inner, rel=0.03)
    assert mean_at(0.58) < 0.02 * inner
