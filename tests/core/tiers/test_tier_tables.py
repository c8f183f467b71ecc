"""Tier lights for a whole source table (`tiers.make_light_table`, each tier's
``make_table``) against the per-source makers (`tiers.make_blender_light`): every
field of every light, on the thesis' scenes and random ones with all kinds of
source, other primaries' emission and radius; plus hand values for one source."""

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from random_scenes import random_scene

from core.bi.format import read_bi
from core.lens.glass import LensOptics
from core.phase1.point_lights import compute_phase1
from core.scene.arrays import SceneArrays
from core.scene.model import Light, Scene, Sphere, Surface
from core.scene.primaries import PrimaryLight
from core.tiers import BlenderLight, Primaries, make_blender_light, make_light_table

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "scripts"))
from cli import bi_scene_light_table, blender_lights  # noqa: E402

MODELS = ("THESIS", "PHYSICAL", "FITTED", "EXACT_PROFILE")
#: numpy's tan/exp/arctan2 may differ from math's in the last bit.
RTOL = 1e-9


def scenes():
    yield "fig1", read_bi(ROOT / "examples" / "fig1.bi")
    yield "fig3", read_bi(ROOT / "examples" / "fig3.bi")
    for seed in range(3):
        yield f"random{seed}", random_scene(seed)
    yield "far", random_scene(7, n_lights=2, n_spheres=10, spread=500.0)


def assert_same_light(got: BlenderLight, want: BlenderLight, where: str):
    assert type(got) is type(want), where
    for f in dataclasses.fields(want):
        if f.name.startswith("_"):
            continue
        a, b = getattr(got, f.name), getattr(want, f.name)
        if isinstance(b, float):
            assert a == pytest.approx(b, rel=RTOL, abs=1e-300, nan_ok=True), (where, f.name)
        elif isinstance(b, tuple):
            assert a == pytest.approx(b, rel=RTOL, abs=1e-12), (where, f.name)
        elif isinstance(b, dict):
            assert a == pytest.approx(b, rel=RTOL), (where, f.name)
        else:
            assert a == b, (where, f.name)


@pytest.mark.parametrize("model", MODELS)
def test_every_field_equals_the_per_source_maker(model):
    checked = 0
    for name, scene in scenes():
        result = compute_phase1(scene)
        want = blender_lights(scene, result, model.lower())
        radius = np.array([lt.radius for lt in scene.lights])
        table = bi_scene_light_table(SceneArrays.from_scene(scene), result.table, model, radius)
        assert len(table) == len(want)
        for t, w in enumerate(want):
            assert_same_light(table.light(t), w, f"{name} source {t}")
            assert table.light(t).to_json().keys() == w.to_json().keys()
        checked += len(want)
    assert checked > 100


def test_all_kinds_and_notes_are_covered():
    kinds, notes = set(), set()
    for _, scene in scenes():
        result = compute_phase1(scene)
        for model in MODELS:
            table = bi_scene_light_table(SceneArrays.from_scene(scene), result.table, model)
            kinds |= {table.light(t).kind for t in range(len(table))}
            notes |= {
                part.split(" ")[0]
                for t in range(len(table))
                for part in table.note(t).split("; ")
                if part
            }
    assert kinds == {"real", "virtual", "collimated"}
    assert {"non-full:", "collimated", "spot", "Cycles", "virtual"} <= notes


def test_optics_tint_and_absorption_follow_physical():
    scene = random_scene(3)
    result = compute_phase1(scene)
    n = len(result.table)
    rng = np.random.default_rng(0)
    tint, absorption = rng.uniform(-0.2, 1.2, (n, 3)), rng.uniform(-0.1, 0.5, (n, 3))
    primaries = Primaries(
        power_w=np.full(n, 900.0),
        radius=np.full(n, 0.05),
        color=np.tile([0.2, 0.7, 1.0], (n, 1)),
        transmission_weight=rng.uniform(-0.1, 1.1, n),
        tint=tint,
        absorption=absorption,
    )
    for model in MODELS:
        table = make_light_table(
            result.table,
            primaries,
            model,
            scene_size=30.0,
            scene_bounds=((-15.0,) * 3, (15.0,) * 3),
        )
        for t, s in enumerate(result.sources):
            want = make_blender_light(
                s,
                PrimaryLight(900.0, 0.05, (0.2, 0.7, 1.0)),
                model,
                optics=LensOptics(
                    float(primaries.transmission_weight[t]),
                    tuple(tint[t].tolist()),
                    tuple(absorption[t].tolist()),
                ),
                scene_size=30.0,
                scene_bounds=((-15.0,) * 3, (15.0,) * 3),
            )
            assert_same_light(table.light(t), want, f"{model} {t}")


def test_hand_values_of_one_thesis_source():
    # Light at the origin, brightness 1 (10 000 W), lens n = 1.5, R = 1 at D = 10 on +x.
    # An opaque sphere off the axis makes the scene reach beyond the image.
    scene = Scene(
        lights=[Light(position=(0.0, 0.0, 0.0))],
        objects=[
            Sphere(center=(10.0, 0.0, 0.0), radius=1.0, surface=Surface(transmission=1.0, ior=1.5)),
            Sphere(center=(30.0, 8.0, 0.0), radius=1.0),
        ],
    )
    result = compute_phase1(scene)
    lt = bi_scene_light_table(SceneArrays.from_scene(scene), result.table, "thesis").light(0)
    # P = 2(n − 1)/(nR) = 2/3, V = P − 1/D = 17/30: real image 30/17 beyond the centre.
    assert lt.location == pytest.approx((10.0 + 30.0 / 17.0, 0.0, 0.0))
    assert lt.direction == (1.0, 0.0, 0.0)
    # THESIS: I = P/(4π) × exp(−(1 − kt)…) = P/(4π): energy = 10 000 W.
    assert lt.energy_w == pytest.approx(10_000.0)
    # Image radius 0: the point light has radius 0; R_T-free cone θ from SPEC §3.3.
    assert lt.radius == 0.0
    assert lt.reference_irradiance == pytest.approx(10_000.0 / (4 * math.pi) / (30 / 17) ** 2)
    assert lt.spot_size_deg == pytest.approx(2.0 * result.sources[0].spread_deg)


def test_other_primaries_emission_and_source_radius_as_per_source():
    """Sources of spot, sun and area lights carry `emission` and `source_radius`:
    the table makes the same effective primary as `make_blender_light`."""
    import dataclasses as dc

    scene = random_scene(4)
    result = compute_phase1(scene)
    n = len(result.table)
    rng = np.random.default_rng(1)
    emission = rng.uniform(0.0, 3.0, n)
    source_radius = np.where(rng.uniform(size=n) < 0.5, np.nan, rng.uniform(0.0, 0.3, n))
    table = dc.replace(result.table, emission=emission, source_radius=source_radius)
    primaries = Primaries(
        power_w=np.full(n, 500.0),
        radius=np.full(n, 0.1),
        color=np.ones((n, 3)),
        transmission_weight=np.ones(n),
    )
    for model in MODELS:
        lights = make_light_table(table, primaries, model, scene_size=20.0)
        for t in range(n):
            want = make_blender_light(
                table.source(t), PrimaryLight(500.0, 0.1), model, scene_size=20.0
            )
            assert_same_light(lights.light(t), want, f"{model} {t}")


def test_hand_values_of_the_lens_light_radius_and_emission():
    # Light of radius 0.1 at the origin, lens n = 1.5, R = 1 at D = 10 on +x: real
    # image at 1/V = 30/17 from the centre. FITTED: blur z·r/D with z = min(1/V, S).
    scene = Scene(
        lights=[Light(position=(0.0, 0.0, 0.0), radius=0.1)],
        objects=[
            Sphere(center=(10.0, 0.0, 0.0), radius=1.0, surface=Surface(transmission=1.0, ior=1.5))
        ],
    )
    result = compute_phase1(scene)
    import dataclasses as dc

    table = dc.replace(result.table, emission=np.array([0.25]), source_radius=np.array([0.2]))
    p = Primaries(
        power_w=np.array([1000.0]),
        radius=np.array([0.1]),
        color=np.ones((1, 3)),
        transmission_weight=np.ones(1),
    )
    plain = make_light_table(result.table, p, "FITTED", scene_size=100.0).light(0)
    assert plain.radius == pytest.approx(0.1 * (30.0 / 17.0) / 10.0)
    small = make_light_table(result.table, p, "FITTED", scene_size=1.5).light(0)
    assert small.radius == pytest.approx(0.1 * 1.5 / 10.0)
    # emission 1/4: a quarter of the energy; the source's radius 0.2 instead of 0.1
    other = make_light_table(table, p, "FITTED", scene_size=100.0).light(0)
    assert other.energy_w == pytest.approx(0.25 * plain.energy_w)
    assert other.radius == pytest.approx(2.0 * plain.radius)
    # THESIS cone at the image: the image's radius |m|·r, m = −(1/V)/D
    cone = make_light_table(result.table, p, "THESIS", scene_size=100.0).light(0)
    assert cone.radius == pytest.approx(0.1 * (30.0 / 17.0) / 10.0)
    assert not cone.inside_lens and not plain.inside_lens


@pytest.mark.parametrize("model", ["FITTED", "CAUSTIC_LAYER"])
def test_a_table_without_near_field_fits_keeps_the_far_spot_and_the_receivers_blur(model):
    # Light of radius 0.1 at D = 10 from a lens (n = 1.5, R = 1); a receiver 1.2 from
    # the lens centre (a resting marble's table): the near field. ``near_fits=False``
    # (live update's coarse Caustic layer) gives the spot of no receiver, with the
    # blur z·r/D of the receiver's z = 1.2 (SPEC §10).
    from core.tiers import TIERS

    scene = Scene(
        lights=[Light(position=(0.0, 0.0, 0.0), radius=0.1)],
        objects=[
            Sphere(center=(10.0, 0.0, 0.0), radius=1.0, surface=Surface(transmission=1.0, ior=1.5))
        ],
    )
    table = compute_phase1(scene).table
    p = Primaries(
        power_w=np.array([1000.0]),
        radius=np.array([0.1]),
        color=np.ones((1, 3)),
        transmission_weight=np.ones(1),
    )
    make = TIERS[model].make_table
    far = make(table, p, scene_size=100.0).light(0)
    fitted = make(table, p, scene_size=100.0, receiver_distance=np.array([1.2])).light(0)
    coarse = make(
        table, p, scene_size=100.0, receiver_distance=np.array([1.2]), near_fits=False
    ).light(0)
    assert "near field" in fitted.note and "near field" not in coarse.note
    assert fitted.location != pytest.approx(far.location)  # the fit moved the spot
    for name in ("location", "energy_w", "spot_size_deg", "spot_blend", "cone_half_angle_deg"):
        assert getattr(coarse, name) == pytest.approx(getattr(far, name), rel=RTOL), name
    assert coarse.radius == pytest.approx(0.1 * 1.2 / 10.0) == pytest.approx(fitted.radius)
