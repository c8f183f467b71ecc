"""Tier lights for a whole source table (addon/tier_tables.py) against the
per-source makers (`light_models.make_blender_light`, `lens_tiers`): every field
of every light, on the thesis' scenes and random ones with all kinds of source;
plus hand values for one source."""

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from addon.bi_format import read_bi
from addon.light_models import BlenderLight, LensOptics, PrimaryLight, make_blender_light
from addon.phase1 import SceneArrays, compute_phase1
from addon.scene import Light, Scene, Sphere, Surface
from addon.tier_tables import Primaries, bi_scene_light_table, make_light_table

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
from cli import blender_lights  # noqa: E402

MODELS = ("THESIS", "PHYSICAL", "FITTED", "EXACT_PROFILE")
#: numpy's tan/exp/arctan2 may differ from math's in the last bit.
RTOL = 1e-9


def random_scene(seed, n_lights=3, n_spheres=40, spread=6.0):
    rng = np.random.default_rng(seed)
    lights = [
        Light(
            position=tuple(rng.uniform(-spread, spread, 3).tolist()),
            color=tuple(rng.uniform(0, 1, 3).tolist()),
            brightness=float(rng.uniform(0.1, 2)),
            radius=float(rng.uniform(0, 0.2)),
        )
        for _ in range(n_lights)
    ]
    objects = [
        Sphere(
            center=tuple(rng.uniform(-spread, spread, 3).tolist()),
            radius=float(rng.uniform(0.05, 1.0)),
            surface=Surface(
                transmission=float(rng.choice([0.0, 0.4, 0.9, 1.0])),
                ior=float(rng.choice([0.9, 1.1, 1.33, 1.5, 2.4])),
            ),
        )
        for _ in range(n_spheres)
    ]
    # A light at a lens's focal point (collimated: D = 1/P = 1.5 R for n = 1.5) and
    # lenses far away and inside the focal length (virtual).
    lights.append(Light(position=(100.0, 100.0, 100.0)))
    objects += [
        Sphere(
            center=(101.5, 100.0, 100.0), radius=1.0, surface=Surface(transmission=1.0, ior=1.5)
        ),
        Sphere(
            center=(100.0, 125.45, 100.0),
            radius=1.0,  # 1/P = 25.5
            surface=Surface(transmission=1.0, ior=1.02),
        ),
        Sphere(center=(40.0, 0.0, 0.0), radius=1.0, surface=Surface(transmission=1.0, ior=1.5)),
        Sphere(center=(0.0, 40.0, 0.0), radius=1.0, surface=Surface(transmission=1.0, ior=1.02)),
    ]
    return Scene(lights=lights, objects=objects)


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
