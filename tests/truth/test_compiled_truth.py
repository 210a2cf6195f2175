"""The ground truth's compiled per-ray passes (shadowlab.truth.compiled, issue 27) equal the
plain numpy they replaced, bit for bit: the sampled truth's samples, horizon test and segments
(rect, disc and sphere lights, own and shared jitter, samples below the horizon and behind a
one-sided light), its per-pixel counts of unoccluded rays, the offset origins on awkward values
(NaN, ±inf, signed zeros, huge and tiny magnitudes) and the hard lights' shadow rays. The exact
hit points are held to their reference in tests/truth/test_ground_truth.py. No timings here."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.scene.area_lights import AreaLight, DiscLight, RectLight, SphereLight
from shadowlab.scene.lights import DirectionalLight, PointLight, SpotLight, T_LIGHT
from shadowlab.techniques.rays.raytrace import (
    SharedJitter, area_chunk_counts, area_chunk_rays, area_chunk_rays_reference, area_visibility,
)
from shadowlab.truth.tracing import mesh_scene, occluded, offset_points, offset_points_reference

LIGHTS = {
    "rect": RectLight(position=np.array([0.2, 3.0, -0.1]), u=np.array([1.5, 0.0, 0.3]), v=np.array([0.0, -0.4, 1.2])),
    "disc": DiscLight(position=np.array([-0.3, 2.5, 0.4]), direction=np.array([0.0, -1.0, 0.0]), radius=0.8),
    "sphere": SphereLight(position=np.array([0.5, 2.0, 0.0]), radius=0.6),
}


def same_bits(a, b):
    """Equal dtype, shape and bytes (NaNs and signed zeros included)."""
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def receivers(m=300, seed=0):
    """M points on and around a floor with unit normals, some tilted far enough that part of a
    light lies below their horizon, some above a one-sided light's plane (behind it); their
    float32 offset origins."""
    rng = np.random.default_rng(seed)
    points = np.column_stack([rng.uniform(-3, 3, m), rng.uniform(-0.5, 0.5, m), rng.uniform(-3, 3, m)])
    points[: m // 10, 1] = 4.0  # above the lights: behind a one-sided light
    normals = np.column_stack([rng.normal(0, 0.8, m), np.ones(m), rng.normal(0, 0.8, m)])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return points, normals, offset_points(points, normals, 10.0)


@pytest.mark.parametrize("shared", [False, True], ids=["own_jitter", "shared_jitter"])
@pytest.mark.parametrize("key", list(LIGHTS))
def test_segments_are_bitwise_the_reference(key, shared):
    """area_chunk_rays (compiled samples for a rect, compiled horizon test and segments) gives
    the numpy reference's live counts, rows, origins and directions bit for bit."""
    light = LIGHTS[key]
    points, normals, origins = receivers()
    n = 37  # not a square: uneven strata rows

    def rng():
        if shared:
            return SharedJitter(np.random.default_rng(5).random((n, 2)))
        return np.random.default_rng([7, 1])

    counts, rows, org, dirs = area_chunk_rays(light, points, normals, origins, n, rng())
    r_counts, r_rows, r_org, r_dirs = area_chunk_rays_reference(light, points, normals, origins, n, rng())
    assert 0 < counts.sum() < len(points) * n  # both dead (horizon, back side) and live samples
    assert same_bits(counts, r_counts)
    assert same_bits(rows, r_rows)
    assert same_bits(org, r_org)
    assert same_bits(dirs, r_dirs)


def test_all_live_chunk_has_no_rows():
    """When every sample is live the rows are None, as in the reference, and the rays are the
    reference's."""
    light = LIGHTS["rect"]
    m = 50
    points = np.column_stack([np.linspace(-1, 1, m), np.zeros(m), np.zeros(m)])
    normals = np.tile([0.0, 1.0, 0.0], (m, 1))
    origins = offset_points(points, normals, 5.0)
    got = area_chunk_rays(light, points, normals, origins, 16, np.random.default_rng(3))
    ref = area_chunk_rays_reference(light, points, normals, origins, 16, np.random.default_rng(3))
    assert got[1] is None and ref[1] is None
    assert all(same_bits(a, b) for i, (a, b) in enumerate(zip(got, ref)) if i != 1)


def test_rect_samples_are_bitwise_the_numpy_map():
    """RectLight.sample_for (compiled) equals AreaLight.sample_for (numpy's uv and affine map)."""
    light = LIGHTS["rect"]
    points, _, _ = receivers(200)
    a, fa = light.sample_for(points, 50, np.random.default_rng(11))
    b, fb = AreaLight.sample_for(light, points, 50, np.random.default_rng(11))
    assert same_bits(a, b) and same_bits(fa, fb)


def reference_counts(scene, light, points, normals, origins, n, rng):
    """Unoccluded counts the pre-issue-27 way: the reference's rays, Embree, bincount."""
    counts, rows, org, dirs = area_chunk_rays_reference(light, points, normals, origins, n, rng)
    blocked = occluded(scene, org, dirs, np.full(len(org), T_LIGHT, np.float32))
    if rows is None:
        return counts - blocked.reshape(len(points), n).sum(axis=1)
    return counts - np.bincount(rows[blocked], minlength=len(points))


@pytest.mark.parametrize("key", list(LIGHTS))
def test_unoccluded_counts_are_the_reference(key, monkeypatch):
    """area_chunk_counts (compiled count of Embree's answers per point) equals the reference's
    blocked-ray bincount, with a caster that blocks part of every light."""
    light = LIGHTS[key]
    points, normals, origins = receivers(400, seed=2)
    quad = (np.array([[-1.0, 1.2, -1.0], [1.0, 1.2, -1.0], [1.0, 1.2, 1.0], [-1.0, 1.2, 1.0]]),
            np.array([[0, 1, 2], [0, 2, 3]]))
    scene, keep = mesh_scene([quad])
    got, rays = area_chunk_counts(scene, light, points, normals, origins, 64, np.random.default_rng([1, 0]))
    ref = reference_counts(scene, light, points, normals, origins, 64, np.random.default_rng([1, 0]))
    assert same_bits(got, ref)
    assert rays > 0 and 0 < (got < 64).sum()
    # the threaded truth over eight chunks of 50 points on worker threads that reuse their ray
    # buffers from chunk to chunk: the same counts as the reference, chunk by chunk
    import shadowlab.truth.area as rt  # where the area estimator lives (raytrace re-exports it)
    from shadowlab.util.compiled import cores

    monkeypatch.setattr(rt, "CHUNK_RAYS", 50 * 64)
    vis, _ = area_visibility(scene, light, points, normals, origins, 64, seed=1)
    chunks = rt.area_chunks(len(points), 64, 1, True)
    assert len(chunks) == 8 and rt.area_workers(64, len(chunks)) >= min(2, cores())
    expected = np.concatenate([reference_counts(scene, light, points[a:b], normals[a:b], origins[a:b], 64, rng)
                               for a, b, rng in chunks])
    assert same_bits(vis, expected / 64)
    del keep


def awkward_rows():
    """Points and normals mixing NaN, ±inf, signed zeros and extreme magnitudes."""
    vals = [0.0, -0.0, 1.0, -2.5, 1e-300, -3e300, np.inf, -np.inf, np.nan]
    rng = np.random.default_rng(4)
    p = rng.choice(vals, (2000, 3))
    n = rng.choice(vals, (2000, 3))
    return p, n


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_offset_points_bitwise_on_awkward_values():
    """The compiled offset origins equal the numpy formula bit for bit on ordinary rows, and on
    rows with NaN, ±inf, signed zeros and huge or tiny values (NaN rows: the numpy fallback)."""
    rng = np.random.default_rng(9)
    p = rng.normal(0, 10.0 ** rng.integers(-6, 6, (5000, 1)), (5000, 3))
    n = rng.normal(0, 1, (5000, 3))
    for extent in (1.0, 1e-8, 1e8):
        for scale in (2.0 ** -18, 1e-3, 0.0):
            assert same_bits(offset_points(p, n, extent, scale), offset_points_reference(p, n, extent, scale))
    p, n = awkward_rows()
    finite = np.isfinite(p).all(axis=1) & np.isfinite(n).all(axis=1)
    for rows in (finite, np.ones(len(p), bool)):  # the compiled pass alone; with the NaN fallback
        assert same_bits(offset_points(p[rows], n[rows], 3.0), offset_points_reference(p[rows], n[rows], 3.0))


@pytest.mark.parametrize("light", [PointLight(position=np.array([0.3, 5.0, -1.0])),
                                   SpotLight(position=np.array([1e4, 2.0, 0.1])),
                                   DirectionalLight(direction=np.array([0.6, -0.8, 0.0]))],
                         ids=["point", "spot", "directional"])
def test_hard_shadow_rays_are_bitwise_numpy(light):
    """The hard lights' shadow rays (compiled for float32 origins) equal numpy's broadcasts."""
    points, normals, origins = receivers(1000, seed=6)
    dirs, tfar = light.shadow_rays(origins, points)
    if isinstance(light, DirectionalLight):
        want = np.broadcast_to((-light.direction).astype(np.float32), origins.shape).copy()
    else:
        want = light.position.astype(np.float32) - origins
    assert same_bits(dirs, want)
    # non-float32 or strided origins take numpy's path and keep its dtype
    d64, _ = light.shadow_rays(origins.astype(np.float64), points)
    assert d64.shape == origins.shape
    assert same_bits(light.shadow_rays(origins[::2], points[::2])[0], want[::2])


def test_split_over_threads_keeps_the_bits(monkeypatch):
    """The per-frame passes cut into row bands and point ranges on helper threads (here three,
    of 64 items at least) give the reference's bits, as in one piece."""
    from shadowlab.gpu.frame import Frame
    from shadowlab.scene import load_scene
    from shadowlab.util import compiled
    from test_ground_truth import assert_exact_points_match_reference

    monkeypatch.setattr(compiled, "MIN_PART", 64)
    monkeypatch.setattr(compiled, "cores", lambda: 3)
    assert len(compiled.split(151, 20000)) == 3
    frame = Frame(load_scene("spot_scene"), 203, 151)
    try:
        assert_exact_points_match_reference(frame)
    finally:
        frame.release()


def test_small_ray_buffers_are_refused():
    """Buffers too small for M·n rays (the compiled pass does not check bounds) are an error."""
    points, normals, origins = receivers(10)
    small = (np.empty((10 * 8 - 1, 3), np.float32), np.empty((10 * 8, 3), np.float32))
    with pytest.raises(ValueError, match="ray buffers"):
        area_chunk_rays(LIGHTS["rect"], points, normals, origins, 8, np.random.default_rng(0), out=small)


def test_kernels_compile_without_a_writable_cache(monkeypatch):
    """Where numba cannot write its on-disk cache (a read-only install) it refuses cache=True when
    a function is decorated; the lab's njit (shadowlab.util.compiled) then compiles without the cache."""
    from shadowlab.util import compiled as compiled_truth

    asked, real = [], compiled_truth._numba_njit

    def refusing(**kw):
        asked.append(kw.get("cache"))
        if kw.get("cache"):
            raise RuntimeError("cannot cache function 'f': no locator available for file 'f.py'")
        return real(**kw)

    monkeypatch.setattr(compiled_truth, "_numba_njit", refusing)

    @compiled_truth.njit(cache=True, nogil=True)
    def plus_one(x):
        return x + 1

    assert plus_one(1) == 2 and asked == [True, False]
