"""core.caustic_layer.plan: planned lens lights → caustic-sheet sources (pure)."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from core.caustic_layer.emitters import Lens
from core.caustic_layer.pipeline import Camera, SheetSource
from core.caustic_layer.plan import (
    FACE_BUDGET,
    MAX_RESOLUTION,
    fallback_reason,
    raster_resolution,
    sheet_camera,
    sheet_source,
)
from core.lens.glass import LensOptics
from core.scene.primaries import PrimaryLight


def planned(D=2.0, unblocked=1.0, emission=1.0):
    src = SimpleNamespace(
        light=0,
        lens=0,
        axis=np.array([0.0, 0.0, -2.0]),
        distance=D,
        lens_center=np.array([1.0, 2.0, 3.0]),
        lens_radius=0.5,
        ior=1.5,
        unblocked_fraction=unblocked,
        emission=emission,
        source_radius=math.nan,
    )
    return SimpleNamespace(source=src)


def test_the_emitter_sits_on_the_axis_with_the_lens_power_and_tint():
    p = planned(D=2.0, unblocked=0.5)
    s = sheet_source(
        p,
        PrimaryLight(1000.0, 0.0, (1.0, 0.5, 0.25)),
        LensOptics(transmission_weight=0.8, tint=(1.0, 1.0, 0.5)),
    )
    assert np.allclose(s.emitter.position, [1.0, 2.0, 5.0])  # centre − D·axis
    assert s.emitter.power == pytest.approx(1000.0 * 0.8**2 * 0.5)
    assert s.emitter.color == pytest.approx((1.0, 0.5, 0.125))
    assert s.lens.radius == 0.5 and s.lens.ior == 1.5 and s.n_source == 1
    extended = sheet_source(p, PrimaryLight(1000.0, 0.1))
    assert extended.emitter.radius == 0.1 and extended.n_source > 1


def test_glossy_and_transparent_receivers_fall_back():
    assert fallback_reason(0.0, 0.0, False) == ""
    assert fallback_reason(1.0, 0.0, False) == "glossy"
    assert fallback_reason(0.0, 0.0, True) == "glossy"
    assert fallback_reason(0.0, 1.0, False) == "transparent"


def test_an_orthographic_camera_gives_its_own_pixel():
    cam = SimpleNamespace(position=(0.0, 0.0, 10.0), fov_deg=(45.0, 45.0))
    c = sheet_camera(cam, 100, ortho_scale=2.0, targets=[(0.0, 0.0, 0.0)])
    assert 2 * 10 * math.tan(c.fov / 2) / 100 == pytest.approx(0.02)
    assert sheet_camera(cam, 100).fov == pytest.approx(math.radians(45))


def test_raster_resolution_within_the_caps():
    def src(r):
        return SheetSource(None, Lens(np.zeros(3), r, 1.5))

    near = Camera(np.array([0.0, 0.0, 1.0]), math.radians(45), 4000)
    assert raster_resolution([src(0.5)], near) == MAX_RESOLUTION
    many = [src(0.5)] * 64
    assert raster_resolution(many, near) ** 2 * 64 <= FACE_BUDGET
    far = Camera(np.array([0.0, 0.0, 1e4]), math.radians(45), 100)
    assert raster_resolution([src(0.5)], far) == 16
