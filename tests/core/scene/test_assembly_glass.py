"""Issue 24: which glass the read models as lenses and which it only names (pure):
a thin-walled sphere (Thin Wall) is no lens and says why; a glass sphere set to
Never and glass that is no sphere are the glass Lens Lights does not model
(`BlenderSceneRead.unmodelled_glass`, which keeps Cycles' refractive caustics on)."""

import numpy as np

from core.lens.glass import MaterialOptics
from core.lens.sphere_fit import SphereFit
from core.scene.assembly import NEVER_REASON, THIN_WALL_REASON, GeometryRecord, assemble

CORNERS = np.array([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
GLASS = MaterialOptics(ior=1.5, transmission=1.0)
THIN = MaterialOptics(thin_wall=1.0)  # Thin Wall: nothing refracts
OPAQUE = MaterialOptics()
SPHERE = SphereFit(True, np.zeros(3), 1.0)
BOX = SphereFit(False, np.zeros(3), 0.0, "a box, not a sphere")


def _read(*records):
    n = len(records)
    m = np.repeat(np.eye(4)[None], n, axis=0)
    m[:, 0, 3] = 3.0 * np.arange(n)  # side by side
    read, _blocking = assemble(list(records), np.arange(n), m, np.full(n, -1), [], "render")
    return read


def _record(name, optics, fit, mode="AUTO"):
    return GeometryRecord(name, None, "MESH", CORNERS, mode, None, optics, fit=fit)


def test_glass_the_read_does_not_model_is_named():
    read = _read(
        _record("Ball", GLASS, SPHERE),
        _record("Never ball", GLASS, SPHERE, mode="NEVER"),
        _record("Bubble", THIN, SPHERE),
        _record("Glass cube", GLASS, BOX),
        _record("Stone cube", OPAQUE, BOX),
        _record("Forced bubble", THIN, SPHERE, mode="ALWAYS"),
    )
    assert list(read.sphere_sources) == ["Ball", "Never ball", "Forced bubble"]
    assert read.lens_candidates.tolist() == [True, False, True]
    assert read.left_out_lenses == [
        ("Bubble", THIN_WALL_REASON),
        ("Glass cube", "a box, not a sphere"),
    ]
    assert read.unmodelled_glass == [
        ("Never ball", NEVER_REASON),
        ("Bubble", THIN_WALL_REASON),
        ("Glass cube", "a box, not a sphere"),
    ]
