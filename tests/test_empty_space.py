"""Empty-space skipping (docs/empty-space-skipping.md): the occupancy grid's numbers, and the
image with skipping on equals the image with it off (≤ 1 8-bit level) for techniques, blend
modes, a crop, slice weights, jitter and the corrected filter, while it really skips."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from vtkvol.engine import occupancy


def sparse_phantom(n: int = 48, seed: int = 1) -> np.ndarray:
    """A few Gaussian blobs in an empty uint8 box (beads-like; about half the bricks empty)."""
    rng = np.random.default_rng(seed)
    z, y, x = np.mgrid[:n, :n, :n].astype(np.float32)
    a = np.zeros((n, n, n), np.float32)
    for _ in range(6):
        c = rng.uniform(6, n - 6, 3)
        r = rng.uniform(2, 5)
        a += 200 * np.exp(-((z - c[0]) ** 2 + (y - c[1]) ** 2 + (x - c[2]) ** 2) / (2 * r * r))
    return np.clip(a, 0, 255).astype(np.uint8)


def _trilinear(a: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Trilinear samples of ``a`` ([z, y, x]) at voxel coordinates ``p`` (k, 3) as (x, y, z),
    clamped at the faces like GL's clamp-to-edge."""
    nz, ny, nx = a.shape
    p = np.clip(p, 0.0, [nx - 1, ny - 1, nz - 1])
    i0 = np.minimum(np.floor(p).astype(int), [nx - 2, ny - 2, nz - 2])
    t = p - i0
    out = np.zeros(len(p))
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                w = ((t[:, 0] if dx else 1 - t[:, 0]) * (t[:, 1] if dy else 1 - t[:, 1])
                     * (t[:, 2] if dz else 1 - t[:, 2]))
                out += w * a[i0[:, 2] + dz, i0[:, 1] + dy, i0[:, 0] + dx]
    return out


# -- the occupancy grid (numpy) -----------------------------------------------------------------
def test_every_trilinear_sample_lies_in_its_bricks_range() -> None:
    """The apron makes the brick's [min, max] hold every sample taken in it, also samples in
    the half voxel outside the outermost voxel centres (clamped)."""
    rng = np.random.default_rng(3)
    a = rng.integers(0, 255, (19, 21, 26)).astype(np.float32)  # not multiples of 8
    ranges = occupancy.brick_ranges(a, apron=1)
    assert ranges.bricks_zyx == (3, 3, 4)
    nz, ny, nx = a.shape
    p = rng.uniform(-0.5, 1.0, (20000, 3)) * [nx, ny, nz] - np.array([0.0, 0.0, 0.0])
    p = np.clip(p, -0.5, [nx - 0.5, ny - 0.5, nz - 0.5])
    values = _trilinear(a, p)
    b = np.clip(np.floor(p / occupancy.BRICK).astype(int), 0, [3, 2, 2])
    lo = ranges.lo[0][b[:, 2], b[:, 1], b[:, 0]]
    hi = ranges.hi[0][b[:, 2], b[:, 1], b[:, 0]]
    assert np.all(values >= lo - 1e-9) and np.all(values <= hi + 1e-9)
    # Without the apron the same samples leave the range: the apron is what makes it hold.
    bare = occupancy.brick_ranges(a, apron=0)
    lo0 = bare.lo[0][b[:, 2], b[:, 1], b[:, 0]]
    hi0 = bare.hi[0][b[:, 2], b[:, 1], b[:, 0]]
    assert np.any((values < lo0 - 1e-9) | (values > hi0 + 1e-9))


@pytest.mark.parametrize("shape", [(5, 17, 9), (20, 33, 31), (1, 3, 40)])
@pytest.mark.parametrize("apron", [0, 1, 2])
@pytest.mark.parametrize("brick", [8, (3, 5, 7)])
def test_brick_ranges_are_each_bricks_window_min_and_max(shape, apron, brick) -> None:
    """The separable reduction equals the definition: min/max over the brick and ``apron``
    voxels around it, clamped at the faces, for partial bricks and anisotropic ones."""
    rng = np.random.default_rng(5)
    a = rng.random((*shape, 2)).astype(np.float32)
    ranges = occupancy.brick_ranges(a, apron=apron, brick=brick)
    edges = occupancy.brick_shape(brick)
    for idx in np.ndindex(*ranges.bricks_zyx):
        window = tuple(slice(max(0, b * e - apron), min(n, (b + 1) * e + apron))
                       for b, e, n in zip(idx, edges, shape, strict=True))
        for c in range(2):
            assert ranges.lo[c][idx] == a[(*window, c)].min()
            assert ranges.hi[c][idx] == a[(*window, c)].max()


def test_brick_ranges_of_nan_never_skip_and_bad_shapes_are_refused() -> None:
    a = np.zeros((8, 8, 16), np.float32)
    a[2, 2, 12] = np.nan
    ranges = occupancy.brick_ranges(a)
    assert ranges.lo[0, 0, 0, 1] == -np.inf and ranges.hi[0, 0, 0, 1] == np.inf
    assert ranges.lo[0, 0, 0, 0] == 0.0  # NaN one voxel beyond the apron stays out
    with pytest.raises(ValueError, match="shape"):
        occupancy.brick_ranges(np.zeros((4, 4)))


def test_max_over_intervals_matches_dense_evaluation() -> None:
    xs = np.array([0.0, 10.0, 20.0, 40.0, 60.0])
    ys = np.array([0.0, 0.0, 0.7, 0.1, 0.0])
    rng = np.random.default_rng(0)
    lo = rng.uniform(-20, 80, 500)
    hi = lo + rng.uniform(0, 30, 500)
    got = occupancy.max_over_intervals(xs, ys, lo, hi)
    dense = np.array([np.interp(np.linspace(a, b, 4001), xs, ys).max()
                      for a, b in zip(lo, hi, strict=True)])
    assert np.allclose(got, dense, atol=1e-3)
    assert occupancy.max_over_intervals(xs, ys, np.array([0.0]), np.array([10.0]))[0] == 0.0


def test_transfer_occupancy_widens_by_two_table_entries() -> None:
    ranges = occupancy.BrickRanges(np.array([[[[0.0, 0.0]]]]), np.array([[[[99.0, 99.6]]]]), 1,
                                   (8, 8, 16))
    ramp = (np.array([0.0, 100.0, 255.0]), np.array([0.0, 0.0, 1.0]))
    # Table over 0…255: two entries ≈ 0.5 units; a brick ending 1 unit below the ramp is
    # empty, one ending 0.4 below it is not (the GPU's interpolated table may be non-zero).
    grid = occupancy.transfer_occupancy(ranges, [ramp], [(0.0, 255.0)])
    assert grid.tolist() == [[[False, True]]]
    assert not occupancy.transfer_occupancy(ranges, [None], [(0.0, 255.0)]).any()


def test_a_ramp_starting_at_the_data_minimum_leaves_the_background_empty() -> None:
    """Bricks all at the table's first value read exactly its first entry, f(r0) = 0; one
    value above it may already read the ramp."""
    ranges = occupancy.BrickRanges(np.array([[[[0.0, 0.0, np.nan]]]]),
                                   np.array([[[[0.0, 0.01, np.nan]]]]), 1, (8, 8, 24))
    ranges = occupancy.BrickRanges(np.nan_to_num(ranges.lo, nan=-np.inf),
                                   np.nan_to_num(ranges.hi, nan=np.inf), 1, (8, 8, 24))
    identity = (np.array([0.0, 1.0]), np.array([0.0, 1.0]))
    grid = occupancy.transfer_occupancy(ranges, [identity], [(0.0, 1.0)])
    assert grid.tolist() == [[[False, True, True]]]


def test_crop_occupancy_agrees_with_the_voxels_it_shows() -> None:
    shape = (20, 24, 30)
    origin, spacing = (5.0, -2.0, 1.0), (0.5, 1.0, 2.0)
    planes = (8.0, 14.0, 3.0, 12.0, 9.0, 30.0)  # µm
    for flags in (0x0002000, 0x7FFDFFF):  # sub-volume, and everything but it
        kept = occupancy.crop_occupancy(shape, origin, spacing, planes, flags)
        # Brute force: a brick is needed when a voxel-coordinate position in it (fine grid,
        # within half a voxel of the brick) falls in a shown region.
        for bz, by, bx in np.ndindex(kept.shape):
            pts = [np.linspace(8 * b - 0.49, min(8 * b + 8, n - 0.5), 23)
                   for b, n in ((bx, shape[2]), (by, shape[1]), (bz, shape[0]))]
            regions = []
            for axis, p in enumerate(pts):
                c = origin[axis] + spacing[axis] * p
                regions.append((c >= planes[2 * axis]).astype(int) + (c >= planes[2 * axis + 1]))
            rx, ry, rz = np.meshgrid(*regions, indexing="ij")
            shown = (flags >> (rx + 3 * ry + 9 * rz)) & 1
            if shown.any():
                assert kept[bz, by, bx], (flags, bz, by, bx)
        if flags == 0x0002000:
            assert 0 < kept.sum() < kept.size


def test_weight_occupancy_drops_bricks_where_an_axis_weight_is_zero() -> None:
    weights = np.ones((3, 11), np.float32)
    weights[0, :5] = 0.0  # x: zero on the first 40 % (entry 5 ramps back up)
    kept = occupancy.weight_occupancy((16, 16, 64), weights)
    assert kept.shape == (2, 2, 8)
    # Entry 4 (x = 0.4 → voxel 25.2) is the last zero: bricks 0–2 (voxels 0–24) lie where the
    # weight is 0; brick 3 (voxels 24–32) reaches the ramp towards entry 5.
    assert kept[0, 0].tolist() == [False, False, False, True, True, True, True, True]
    assert kept[:, :, 3:].all() and not kept[:, :, :3].any()


# -- images: on vs off ---------------------------------------------------------------------------
def _render_pair(configure: Callable, method: str = "local", array: np.ndarray | None = None,
                 **scene_kw) -> tuple[np.ndarray, np.ndarray, dict]:
    """Render the sparse phantom at 128² with skipping off, then on (same window, same
    settings, second frame each); return both images and the host's stats with it on."""
    from vtkvol.engine.illuminator import Illuminator
    from vtkvol.engine.offscreen import grab, simple_volume_scene

    arr = sparse_phantom() if array is None else array
    kw = {"opacity": [(0.0, 0.0), (30.0, 0.0), (255.0, 0.8)], "azimuth": 30.0,
          "elevation": 20.0, **scene_kw}
    rw, ren, vol = simple_volume_scene(arr, size=(128, 128), **kw)
    il = Illuminator(vol, ren, method=method)
    try:
        configure(vol, il)
        if il.spec.has("progressive"):
            il.set_parameters(max_iterations=8)
            # Refine first: toggling skipping restarts nothing, so both images then show the
            # same converged light.
            il.converge(max_seconds=60)
        images = []
        for on in (False, True):
            il.set_empty_space_skipping(on)
            grab(rw)
            images.append(grab(rw).astype(np.int16))
        stats = il.empty_space_stats()
        assert il.last_error is None, il.last_error
    finally:
        il.release()
        rw.Finalize()
    return images[0], images[1], stats


def _same_image(off: np.ndarray, on: np.ndarray, stats: dict, *, min_empty: float = 0.3) -> None:
    assert stats["active"], stats
    assert stats["empty_fraction"] >= min_empty, stats
    assert off.max() > 60, "the phantom must be visible"
    diff = np.abs(off - on)
    assert diff.max() <= 1, (diff.max(), int((diff > 1).sum()))


def _nothing(vol, il) -> None:
    pass


@pytest.mark.gl
@pytest.mark.parametrize("method", ["local", "shadow_volume", "cone_traced", "translucency",
                                    "hybrid_diffusion"])
def test_techniques_render_the_same_image(method: str) -> None:
    """Surface techniques (local, shadow volume, cone tracing, translucency) and a medium
    one (hybrid diffusion, refined to convergence first)."""
    off, on, stats = _render_pair(_nothing, method)
    _same_image(off, on, stats)


def _blend(mode: str) -> Callable:
    def configure(vol, il) -> None:
        import vtk

        mapper = vol.GetMapper()
        mapper.SetBlendMode(getattr(vtk.vtkVolumeMapper, mode))
    return configure


@pytest.mark.gl
@pytest.mark.parametrize("mode", ["MAXIMUM_INTENSITY_BLEND", "ADDITIVE_BLEND"])
def test_blend_modes_with_exact_zero_contributions(mode: str) -> None:
    """MIP (non-decreasing opacity: the maximum of the samples left is the maximum, or both
    classify to 0) and additive (a zero-opacity sample adds 0)."""
    off, on, stats = _render_pair(_blend(mode))
    _same_image(off, on, stats)


@pytest.mark.gl
def test_blends_that_count_every_sample_are_left_alone() -> None:
    """Average intensity counts zero-opacity samples; MIP with an opacity band (zero above it)
    would take a different maximum: both keep the full march, and say so."""
    off, on, stats = _render_pair(_blend("AVERAGE_INTENSITY_BLEND"))
    assert not stats["active"] and "average" in stats["reason"]
    assert np.array_equal(off, on)

    def banded_mip(vol, il) -> None:
        _blend("MAXIMUM_INTENSITY_BLEND")(vol, il)
        otf = vol.GetProperty().GetScalarOpacity()
        otf.RemoveAllPoints()
        for x, y in ((0, 0), (30, 0), (60, 1), (100, 0), (255, 0)):
            otf.AddPoint(x, y)

    off, on, stats = _render_pair(banded_mip)
    assert not stats["active"] and "non-decreasing" in stats["reason"]


def _crop(vol, il) -> None:
    mapper = vol.GetMapper()
    mapper.SetCropping(1)
    mapper.SetCroppingRegionPlanes(4.0, 30.0, 0.0, 47.0, 10.0, 40.0)
    mapper.SetCroppingRegionFlagsToSubVolume()


def _weights(vol, il) -> None:
    w = np.ones((3, 16), np.float32)
    w[0, :6] = 0.0
    w[2] = np.linspace(0.2, 1.0, 16)
    il.set_slice_weights(w)


def _clip(vol, il) -> None:
    import vtk

    plane = vtk.vtkPlane()
    plane.SetOrigin(24.0, 24.0, 24.0)
    plane.SetNormal(0.3, 0.5, 0.8)
    planes = vtk.vtkPlaneCollection()
    planes.AddItem(plane)
    vol.GetMapper().SetClippingPlanes(planes)


def _jitter(vol, il) -> None:
    vol.GetMapper().SetUseJittering(1)


def _corrected(vol, il) -> None:
    il.set_interpolation("corrected")


@pytest.mark.gl
@pytest.mark.parametrize("configure", [_crop, _weights, _clip, _jitter, _corrected],
                         ids=["crop", "slice_weights", "clip_plane", "jitter", "corrected"])
def test_crop_weights_jitter_and_filter(configure: Callable) -> None:
    off, on, stats = _render_pair(configure, "shadow_volume")
    _same_image(off, on, stats)


@pytest.mark.gl
def test_crop_empties_bricks_the_transfer_function_keeps() -> None:
    _, _, plain = _render_pair(_nothing)
    _, _, cropped = _render_pair(_crop)
    assert cropped["empty_fraction"] > plain["empty_fraction"] + 0.1


@pytest.mark.gl
def test_two_independent_channels() -> None:
    """Two channels, one TF each; the second channel's blobs are elsewhere."""
    a = sparse_phantom(40, seed=1)
    b = sparse_phantom(40, seed=7)
    arr = np.stack([a, b], axis=-1)

    def two(vol, il) -> None:
        import vtk

        prop = vol.GetProperty()
        prop.SetIndependentComponents(1)
        for c, color in ((0, (1, 0.3, 0.2)), (1, (0.2, 1.0, 0.3))):
            otf = vtk.vtkPiecewiseFunction()
            otf.AddPoint(0, 0)
            otf.AddPoint(40, 0)
            otf.AddPoint(255, 0.8)
            ctf = vtk.vtkColorTransferFunction()
            ctf.AddRGBPoint(0, *color)
            ctf.AddRGBPoint(255, *color)
            prop.SetScalarOpacity(c, otf)
            prop.SetColor(c, ctf)

    off, on, stats = _render_pair(two, array=arr)
    _same_image(off, on, stats, min_empty=0.1)


@pytest.mark.gl
def test_the_grid_is_what_the_ray_caster_skips(monkeypatch) -> None:
    """The equality above can fail: the shader really jumps over what the grid calls empty
    (declaring every brick empty makes the volume vanish)."""
    monkeypatch.setattr(occupancy, "transfer_occupancy",
                        lambda ranges, *a: np.zeros(ranges.bricks_zyx, bool))
    off, on, stats = _render_pair(_nothing)
    assert stats["empty_fraction"] == 1.0
    assert off.max() > 60 and on.max() == 0


@pytest.mark.gl
def test_no_exactness_loss_with_a_tf_edge_inside_the_data() -> None:
    """A TF ramp that starts right at a common data value (the table interpolation makes the
    GPU's opacity non-zero half an entry early): still exact."""
    arr = sparse_phantom()
    for start in (12.0, 50.0, 120.0):
        off, on, stats = _render_pair(_nothing, array=arr,
                                      opacity=[(0.0, 0.0), (start, 0.0), (start + 1.0, 0.6)])
        _same_image(off, on, stats, min_empty=0.2)


# -- the setting -------------------------------------------------------------------------------
def test_render_setting_default_and_validation() -> None:
    from pydantic import ValidationError

    from vtkvol.model.scene import RenderSettings

    assert RenderSettings().empty_space_skipping is True
    with pytest.raises(ValidationError):
        RenderSettings(empty_space_skipping="sometimes")


@pytest.mark.gl
def test_scene_follows_the_model_setting() -> None:
    import vtk

    from vtkvol.engine.offscreen import grab, make_render_window
    from vtkvol.engine.scene import VolumeScene
    from vtkvol.io import VolumeData
    from vtkvol.model.defaults import scene_for

    data = VolumeData.from_array(sparse_phantom(32)[None], (0.5, 0.5, 1.0), ["beads"])
    model = scene_for(data)
    rw = make_render_window((96, 96))
    ren = vtk.vtkRenderer()
    rw.AddRenderer(ren)
    scene = VolumeScene(ren, model, data, request_render=lambda: None)
    try:
        il = scene.illuminator
        assert il is not None and il.empty_space_skipping
        grab(rw)
        grab(rw)
        assert "vtkvol<host_empty_space.glsl>" in il.fragment_source
        model.render.empty_space_skipping = False
        assert not il.empty_space_skipping
        grab(rw)
        grab(rw)
        assert "vtkvol<host_empty_space.glsl>" not in il.fragment_source
        assert il.empty_space_stats() == {"active": False, "reason": "switched off"}
    finally:
        scene.close()
        rw.Finalize()


@pytest.mark.gui
def test_channels_dock_checkbox(qapp) -> None:
    """The channels dock's render settings show the switch and set it, both ways."""
    from vtkvol.model.scene import SceneModel
    from vtkvol.ui.docks.channels import ChannelsDock

    model = SceneModel()
    dock = ChannelsDock(model)
    try:
        assert dock.skip_empty.isChecked()
        dock.skip_empty.setChecked(False)
        assert model.render.empty_space_skipping is False
        model.render.empty_space_skipping = True
        assert dock.skip_empty.isChecked()
    finally:
        dock.deleteLater()


def test_bricks_are_near_cubes_in_space() -> None:
    assert occupancy.brick_for_spacing((0.1, 0.1, 0.1)) == (8, 8, 8)
    # A confocal stack with 5.6× coarser z: 8 × 8 voxels in x, y and 2 (not 1.4) in z.
    assert occupancy.brick_for_spacing((0.0225, 0.0225, 0.125)) == (2, 8, 8)
    assert occupancy.brick_for_spacing((-0.5, 1.0, 0.25)) == (8, 2, 4)  # (z, y, x)
    ranges = occupancy.brick_ranges(np.zeros((5, 17, 9)), brick=(2, 8, 8))
    assert ranges.bricks_zyx == (3, 3, 2)


@pytest.mark.gl
def test_anisotropic_bricks_render_the_same_image() -> None:
    off, on, stats = _render_pair(_nothing, "shadow_volume", spacing=(0.5, 0.5, 2.0))
    assert stats["brick_voxels"] == (8, 8, 2)
    _same_image(off, on, stats)


@pytest.mark.gl
def test_bench_measures_both_sides_and_writes_a_section(tmp_path) -> None:
    """`vtkvol bench --empty-space` (tiny): both sides timed, the images equal, the section
    and the JSON lists written, other results kept."""
    import json

    from vtkvol.bench import empty_space
    from vtkvol.bench.scenes import Scene

    (tmp_path / "benchmarks.json").write_text(json.dumps(
        {"format": "vtkvol-bench", "version": 1, "runs": [], "records": [],
         "stability": [], "scattering_runs": [{"renderer": "x", "mode": "quick"}]}))
    config = empty_space.SkipConfig("quick", 24, 64, 1, 1, ("local",))
    beads = Scene("beads", sparse_phantom(32), (1.0, 1.0, 1.0),
                  [(0.0, 0.0), (30.0, 0.0), (255.0, 0.8)], "sparse blobs")
    result = empty_space.run(config, tmp_path, [beads], progress=False)
    (rec,) = result["records"]
    assert rec["ok"] and rec["active"] and rec["max_abs"] <= 1, rec
    assert rec["frame_off_ms"] > 0 and rec["cpu_on_ms"] > 0 and rec["ratio"] > 0
    doc = json.loads((tmp_path / "benchmarks.json").read_text())
    assert len(doc["empty_space"]) == 1 and len(doc["empty_space_runs"]) == 1
    assert doc["scattering_runs"] == [{"renderer": "x", "mode": "quick"}]
    md = (tmp_path / "benchmarks.md").read_text()
    assert "## Empty-space skipping (quick," in md and "| beads |" in md


def test_max_over_intervals_with_thousands_of_nodes() -> None:
    """A label transfer function (a spike per id) is answered by a range-maximum query."""
    ids = np.arange(1, 4001, dtype=np.float64)
    xs = np.sort(np.concatenate([ids - 0.4, ids, ids + 0.4, [0.0]]))
    ys = np.where(np.isin(xs, ids), np.random.default_rng(1).uniform(0.1, 1, xs.size), 0.0)
    rng = np.random.default_rng(2)
    lo = np.concatenate([rng.uniform(0, 4000, 3000), [-1.0, 5.0]])
    hi = np.concatenate([lo[:3000] + rng.exponential(3, 3000), [5000.0, 4000.0]])
    got = occupancy.max_over_intervals(xs, ys, lo, hi)
    want = np.array([max(np.interp([a, b], xs, ys).max(),
                         ys[(xs >= a) & (xs <= b)].max(initial=0.0)) for a, b in
                     zip(lo, hi, strict=True)])
    assert np.array_equal(got, want)
    assert (got == 0).any() and (got > 0).any()


@pytest.mark.gl
def test_a_gl_failure_of_the_grid_leaves_the_full_march(monkeypatch) -> None:
    """An occupancy texture that cannot be made is reported in the stats and logged; the view
    renders the full march (the same image)."""
    from vtkvol.engine import empty_space
    from vtkvol.engine.gl import GLUnavailableError

    def broken(*args, **kwargs):
        raise GLUnavailableError("could not allocate a 6×6×6×1 float 3D texture")

    monkeypatch.setattr(empty_space, "Texture3D", broken)
    off, on, stats = _render_pair(_nothing)
    assert not stats["active"] and "could not allocate" in stats["reason"]
    assert np.array_equal(off, on) and off.max() > 60


@pytest.mark.gl
def test_dense_data_keeps_the_full_march() -> None:
    """With (almost) nothing empty the per-sample check would only cost: skipping stays out
    of the shader and says why."""
    dense = np.full((32, 32, 32), 40, np.uint8)
    dense[8:24, 8:24, 8:24] = 200
    off, on, stats = _render_pair(_nothing, array=dense)
    assert not stats["active"] and stats["empty_fraction"] == 0.0
    assert "only 0 % of the bricks are empty" in stats["reason"]
    assert np.array_equal(off, on)


@pytest.mark.gl
def test_opacity_volume_data_with_a_ramp_from_zero() -> None:
    """The bench's sphere over slab: float opacity data, identity transfer function 0 → 0,
    1 → 1. The background (exactly 0, the table's first value) is skipped, exactly."""
    from vtkvol.bench.scenes import phantom_scenes

    scene = phantom_scenes(48)[0]
    off, on, stats = _render_pair(_nothing, "shadow_volume", array=scene.data,
                                  opacity=scene.opacity_points)
    _same_image(off, on, stats, min_empty=0.3)


@pytest.mark.parametrize("value", [1, "yes", None, [True]])
def test_a_session_with_a_bad_switch_is_refused_in_one_line(tmp_path, value) -> None:
    """The switch is strict like the other settings: 1 or "yes" is not true."""
    import json
    from pathlib import Path

    from vtkvol.model.session import SessionError, read_session

    fixture = Path(__file__).parent / "fixtures" / "sessions" / "v6_complete.vtkvol.json"
    doc = json.loads(fixture.read_text(encoding="utf-8"))
    doc["scene"]["render"]["empty_space_skipping"] = value
    path = tmp_path / "v.vtkvol.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(SessionError, match=r"^v\.vtkvol\.json: ") as info:
        read_session(path)
    message = str(info.value)
    assert "render.empty_space_skipping" in message and "\n" not in message
