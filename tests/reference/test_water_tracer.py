"""The water reference (`reference/water_tracer.py`) on cases known in closed form:
flat water under the sun (S·cos θ·T(θ)·exp(−α·D/cos θ_t)/n² on the floor), the
height field's exact normals, and its meshing."""

import math

import numpy as np
import pytest

from reference.water_tracer import SineWaves, height_field_mesh, trace_floor

N = 1.333


def test_flat_water_under_the_sun():
    zen = math.radians(40.0)
    d = [math.sin(zen), 0.0, -math.cos(zen)]
    flat = SineWaves(0.0, (0.0,), ((1.0, 0.0),), (0.0,), (-0.5, 0.5, -0.5, 0.5))
    ex = np.linspace(0.0, 0.4, 3)
    ey = np.linspace(-0.2, 0.2, 3)
    r = trace_floor(flat, -0.5, ex, ey, ior=N, absorption=0.3, sun_direction=d,
                    sun_strength=3.0, n_rays=200_000)  # fmt: skip
    ci, st = math.cos(zen), math.sin(zen) / N
    ct = math.sqrt(1 - st * st)
    rs, rp = (ci - N * ct) / (ci + N * ct), (N * ci - ct) / (N * ci + ct)
    t = 1 - 0.5 * (rs * rs + rp * rp)
    expect = 3.0 * ci * t * math.exp(-0.3 * 0.5 / ct) / N**2
    np.testing.assert_allclose(r.irradiance, expect, rtol=0.03)
    assert r.flux == pytest.approx(expect, rel=0.01)  # the 1 m² surface, all landed


def test_sine_normals_and_mesh():
    w = SineWaves(0.1, (0.02,), ((3.0, 4.0),), (0.5,), (-1.0, 1.0, -1.0, 1.0))
    x, y = 0.3, -0.2
    e = 1e-6
    hx = (w.height(x + e, y) - w.height(x - e, y)) / (2 * e)
    hy = (w.height(x, y + e) - w.height(x, y - e)) / (2 * e)
    n = np.array([-hx, -hy, 1.0]) / math.sqrt(hx * hx + hy * hy + 1)
    np.testing.assert_allclose(w.normal(x, y), n, atol=1e-8)
    v, t, cn = height_field_mesh(w, 4, 3)
    assert v.shape == (20, 3) and t.shape == (24, 3) and cn.shape == (24, 3, 3)
    c = v[t]
    up = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])[:, 2]
    assert np.all(up > 0)  # counter-clockwise seen from above
