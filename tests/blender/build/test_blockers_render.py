"""The blocker's shadow inside the caustic, rendered (Cycles, AUTO = Exact profile with
its shadow mask), against phase 2's reference (reference/phase2.py).

The scene of issue 13: a point light 3 above a glass ball (R = 0.5, n = 1.5) whose
centre is 1.5 above a white floor, an opaque sphere (R = 0.12) halfway between them,
off the axis by 0.158 so that it shades one side of the lens. The floor lies past the
image point (1.0 below the centre), so the shadow falls on the far side (−x) of the
caustic. A pixel of the render "with lens lights" minus "without" is the floor's
radiance 0.8 E/π of the lens light alone; the reference bins exact rays light →
blocker → lens → floor into the same pixels.

Asserted: the left/right ratio of the light in view within 10 % of the reference's
(the lens light without the mask: 1, the issue's complaint); the L1 error of the image
(over the reference's light in view) ≤ 0.25 at this size (40 px, 64 samples;
reports/blockers.md has the benchmark's figures); the light in view within 15 %.
"""

import math

import bpy
import numpy as np
import pytest
from measuring_scene import (
    build_measuring_scene,
    direct_light_only,
    new_material,
    render_grey,
)

from reference import Blocker, GlassSphere, PointLight, ReceiverPlane
from reference.phase2 import phase2_irradiance

pytestmark = pytest.mark.blender

R, N, HEIGHT, D, POWER, ALBEDO = 0.5, 1.5, 1.5, 3.0, 1000.0, 0.8
BLOCKER = ((0.158, 0.0, HEIGHT + 1.5), 0.12)
PX, VIEW = 40, 1.2


def build(tmp):
    built = build_measuring_scene(
        "CYCLES",
        resolution=PX,
        floor_size=8.0,
        albedo=ALBEDO,
        view=VIEW,
        camera_height=6.0,
        ball=dict(radius=R, location=(0.0, 0.0, HEIGHT), ior=N, name="Marble"),
        lamp=dict(location=(0.0, 0.0, HEIGHT + D), power=POWER),
    )
    bpy.ops.mesh.primitive_uv_sphere_add(
        radius=BLOCKER[1], location=BLOCKER[0], segments=32, ring_count=16
    )
    blocker = bpy.context.object
    blocker.name = "Blocker"
    blocker.data.materials.append(new_material("Opaque"))  # Principled, no transmission
    blocker.visible_camera = False
    sc = built.scene
    direct_light_only(sc, 64)
    return sc


def render(sc, path):
    return render_grey(sc, path)  # (rows = y from the bottom, columns = x)


def reference_image():
    """Phase 2's irradiance in the camera's pixels, as the floor's radiance."""
    edges = np.linspace(-VIEW / 2, VIEW / 2, PX + 1)
    ref = phase2_irradiance(
        PointLight((0.0, 0.0, HEIGHT + D), POWER),
        GlassSphere((0.0, 0.0, HEIGHT), R, N),
        ReceiverPlane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
        (edges, edges),
        [Blocker(*BLOCKER)],
    )
    return ALBEDO * ref.irradiance.T / math.pi  # (y, x) like the render


def left_right(img):
    half = img.shape[1] // 2
    return float(img[:, :half].sum() / img[:, half:].sum())


@pytest.fixture(scope="module")
def images(extension, tmp_path_factory):
    from lens_lights.blender.commands.generate import generate

    tmp = tmp_path_factory.mktemp("blockers")
    sc = build(tmp)
    without = render(sc, tmp / "without.exr")
    level, message, _ = generate(bpy.context)
    assert level != "ERROR", message
    (ll,) = [
        o
        for o in bpy.data.objects
        if o.lens_lights.is_lens_light and not o.get("lens_lights_reflection")
    ]
    masks = [
        n.image.name
        for n in ll.data.node_tree.nodes
        if n.bl_idname == "ShaderNodeTexImage" and n.image.name.startswith("Lens mask")
    ]
    with_ = render(sc, tmp / "with.exr")
    return dict(diff=with_ - without, light=ll, masks=masks, model=ll.lens_lights.energy_model)


def test_the_profile_light_carries_a_shadow_mask(images):
    assert images["model"] == "EXACT_PROFILE"
    assert len(images["masks"]) == 1
    assert 0.0 < images["light"].lens_lights.unblocked_fraction < 1.0


def test_the_shadow_falls_inside_the_caustic_as_in_the_reference(images):
    got, ref = images["diff"], reference_image()
    lr_got, lr_ref = left_right(got), left_right(ref)
    l1 = float(np.abs(got - ref).sum() / ref.sum())
    flux = float(got.sum() / ref.sum())
    print(
        f"\nleft/right: render {lr_got:.3f}, reference {lr_ref:.3f}; L1 {l1:.3f}; flux {flux:.3f}"
    )
    assert lr_ref < 0.8  # the reference does see the shadow on the −x side
    assert lr_got == pytest.approx(lr_ref, rel=0.10)
    assert l1 <= 0.25
    assert flux == pytest.approx(1.0, rel=0.15)


def test_clear_removes_the_mask_image(images):
    from lens_lights.blender.build import cleanup

    cleanup.clear(bpy.context.scene)
    assert not [i for i in bpy.data.images if i.name.startswith("Lens mask")]
