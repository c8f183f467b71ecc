"""The `Lens` interface: the ball against the exact meridional optics of SPEC §6, and a
test-only kind (a glass disc with flat faces) that plugs into the caustic layer's beam
tracer by one registry line."""

import math

import numpy as np
import pytest

from core.caustic_layer.beam_trace import trace_beam
from core.caustic_layer.emitters import Lens as LensRecord
from core.caustic_layer.emitters import SunLight
from core.lens import ball_optics as bo
from core.lens import kinds
from core.lens.ball import BallLens
from core.lens.base import ExitRays, Lens
from core.lens.refraction import fresnel_from_cosines, refract


def _fan(D, R, psi):
    """Meridional rays from (0, 0, −D) at angles psi to the z axis (the y–z plane)."""
    d = np.stack([np.zeros_like(psi), np.sin(psi), np.cos(psi)], axis=1)
    return np.broadcast_to([0.0, 0.0, -D], d.shape), d


@pytest.mark.parametrize("D, R, n, a", [(5.0, 1.0, 1.5, 0.0), (3.0, 0.5, 1.8, 0.4)])
def test_ball_trace_is_the_exact_meridional_optics(D, R, n, a):
    alpha = bo.cone_half_angle(D, R)
    psi = np.linspace(0.0, 0.999 * alpha, 41)
    o, d = _fan(D, R, psi)
    out = BallLens(np.zeros(3), R, n, a).trace(o, d)
    fan = bo.trace_rays(psi, D, R, n, absorption=a)
    assert out.hit.all()
    # exit direction at theta_exit to the axis, toward it (positive: converging)
    theta = np.arctan2(-out.directions[:, 1], out.directions[:, 2])
    np.testing.assert_allclose(theta, fan.theta_exit, atol=1e-9)
    # exit point at polar angle exit_polar from the front pole (0, 0, −R)
    polar = np.arctan2(out.points[:, 1], -out.points[:, 2])
    np.testing.assert_allclose(np.unwrap(polar), fan.exit_polar, atol=1e-9)
    np.testing.assert_allclose(out.path, fan.chord, rtol=1e-9)
    np.testing.assert_allclose(out.weight, fan.transmission, rtol=1e-9, atol=1e-15)
    lens = BallLens(np.zeros(3), R, n, a)
    np.testing.assert_allclose(lens.incidence_transmission(fan.iota), fan.transmission)


def test_ball_intersect_and_bounding_sphere():
    lens = BallLens(np.array([1.0, 2.0, 3.0]), 2.0, 1.5)
    c, r = lens.bounding_sphere()
    assert np.array_equal(c, [1.0, 2.0, 3.0]) and float(r) == 2.0
    o = np.array([[1.0, 2.0, -7.0], [1.0, 2.0, 3.0], [9.0, 2.0, -7.0]])
    d = np.array([[0.0, 0.0, 1.0]] * 3)
    t, nrm = lens.intersect(o, d)
    np.testing.assert_array_equal(t, [8.0, 2.0, np.inf])  # outside, inside (far side), miss
    np.testing.assert_array_equal(nrm, [[0, 0, -1.0], [0, 0, 1.0], [0, 0, 0.0]])
    out = lens.trace(o[2:], d[2:])  # a miss goes on unchanged
    assert not out.hit[0] and out.weight[0] == 1.0 and np.array_equal(out.points, o[2:])
    assert BallLens.point_image and issubclass(BallLens, Lens)


@pytest.mark.parametrize("n", [1.5, 1.9])
def test_aimed_rim_rays_enter_at_the_tangent_point(n):
    """A tracer's grid rim ray is tangent by construction; its frames' rounding may put it
    a few 1e-12 R² outside (measured 1.5e-12 for a sun's samples in a real scene). Aimed,
    it enters at the tangent point and leaves turned by the grazing deviation
    π − 2 asin(1/n) (SPEC §6: 2(ι − r) at ι = 90°); not aimed, it is a miss."""
    R = 0.01
    b = R * math.sqrt(1.0 + 3e-12)  # the impact parameter, just outside
    o = np.array([[0.0, b, -4.0 * R]])
    d = np.array([[0.0, 0.0, 1.0]])
    lens = BallLens(np.zeros(3), R, n)
    assert not lens.trace(o, d).hit[0]
    out = lens.trace(o, d, aimed=True)
    assert out.hit[0]
    turned = math.acos(float(out.directions[0] @ d[0]))
    assert turned == pytest.approx(math.pi - 2.0 * math.asin(1.0 / n), abs=1e-5)


def test_registry_builds_the_ball_and_rejects_unknown_kinds():
    lens = kinds.make_lens("ball", np.zeros(3), 1.0, 1.5, 0.1)
    assert isinstance(lens, BallLens) and (lens.radius, lens.ior, lens.absorption) == (1, 1.5, 0.1)
    with pytest.raises(ValueError, match="unknown lens kind"):
        kinds.make_lens("prism", np.zeros(3), 1.0, 1.5)


class GlassDisc(Lens):
    """Test-only kind: a disc of glass (flat parallel faces) of ``radius``, ``thickness``
    along the unit ``axis`` (``params = (axis, thickness)``). Rays through both faces are
    shifted, not turned; rays meeting the rim are dropped."""

    point_image = False

    def __init__(self, center, radius, ior, absorption=0.0, axis=(0, 0, 1), thickness=0.2):
        self.center = np.asarray(center, dtype=float)
        self.radius, self.ior, self.absorption = float(radius), float(ior), float(absorption)
        self.axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        self.thickness = float(thickness)

    def bounding_sphere(self):
        return self.center, np.asarray(math.hypot(self.radius, 0.5 * self.thickness))

    def _face(self, origins, directions, side):
        """Distance to the face plane on ``side`` (±1) and whether it is within the disc."""
        along = directions @ self.axis
        h = (self.center - origins) @ self.axis + side * 0.5 * self.thickness
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(along != 0.0, h / np.where(along != 0.0, along, 1.0), np.inf)
        p = origins + np.where(np.isfinite(t), t, 0.0)[..., None] * directions
        lateral = (p - self.center) - ((p - self.center) @ self.axis)[..., None] * self.axis
        return t, p, np.linalg.norm(lateral, axis=-1) <= self.radius

    def intersect(self, origins, directions):
        best = np.full(directions.shape[:-1], np.inf)
        nrm = np.zeros(directions.shape)
        for side in (-1.0, 1.0):
            t, _, inside = self._face(origins, directions, side)
            take = inside & (t > 0.0) & (t < best)
            best = np.where(take, t, best)
            nrm = np.where(take[..., None], side * self.axis, nrm)
        return best, nrm

    def trace(self, origins, directions, aimed=False):  # a disc's faces: nothing grazes
        s = np.where(directions @ self.axis > 0.0, 1.0, -1.0)  # the face it leaves by
        t1, p1, in1 = self._face(origins, directions, -s)
        facing = -s[..., None] * self.axis  # against the ray on both faces
        inner = refract(directions, facing, 1.0 / self.ior)
        t2, p2, in2 = self._face(p1, inner.directions, s)
        outer = refract(inner.directions, facing, self.ior)
        ts1, tp1 = fresnel_from_cosines(inner.cos_i, inner.cos_t, 1.0, self.ior)
        ts2, tp2 = fresnel_from_cosines(outer.cos_i, outer.cos_t, self.ior, 1.0)
        w = 0.5 * (ts1 * ts2 + tp1 * tp2) * np.exp(-self.absorption * t2)
        hit = in1 & (t1 > 0.0)
        w = np.where(in2 & ~outer.tir, w, 0.0)  # through the rim: dropped
        return ExitRays(
            points=np.where(hit[..., None], p2, origins),
            directions=np.where(hit[..., None], outer.directions, directions),
            weight=np.where(hit, w, 1.0),
            hit=hit,
            path=np.where(hit, t2, 0.0),
        )


def test_a_new_kind_is_a_class_and_one_registry_line(monkeypatch):
    monkeypatch.setattr(kinds, "LENS_KINDS", {**kinds.LENS_KINDS, "disc": GlassDisc})
    axis, radius, thickness, n, S = np.array([0.0, 0.0, 1.0]), 1.0, 0.3, 1.5, 100.0
    center = np.array([1.0, -2.0, 0.5])
    sun = np.array([0.0, 0.0, 1.0])
    record = LensRecord(center, radius, n, kind="disc", params=(axis, thickness))
    beam = trace_beam(SunLight(sun, S), record, 64, 32)
    # a slab shifts the rays, never turns them
    np.testing.assert_allclose(
        beam.exit_dirs, np.broadcast_to(sun, beam.exit_dirs.shape), atol=1e-12
    )
    # rays through the disc leave by its back face
    back = (beam.exit_points - center) @ axis
    lateral = np.linalg.norm((beam.exit_points - center)[..., :2], axis=-1)
    through = lateral < radius * (1.0 - 1e-9)
    assert through.any()
    np.testing.assert_allclose(back[through], 0.5 * thickness, atol=1e-12)
    # flux: S × the face's area × two normal-incidence Fresnel transmissions (the grid
    # over the bounding sphere resolves the disc's edge to about a cell)
    t0 = 4.0 * n / (n + 1.0) ** 2
    assert beam.total_flux == pytest.approx(S * math.pi * radius**2 * t0 * t0, rel=0.02)
    # the ball's tracing is untouched by the new kind
    ball = trace_beam(SunLight(sun, S), LensRecord(center, radius, n), 16, 16)
    assert ball.total_flux > 0.0 and kinds.make_lens("disc", center, 1.0, n).point_image is False
