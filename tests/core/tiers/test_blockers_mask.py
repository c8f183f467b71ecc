"""The Exact profile's shadow mask (`core.tiers.exact_profile_mask.emission_mask`) against phase 2's
reference (reference/phase2.py): the unblocked beam's irradiance times the mask,
looked up in the direction from the light's apex, is the blocked beam's, and the mask
passes the flux the reference passes (half the lens blocked, a centred blocker, a glass
blocker)."""

from __future__ import annotations

import numpy as np
import pytest

from core.tiers.exact_profile_mask import emission_mask
from reference import Blocker, GlassSphere, PointLight, ReceiverPlane
from reference.phase2 import phase2_irradiance

LIGHT = PointLight((0.0, 0.0, 3.0), 100.0)
LENS = GlassSphere((0.0, 0.0, 0.0), 0.5, 1.5)
Z = 1.5  # the receiver, that far below the lens' centre
PLANE = ReceiverPlane((0.0, 0.0, -Z), (0.0, 0.0, 1.0))
APEX = np.array([0.0, 0.0, -0.5005])  # the profile light, just behind the back pole
EX, EY = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])  # its local X, Y
EDGES = np.linspace(-0.4, 0.4, 33)


def masked(mask):
    """Where each cell centre of the plane lies in the mask's texels."""
    c = 0.5 * (EDGES[1:] + EDGES[:-1])
    u, v = np.meshgrid(c, c, indexing="ij")
    to = np.stack([u, v, np.full_like(u, -Z)], axis=-1) - APEX
    to /= np.linalg.norm(to, axis=-1)[..., None]
    ij = lambda s: np.clip(((s / mask.s_max + 1) / 2 * mask.size).astype(int), 0, mask.size - 1)  # noqa: E731
    return mask.pixels[ij(to @ EY), ij(to @ EX)]


@pytest.mark.parametrize(
    "blocker",
    [
        Blocker((0.158, 0.0, 1.5), 0.12),  # the issue's: about half the lens
        Blocker((0.0, 0.0, 1.5), 0.1),  # over the lens' centre
        Blocker((0.0, 0.05, 1.5), 0.12, ior=1.5),  # glass: its Fresnel share passes
    ],
)
def test_the_mask_turns_the_free_beam_into_the_blocked_one(blocker):
    grid = (EDGES, EDGES)
    free = phase2_irradiance(LIGHT, LENS, PLANE, grid)
    ref = phase2_irradiance(LIGHT, LENS, PLANE, grid, [blocker])
    glass = blocker.ior is not None
    mask = emission_mask(
        LIGHT.position,
        LENS.center,
        0.5,
        1.5,
        (
            np.array([blocker.center]),
            np.array([blocker.radius]),
            np.array([1.5 if glass else 1.0]),
            np.array([1.0 if glass else 0.0]),
        ),
        APEX,
        EX,
        EY,
        receiver=Z,
    )
    got = free.irradiance * masked(mask)
    l1 = np.abs(got - ref.irradiance).sum() / ref.irradiance.sum()
    assert l1 < 0.04
    assert mask.passed == pytest.approx(ref.flux_on_plane / ref.flux_unblocked, rel=5e-3)
    if glass:  # nowhere darker than the glass' head-on share (4n/(n + 1)²)² lets through
        assert mask.pixels.min() > 0.9216 * 0.2 and mask.passed > 0.9


def test_a_blocker_off_the_beam_leaves_the_mask_at_one():
    far = (np.array([[3.0, 0.0, 1.5]]), np.array([0.1]), np.ones(1), np.zeros(1))
    mask = emission_mask(LIGHT.position, LENS.center, 0.5, 1.5, far, APEX, EX, EY, receiver=Z)
    assert mask.passed == 1.0 and np.all(mask.pixels == 1.0)
