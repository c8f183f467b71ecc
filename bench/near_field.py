"""Near field (issue 12): how each tier lights a receiver that touches or nearly
touches the lens, against the exact optics.

    $PY bench/near_field.py [--root DIR]     # DIR: a checkout to measure (default: this one)

A glass sphere (R, n) under a point light D above its centre; the receiver is
the plane Z from the centre across the axis (Z = R: a marble resting on a table;
1.5 R, 2 R: a ball close to a wall). Each tier's light is made as the add-on
makes it (with the receiver's distance where the checkout takes it) and measured
on that plane: the relative L1 error over the lens's shadow disc and the flux
ratio there (`core.tiers.beam_error`). A light at or behind the receiver's plane puts
nothing on its lit side (L1 = 1, flux 0).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

ap = argparse.ArgumentParser()
ap.add_argument("--root", default=str(Path(__file__).resolve().parent.parent))
ap.add_argument("--ior", type=float, default=1.5)
ARGS = ap.parse_args()
sys.path.insert(0, ARGS.root)

from core.phase1.point_lights import compute_phase1
from core.scene.model import Light, Scene, Sphere, Surface
from core.scene.primaries import PrimaryLight
from core.tiers import TIERS, make_blender_light
from core.tiers import beam_error as acc
from core.tiers import exact_profile as xp

R = 0.01


class _Nothing:
    def flux_within_radius(self, Z, radii):
        return np.zeros(np.shape(radii))


def _model(light, src, Z):
    apex = float(np.dot(np.asarray(light.location) - src.lens_center, src.axis))
    if apex >= Z:
        return _Nothing()
    if light.model == "EXACT_PROFILE":
        key = (round(src.distance / R, 9), round(src.ior, 9))
        try:
            prof = xp.cached_profile(*key, bool(apex < R))
        except TypeError:  # a checkout without the near table
            prof = xp.cached_profile(*key)
        I0 = light.energy_w / (4 * math.pi) / (prof.flux / (2 * math.pi))
        return xp._Profile2D(prof, R, I0)
    return acc.model_from_light(light, src)


def case(D_over_R, Z_over_R, n):
    D, Z = D_over_R * R, Z_over_R * R
    scene = Scene(
        lights=[Light((0.0, 0.0, D))],
        objects=[Sphere((0.0, 0.0, 0.0), R, Surface(transmission=1.0, ior=n))],
    )
    src = compute_phase1(scene).sources[0]
    bounds = ((-0.5, -0.5, -Z), (0.5, 0.5, D))
    size = math.dist(*bounds)
    beam = acc.ExactBeam(1.0, D, R, n, n_fan=8000)
    edges = acc.ring_edges(beam.shadow_radius(Z))
    true = beam.flux_within_radius(Z, edges)
    out = {}
    for name in TIERS:
        kw = dict(scene_size=size, scene_bounds=bounds)
        try:
            light = make_blender_light(
                src, PrimaryLight(4 * math.pi), name, receiver_distance=Z, **kw
            )
        except TypeError:  # a checkout without the near field
            light = make_blender_light(src, PrimaryLight(4 * math.pi), name, **kw)
        mod = np.asarray(_model(light, src, Z).flux_within_radius(Z, edges), float)
        l1 = float(np.sum(np.abs(np.diff(mod) - np.diff(true))) / (true[-1] - true[0]))
        ratio = float((mod[-1] - mod[0]) / (true[-1] - true[0]))
        out[name] = (l1, ratio)
    return out


if __name__ == "__main__":
    print(f"root {ARGS.root}, n = {ARGS.ior}")
    print("| D/R | receiver Z | " + " | ".join(f"{t} L1 / flux" for t in TIERS) + " |")
    print("|---|---|" + "---|" * len(TIERS))
    for D_over_R in (100.0, 10.0, 5.0):
        for Z_over_R in (1.0, 1.5, 2.0):
            res = case(D_over_R, Z_over_R, ARGS.ior)
            cells = " | ".join(f"{l1:.2f} / {r:.2f}" for l1, r in res.values())
            print(f"| {D_over_R:g} | {Z_over_R:g} R | {cells} |")
