"""The glass mesh lens (`core.lens.mesh.MeshLens`) against values worked out by hand
(slab, prism, a cube's total internal reflection, Beer, the slab's series of internal
reflections) and against the ball (`core.lens.ball`, independent code) for a finely
tessellated sphere. Fresnel here is the tests' own copy (`glass_meshes.fresnel_t`)."""

import math

import numpy as np
import pytest
from glass_meshes import box, fresnel_t, prism, sphere

from core.lens.ball import BallLens
from core.lens.kinds import make_lens
from core.lens.mesh import MeshLens

N = 1.5


def _mesh(v, t, normals=None, absorption=0.0, ior=N):
    c = 0.5 * (v.min(axis=0) + v.max(axis=0))
    r = float(np.linalg.norm(v - c, axis=1).max())
    return MeshLens(c, r, ior, absorption, v, t, normals)


def _unpolarised_pair(cos_in, cos_out):
    """Two crossings in one plane of incidence: ½(t_s t_s' + t_p t_p')."""
    s1, p1 = fresnel_t(cos_in, 1.0, N)
    s2, p2 = fresnel_t(cos_out, N, 1.0)
    return 0.5 * (s1 * s2 + p1 * p2)


def test_registered_as_the_mesh_kind():
    v, t = box((-1, -1, -1), (1, 1, 1))
    lens = make_lens("mesh", np.zeros(3), math.sqrt(3), N, 0.0, (v, t, None))
    assert isinstance(lens, MeshLens) and not lens.point_image and lens.convex
    c, r = lens.bounding_sphere()
    assert np.allclose(c, 0) and r == pytest.approx(math.sqrt(3))


@pytest.mark.parametrize("theta_deg", [0.0, 20.0, 40.0, 70.0])
def test_slab_shifts_a_ray_sideways_and_transmits_the_fresnel_product(theta_deg):
    thick = 0.8
    lens = _mesh(*box((-6, -6, 0), (6, 6, thick)))
    th = math.radians(theta_deg)
    d = np.array([math.sin(th), 0.0, -math.cos(th)])
    p1 = np.array([0.3, 0.2, thick])
    out = lens.trace((p1 - 3 * d)[None], d[None])
    th_r = math.asin(math.sin(th) / N)
    shift = thick * math.sin(th - th_r) / math.cos(th_r)
    seg = out.points[0] - p1
    lateral = np.linalg.norm(seg - (seg @ d) * d)
    assert out.hit[0] and out.points[0, 2] == pytest.approx(0.0, abs=1e-9)
    assert lateral == pytest.approx(shift, abs=1e-9)
    np.testing.assert_allclose(out.directions[0], d, atol=1e-12)
    assert out.weight[0] == pytest.approx(
        _unpolarised_pair(math.cos(th), math.cos(th_r)), rel=1e-12
    )
    assert out.path[0] == pytest.approx(thick / math.cos(th_r), rel=1e-12)


def test_prism_deviates_by_its_minimum_deviation():
    apex = 60.0
    lens = _mesh(*prism(apex, side=1.0, length=4.0))
    half = math.radians(apex) / 2
    theta = math.asin(N * math.sin(half))  # incidence at minimum deviation
    elev = theta - half  # the ray rises into the left face, leaves falling
    d = np.array([math.cos(elev), 0.0, math.sin(elev)])
    h, w = math.cos(half), math.sin(half)
    hit = np.array([-w / 2, 0.3, h / 2])  # the left face at mid-height
    out = lens.trace((hit - 2 * d)[None], d[None])
    dev = math.acos(float(np.clip(out.directions[0] @ d, -1, 1)))
    assert dev == pytest.approx(2 * theta - math.radians(apex), abs=1e-12)
    np.testing.assert_allclose(out.directions[0], [math.cos(elev), 0, -math.sin(elev)], atol=1e-12)
    cos_i, cos_r = math.cos(theta), math.cos(half)
    assert out.weight[0] == pytest.approx(_unpolarised_pair(cos_i, cos_r), rel=1e-12)


def test_cube_side_face_reflects_totally_at_sixty_degrees():
    lens = _mesh(*box((-1, -1, -1), (1, 1, 1)))
    sin_t = N * math.sin(math.radians(30.0))  # refracted 30° from vertical: 60° at the side
    th = math.asin(sin_t)
    d = np.array([sin_t, 0.0, -math.cos(th)])
    entry = np.array([0.5, 0.1, 1.0])
    out = lens.trace((entry - 2 * d)[None], d[None])
    # down to the side x = 1 at z = 1 − 0.5 cot 30°, mirrored, down to z = −1
    z_side = 1.0 - 0.5 / math.tan(math.radians(30))
    x_exit = 1.0 - (z_side + 1.0) * math.tan(math.radians(30))
    np.testing.assert_allclose(out.points[0], [x_exit, 0.1, -1.0], atol=1e-9)
    np.testing.assert_allclose(out.directions[0], [-sin_t, 0.0, -math.cos(th)], atol=1e-12)
    cos30 = math.cos(math.radians(30))
    assert out.weight[0] == pytest.approx(_unpolarised_pair(math.cos(th), cos30), rel=1e-12)
    # with every branch followed, nothing leaves by the side face it met
    br = lens.trace_branches((entry - 2 * d)[None], d[None], max_depth=12, min_weight=1e-9)
    live = br.weight[:, 0] > 0
    faces = lens.face_normals[br.exit_face[live, 0]]
    first_side = np.isclose(br.points[live, 0, 2], z_side) & np.isclose(faces[:, 0], 1.0)
    assert not first_side.any()


def test_beer_absorption_along_the_path():
    a, thick = 0.7, 1.3
    lens = _mesh(*box((-5, -5, 0), (5, 5, thick)), absorption=a)
    out = lens.trace(np.array([[0.2, 0.1, 3.0]]), np.array([[0.0, 0.0, -1.0]]))
    t0 = _unpolarised_pair(1.0, 1.0)
    assert out.weight[0] == pytest.approx(t0 * math.exp(-a * thick), rel=1e-12)
    assert out.path[0] == pytest.approx(thick, rel=1e-12)


def test_slab_internal_reflections_sum_to_the_fresnel_series():
    """Normal incidence on a slab: out below T²(1 + R² + R⁴ …) = T²/(1 − R²), back out
    above R + T²R(1 + R² …); with absorption each pass × e^{−aL}."""
    a, thick = 0.2, 0.5
    lens = _mesh(*box((-5, -5, 0), (5, 5, thick)), absorption=a)
    br = lens.trace_branches(
        np.array([[0.2, 0.1, 3.0]]), np.array([[0.0, 0.0, -1.0]]), max_depth=40, min_weight=1e-14
    )
    r = ((N - 1) / (N + 1)) ** 2
    t = 1 - r
    k = math.exp(-a * thick)
    down = t * t * k / (1 - r * r * k * k)
    up = r + t * t * r * k * k / (1 - r * r * k * k)
    w = br.weight[:, 0]
    going_down = br.directions[:, 0, 2] < 0
    assert w[going_down & (w > 0)].sum() == pytest.approx(down, rel=1e-9)
    assert w[~going_down & (w > 0)].sum() == pytest.approx(up, rel=1e-9)
    assert w.sum() + br.absorbed[0] + br.dropped[0] == pytest.approx(1.0, abs=1e-14)
    assert br.absorbed[0] == pytest.approx(1 - down - up, rel=1e-9)


def test_energy_is_conserved_over_every_branch():
    rng = np.random.default_rng(4)
    lens = _mesh(*box((-1, -0.7, -0.4), (1, 0.7, 0.4)), absorption=0.3)
    o = rng.normal(size=(400, 3))
    o = 4 * o / np.linalg.norm(o, axis=1)[:, None]
    d = rng.uniform(-0.6, 0.6, (400, 3)) - o
    d /= np.linalg.norm(d, axis=1)[:, None]
    br = lens.trace_branches(o, d, max_depth=10, min_weight=1e-4)
    total = br.weight.sum(0) + br.absorbed + br.dropped
    np.testing.assert_allclose(total, 1.0, atol=1e-12)
    met = br.hit[0]
    assert met.sum() > 300 and br.dropped[met].mean() < 2e-3
    assert np.all(br.weight[0][~met] == 1.0) and np.all(br.crossings[0][~met] == 0)
    assert br.weight.shape[0] > 3  # the internal reflections are there


def test_fine_sphere_traces_like_the_ball():
    v, t, nrm = sphere(1.0, 48, 96)
    lens = _mesh(v, t, nrm)
    ball = BallLens(np.zeros(3), 1.0, N)
    rng = np.random.default_rng(2)
    b = 0.92 * np.sqrt(rng.uniform(0, 1, 2000))
    phi = rng.uniform(0, 2 * np.pi, 2000)
    axis = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    e1 = np.cross(axis, [1.0, 0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    o = -5 * axis + (b * np.cos(phi))[:, None] * e1 + (b * np.sin(phi))[:, None] * e2
    d = np.broadcast_to(axis, o.shape)
    m, s = lens.trace(o, d), ball.trace(o, d)
    assert m.hit.all() and s.hit.all()
    ang = np.arccos(np.clip(np.einsum("ij,ij->i", m.directions, s.directions), -1, 1))
    # 48 × 96 facets: chords sag 1 − cos(π/96) ≈ 5e-4 of R
    assert ang.max() < 6e-3 and ang.mean() < 1.5e-3
    assert np.abs(m.weight - s.weight).max() < 5e-3
    assert np.abs(m.points - s.points).max() < 3e-3
    assert np.abs(m.path - s.path).max() < 3e-3


def test_flat_and_smooth_normals_on_a_low_poly_sphere():
    v, t, nrm = sphere(1.0, 8, 16)
    flat, smooth = _mesh(v, t), _mesh(v, t, nrm)
    ball = BallLens(np.zeros(3), 1.0, N)
    rng = np.random.default_rng(9)
    xy = rng.uniform(-0.5, 0.5, (500, 2))
    o = np.column_stack([xy, np.full(500, -4.0)])
    d = np.tile([0.0, 0.0, 1.0], (500, 1))
    f, s, b = flat.trace(o, d), smooth.trace(o, d), ball.trace(o, d)

    def err(x):
        return np.arccos(np.clip(np.einsum("ij,ij->i", x.directions, b.directions), -1, 1))

    # smooth shading bends like the sphere it stands for; flat facets like prisms
    assert err(s).mean() < 0.5 * err(f).mean()
    # flat: parallel rays through the same pair of facets leave parallel
    fb = flat.trace_branches(o, d, max_depth=2, min_weight=0.5)
    sb = smooth.trace_branches(o, d, max_depth=2, min_weight=0.5)
    key = fb.signature[0] * np.uint64(7) + fb.exit_face[0].astype(np.uint64)
    _, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
    pair = np.nonzero(counts[inv] > 1)[0]
    assert len(pair) > 20
    for g in np.unique(inv[pair]):
        rows = np.nonzero(inv == g)[0]
        assert np.ptp(f.directions[rows], axis=0).max() < 1e-12
        assert np.ptp(s.directions[rows], axis=0).max() > 1e-4
    # a flat low-poly sphere: a face group per facet (16 triangles at each pole, 6
    # rings of 16 planar quads); its smooth twin one
    assert flat.face_groups.max() + 1 == 16 * 2 + 16 * 6 and smooth.face_groups.max() == 0
    assert sb.signature[0].min() == sb.signature[0].max()


def test_bent_shading_normals_leak_nothing():
    """Corner normals tilted up to 50° off the surface: the crossings that they would
    turn back use the geometric normal, so every path still leaves through the
    surface outward and all the power is accounted for."""
    v, t, nrm = sphere(1.0, 10, 20)
    rng = np.random.default_rng(6)
    bent = nrm + rng.normal(0, 0.6, nrm.shape)
    lens = _mesh(v, t, bent)
    o = rng.normal(size=(600, 3))
    o = 3 * o / np.linalg.norm(o, axis=1)[:, None]
    d = rng.uniform(-0.7, 0.7, (600, 3)) - o
    d /= np.linalg.norm(d, axis=1)[:, None]
    br = lens.trace_branches(o, d, max_depth=64, min_weight=0.0)
    np.testing.assert_allclose(br.weight.sum(0) + br.absorbed + br.dropped, 1.0, atol=1e-12)
    assert not br.leaked.any()  # nothing lost through a crack
    assert br.dropped.max() < 1e-3  # only what stays trapped past 64 crossings
    out = (br.weight > 0) & (br.crossings > 0)
    nrm_exit = lens.face_normals[br.exit_face[out]]
    assert np.all(np.einsum("ij,ij->i", br.directions[out], nrm_exit) > 0)


def test_light_leaving_one_part_enters_the_next():
    """Two slabs in one (non-convex) mesh: the ray crosses four faces, shifted twice."""
    v1, t1 = box((-5, -5, 0), (5, 5, 0.5))
    v2, t2 = box((-5, -5, 1.5), (5, 5, 2.0))
    lens = _mesh(np.vstack([v1, v2]), np.vstack([t1, t2 + len(v1)]))
    assert not lens.convex
    th = math.radians(35)
    d = np.array([math.sin(th), 0, -math.cos(th)])
    p1 = np.array([0.0, 0.0, 2.0])
    br = lens.trace_branches((p1 - d)[None], d[None], max_depth=4, min_weight=0.5)
    assert br.crossings[0, 0] == 4
    th_r = math.asin(math.sin(th) / N)
    shift = 2 * 0.5 * math.sin(th - th_r) / math.cos(th_r)
    seg = br.points[0, 0] - p1
    assert np.linalg.norm(seg - (seg @ d) * d) == pytest.approx(shift, abs=1e-9)
    pair = _unpolarised_pair(math.cos(th), math.cos(th_r))
    s1, p1_ = fresnel_t(math.cos(th), 1, N)
    s2, p2 = fresnel_t(math.cos(th_r), N, 1)
    assert br.weight[0, 0] == pytest.approx(0.5 * ((s1 * s2) ** 2 + (p1_ * p2) ** 2), rel=1e-12)
    assert pair > br.weight[0, 0]


def test_a_bounding_sphere_too_small_grows_to_hold_the_mesh():
    v, t = box((-1, -1, -1), (1, 1, 3))
    lens = MeshLens(np.zeros(3), 1.0, N, 0.0, v, t)
    _, r = lens.bounding_sphere()
    assert float(r) == pytest.approx(math.sqrt(1 + 1 + 9), rel=1e-8)
    assert float(r) >= np.linalg.norm(v, axis=1).max()


def test_light_lost_through_a_hole_is_counted_as_leaked():
    v, t = box((-1, -1, -1), (1, 1, 1))
    bottom = np.all(v[t][:, :, 2] == -1, axis=1)
    lens = _mesh(v, t[~bottom])  # no floor: the light that enters the top falls out
    assert not lens.convex
    o = np.array([[0.2, 0.1, 3.0], [5.0, 0.0, 0.0]])
    d = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, -1.0]])
    br = lens.trace_branches(o, d, max_depth=8, min_weight=1e-9)
    assert br.leaked.tolist() == [True, False]
    np.testing.assert_allclose(br.weight.sum(0) + br.absorbed + br.dropped, 1.0, atol=1e-12)
    assert br.dropped[0] == pytest.approx(1 - ((N - 1) / (N + 1)) ** 2, rel=1e-9)


def _float32_pebble():
    """A smooth UV-sphere pebble scaled (1, 1, 0.5) away from the origin, its
    coordinates rounded to float32 as Blender stores them: its quads (two triangles
    each) fold by ~1e-7 either way."""
    v, t, _ = sphere(0.5, 32, 32)
    v = (v * [1.0, 1.0, 0.5] + [3.0, -2.0, 1.0]).astype(np.float32).astype(float)
    return v, t


def test_a_convex_mesh_in_float32_coordinates_is_still_convex():
    """Blender's float32 vertices bend its flat quads a little either way: the mesh
    is still convex (one way in, one way out: the fast walk), and that walk gives
    every branch the general walk gives (re-entry tested) to rounding."""
    v, t = _float32_pebble()
    lens = _mesh(v, t)
    assert lens.convex
    general = _mesh(v, t)
    general.__dict__["convex"] = False  # the walk that tests every ray against the mesh
    rng = np.random.default_rng(3)
    light = np.array([3.4, -1.7, 5.0])
    tgt = np.array([3.0, -2.0, 1.0]) + rng.uniform(-0.55, 0.55, (4000, 3)) * [1, 1, 0.5]
    dirs = tgt - light
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    o = np.broadcast_to(light, dirs.shape)
    a = lens.trace_branches(o, dirs, max_depth=8, min_weight=5e-3)
    b = general.trace_branches(o, dirs, max_depth=8, min_weight=5e-3)
    through = lambda br: np.where(br.crossings >= 2, br.weight, 0.0).sum(axis=0)  # noqa: E731
    np.testing.assert_allclose(through(a), through(b), atol=1e-12)
    assert through(a).sum() > 100.0  # most rays went through


def test_a_real_fold_outward_is_not_convex():
    """A pebble with one vertex pushed in by a thousandth of its size is concave there."""
    v, t = _float32_pebble()
    v = v.copy()
    k = len(v) // 2 + 5  # a vertex on the equator's side, away from the poles
    c = np.array([3.0, -2.0, 1.0])
    v[k] = c + (v[k] - c) * (1.0 - 1e-3 * 8)
    assert not _mesh(v, t).convex


def test_walking_a_convex_mesh_gives_the_branches_of_the_bvh(monkeypatch):
    """A convex mesh's waves are mostly walked on its surface (`core.shared.surface_walk`):
    every branch the same as with every segment cast against the BVH alone."""
    import core.lens.mesh as mesh_module
    from core.shared.triangle_bvh import intersect

    v, t, nrm = sphere(1.0, 24, 48)
    v, nrm = v * [1.0, 0.7, 0.45], nrm / [1.0, 0.7, 0.45]
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    lens = _mesh(v, t, nrm, absorption=0.2)
    assert lens.convex
    rng = np.random.default_rng(8)
    light = np.array([0.4, 0.3, 3.0])
    d = rng.uniform(-1, 1, (6000, 3)) * [1.0, 0.7, 0.45] - light
    d /= np.linalg.norm(d, axis=1)[:, None]
    d = d[np.lexsort((d[:, 1], np.round(d[:, 0], 2)))]  # roughly coherent, as a grid
    o = np.broadcast_to(light, d.shape)
    walked = lens.trace_branches(o, d, max_depth=8, min_weight=1e-3)
    monkeypatch.setattr(
        mesh_module,
        "intersect_convex",
        lambda walk, o, d, side: intersect(walk.bvh, o, d, facing=side),
    )
    cast = lens.trace_branches(o, d, max_depth=8, min_weight=1e-3)
    assert walked.weight.shape == cast.weight.shape and walked.weight.shape[0] > 3
    for f in ("points", "directions", "weight", "path", "absorbed", "dropped"):
        np.testing.assert_allclose(getattr(walked, f), getattr(cast, f), rtol=0, atol=1e-12)
    for f in ("crossings", "signature", "exit_face", "hit", "leaked"):
        np.testing.assert_array_equal(getattr(walked, f), getattr(cast, f))


def test_the_same_mesh_in_another_face_order_traces_bit_for_bit_the_same():
    # Blender may hand a mesh's faces in another order from one run to the next (its UV
    # sphere): the triangles shuffled and each one's corners turned, winding kept
    v, t, nrm = sphere(0.5, 16, 32)
    v = v * [1.0, 1.0, 0.5]
    rng = np.random.default_rng(4)
    order = rng.permutation(len(t))
    turn = rng.integers(0, 3, len(t))
    rot = (turn[:, None] + np.arange(3)) % 3
    t2 = np.take_along_axis(t, rot, axis=1)[order]
    n2 = np.take_along_axis(nrm, rot[:, :, None], axis=1)[order]
    a, b = _mesh(v, t, nrm), _mesh(v, t2, n2)
    xy = rng.uniform(-0.45, 0.45, (3000, 2))
    o = np.column_stack([xy, np.full(3000, 3.0)])
    d = _unit_rows(np.column_stack([0.1 * xy, np.full(3000, -1.0)]))
    ra, rb = a.trace_branches(o, d), b.trace_branches(o, d)
    assert ra.weight.shape[0] > 2 and ra.hit[0].sum() > 1500
    for name in ("points", "directions", "weight", "hit", "signature", "exit_face"):
        assert np.array_equal(getattr(ra, name), getattr(rb, name)), name


def _unit_rows(x):
    return x / np.linalg.norm(x, axis=1, keepdims=True)
