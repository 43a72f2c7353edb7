"""The opacity source: what the volume absorbs, as the ray caster classifies it.

One service of the technique host (:class:`vtkvol.engine.illuminator.Illuminator` owns one):
the data, its transfer functions (1-D, with gradient opacity, or 2-D tables), the mapper's
cropping regions and clipping planes and the slice weights become per-voxel opacity, either in
numpy (:meth:`OpacitySource.opacity_volume`, the reference) or on the GPU
(:meth:`OpacitySource.opacity_texture`, ``vtkvol.engine.classify``). Results are cached under
:meth:`OpacitySource.signature`, which changes exactly when one of those inputs does. VTK's
counterpart is ``vtkOpenGLVolumeLookupTables`` with the mapper's cropping and clipping.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Generator
from typing import Any, Literal

import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

from vtkvol.engine import classify, tf2d
from vtkvol.engine.gl import GLUnavailableError, Texture3D, compute_supported, gl
from vtkvol.engine.technique import run_steps

# The warnings keep the host's logger name: applications and tests filter on it.
logger = logging.getLogger("vtkvol.engine.illuminator")

#: Voxels per chunk of :meth:`Illuminator.opacity_volume_steps` (about 0.1 s of numpy).
OPACITY_SLAB_VOXELS = 1 << 21


def _clipping_signature(mapper: vtk.vtkVolumeMapper) -> tuple:
    planes = mapper.GetClippingPlanes()
    if planes is None:
        return ()
    return tuple(
        (tuple(planes.GetItem(k).GetOrigin()), tuple(planes.GetItem(k).GetNormal()))
        for k in range(planes.GetNumberOfItems())
    )


#: Largest component (voxels) whose 2-D table coordinates are kept between TF edits (256 MB).
_COORDS_CACHE_VOXELS = 32 * 1024 * 1024


def gradient_opacity_on(prop: vtk.vtkVolumeProperty, c: int) -> bool:
    """True when VTK multiplies component ``c``'s opacity by a gradient-opacity function
    (1-D mode; VTK ignores it in 2-D mode)."""
    return bool(prop.HasGradientOpacity(c)) and not prop.GetDisableGradientOpacity(c)


def _evaluate_piecewise(function: vtk.vtkPiecewiseFunction, values: np.ndarray) -> np.ndarray:
    """Evaluate a (linear) piecewise function on an array; integer data through a lookup table."""
    n = function.GetSize()
    if n == 0:
        return np.zeros(values.shape, np.float32)
    nodes = np.array([_node(function, i) for i in range(n)])
    xs, ys = nodes[:, 0], nodes[:, 1]
    if values.dtype.kind in "ui" and values.dtype.itemsize <= 2:
        info = np.iinfo(values.dtype)
        table = np.interp(np.arange(info.min, info.max + 1, dtype=np.float64), xs, ys)
        table = table.astype(np.float32)
        return table[values.astype(np.int64) - info.min] if info.min else table[values]
    finite = np.where(np.isfinite(values), values, xs[0])
    return np.interp(finite, xs, ys).astype(np.float32)


def _node(function: vtk.vtkPiecewiseFunction, i: int) -> list[float]:
    node = [0.0] * 4
    function.GetNodeValue(i, node)
    return node


def _axis_weight_vectors(weights: np.ndarray, shape_zyx: tuple[int, int, int]
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """wX(x), wY(y), wZ(z) sampled at voxel centres."""
    nz, ny, nx = shape_zyx
    grid = np.linspace(0.0, 1.0, weights.shape[1])

    def sample(row: np.ndarray, n: int) -> np.ndarray:
        return np.interp(np.linspace(0.0, 1.0, n), grid, row).astype(np.float32)

    return sample(weights[0], nx), sample(weights[1], ny), sample(weights[2], nz)


class OpacitySource:
    """Classification, crop, clip and slice weights of one illuminated volume, with caches.

    ``host`` supplies the VTK objects (``volume``, ``image``, ``spacing``, ``dims``,
    ``render_window``), the slice weights and whether :meth:`Illuminator.precompute` runs its
    chunks; the source owns the numpy cache, the GPU classifier and the opacity texture."""

    def __init__(self, host: Any) -> None:
        # The host (engine/illuminator.py), typed loosely: importing it here would close an
        # import circle (scripts/import_graph.py).
        self._host = host
        self._opacity_cache: tuple[tuple, np.ndarray] | None = None
        #: Classification backend of :meth:`opacity_texture` ("auto", "gpu", "cpu").
        self._classification = "auto"
        self._classifier: classify.GpuClassifier | None = None
        self._classify_failed = ""  # why the GPU classification is off for good ("" = not)
        self._opacity_texture: Texture3D | None = None
        self._opacity_texture_key: tuple | None = None
        self._classify_stats: dict[str, Any] = classify.stats_template()
        #: Per component, VTK's table coordinates (s, t) of every voxel: they depend on the
        #: data only, so a 2-D TF edit pays the lookup, not the gradient.
        self._coords_cache: dict[int, tuple[tuple, tuple[np.ndarray, np.ndarray]]] = {}

    def opacity_volume(self) -> np.ndarray:
        """Per-voxel opacity (per ``unit_distance`` µm) as the ray caster sees it.

        float32 ``[z, y, x]``: every visible component classified as VTK's shader does and
        combined as independent absorbers (α = 1 − Π(1 − α_c)), then zeroed outside the
        cropping box and multiplied by the slice weights, so what is cropped away casts no
        shadow. Classification (docs/transfer-functions-2d.md): in 1-D mode the scalar
        opacity function times the gradient-opacity function, if one is set; in 2-D mode the
        component's (value, gradient magnitude) table, looked up bilinearly at VTK's
        coordinates. Gradients are VTK's central differences at the voxel centres. Cached
        until an input changes.
        """
        return run_steps(self.opacity_volume_steps())

    def opacity_volume_steps(self) -> Generator[float, None, np.ndarray]:
        """:meth:`opacity_volume` in slabs of z slices (for ``prepare_steps``): yields the
        fraction done after each slab of about :data:`OPACITY_SLAB_VOXELS` voxels and returns
        the volume (``opacity = yield from host.opacity_volume_steps()``). A cached volume
        returns at once."""
        key = self.signature()
        if self._opacity_cache is not None and self._opacity_cache[0] == key:
            return self._opacity_cache[1]
        img = self._host.image
        nx, ny, nz = img.GetDimensions()
        scalars = img.GetPointData().GetScalars()
        if scalars is None:
            raise RuntimeError("the volume's input image has no point scalars")
        values = vtk_to_numpy(scalars).reshape(nz, ny, nx, -1)
        prop = self._host.volume.GetProperty()
        ncomp = values.shape[-1]
        independent = ncomp == 1 or bool(prop.GetIndependentComponents())
        two_d = prop.GetTransferFunctionMode() == vtk.vtkVolumeProperty.TF_2D
        if two_d and not independent:
            raise ValueError(
                "2-D transfer functions need independent components: VTK classifies "
                f"dependent {ncomp}-component data (RGB/RGBA colour) without a 2-D table")
        spacing = self._host.spacing
        step = float(self._host.volume.GetMapper().GetSampleDistance())
        u0 = prop.GetScalarOpacityUnitDistance(0)
        comps = range(ncomp) if independent else [ncomp - 1]
        # What classifies each component, over the whole volume: gradients need the
        # neighbouring slices, which a slab does not hold.
        tables: dict[int, np.ndarray] = {}
        coords: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        gradients: dict[int, np.ndarray] = {}  # |g| in data units, for gradient opacity
        for c in comps:
            fc = c if independent else 0
            value_range = scalars.GetRange(c)
            if two_d and prop.GetTransferFunction2D(fc) is not None:
                tables[c] = tf2d.unit_alpha_table(prop.GetTransferFunction2D(fc), step,
                                                  prop.GetScalarOpacityUnitDistance(fc))
                coords[c] = self._table_coords(c, values[..., c], spacing, value_range)
            elif gradient_opacity_on(prop, fc):
                # VTK's table spans |g| in 0…¼·range and |g| is clamped to it.
                span = float(value_range[1] - value_range[0]) or 1.0
                gradients[c] = tf2d.normalised_gradient(values[..., c], spacing, value_range) * (
                    np.float32(tf2d.GRADIENT_RANGE_FRACTION * span))
        weights = _axis_weight_vectors(self._host._weights, (nz, ny, nx)) if (
            self._host._weights is not None) else None
        opacity = np.empty((nz, ny, nx), np.float32)
        slab = max(1, OPACITY_SLAB_VOXELS // max(1, nx * ny))
        for z0 in range(0, nz, slab):
            z1 = min(nz, z0 + slab)
            transparency = np.ones((z1 - z0, ny, nx), np.float32)
            for c in comps:
                fc = c if independent else 0
                weight = prop.GetComponentWeight(fc) if independent and ncomp > 1 else 1.0
                if weight <= 0:
                    continue
                if c in tables:
                    s, t = coords[c]
                    alpha = tf2d.lookup(tables[c], s[z0:z1], t[z0:z1])
                else:
                    alpha = _evaluate_piecewise(prop.GetScalarOpacity(fc), values[z0:z1, ..., c])
                    if c in gradients:
                        alpha = alpha * _evaluate_piecewise(prop.GetGradientOpacity(fc),
                                                            gradients[c][z0:z1])
                alpha = alpha * weight
                uc = prop.GetScalarOpacityUnitDistance(fc)
                if uc != u0:  # express every component per the same unit distance
                    alpha = 1.0 - np.power(1.0 - np.clip(alpha, 0, 1), u0 / uc)
                transparency *= 1.0 - np.clip(alpha, 0.0, 1.0)
            part = opacity[z0:z1]
            np.subtract(1.0, transparency, out=part)
            self._apply_crop(part, z0)
            if weights is not None:
                wx, wy, wz = weights
                part *= wz[z0:z1, None, None] * wy[None, :, None] * wx[None, None, :]
            yield z1 / nz
        self._opacity_cache = (key, opacity)
        return opacity

    @property
    def classification(self) -> str:
        """Backend of :meth:`opacity_texture`: ``"auto"`` (the compute shader where the
        context runs compute shaders and the volume allows it, else numpy with one logged
        warning), ``"gpu"`` (the compute shader or an error) or ``"cpu"`` (numpy, uploaded).
        An engine choice, not a session setting; :meth:`opacity_volume` is always numpy."""
        return self._classification

    @classification.setter
    def classification(self, backend: str) -> None:
        if backend not in ("auto", "gpu", "cpu"):
            raise ValueError(f"classification must be 'auto', 'gpu' or 'cpu', not {backend!r}")
        if backend != self._classification:
            self._classification = backend
            self._opacity_texture_key = None  # the next request classifies anew
            self._host.changes.pending.opacity = True  # and the technique recomputes from it

    def classification_stats(self) -> dict[str, Any]:
        """The opacity texture's classification: ``backend`` of the last one ("gpu"/"cpu"),
        ``reason`` (why not on the GPU, or ""), counters ``gpu_classifications``,
        ``cpu_classifications``, ``scalar_uploads`` (data sets uploaded for the shader),
        ``opacity_uploads`` (numpy volumes uploaded), ``classify_ms`` (wall time of the last
        classification, issuing only unless chunked), ``scalar_upload_ms`` and
        ``scalar_bytes`` (GPU memory of the scalar copy)."""
        return dict(self._classify_stats)

    def opacity_texture(self, quantity: str = "alpha") -> Texture3D:
        """:meth:`opacity_volume` as a host-owned r32f 3-D texture of the data's shape (voxel
        centres at texel centres; context current), classified on the GPU
        (:attr:`classification`). ``quantity``: ``"alpha"`` (the opacity per unit distance)
        or ``"optical_depth"``, s = −ln(1 − α) with α clamped at 1 − 10⁻⁶ (the extinction
        grid of the shadow volume, converted in the same pass). Cached until an input or
        the quantity changes; valid until the next call, the technique's release or
        :meth:`release`. Techniques read it, never release it."""
        return run_steps(self.opacity_texture_steps(quantity))

    def opacity_texture_steps(self, quantity: str = "alpha"
                              ) -> Generator[float, None, Texture3D]:
        """:meth:`opacity_texture` in chunks (for ``prepare_steps``; each chunk waited for
        while :attr:`precomputing`): ``tex = yield from host.opacity_texture_steps()``."""
        if quantity not in classify.QUANTITIES:
            raise ValueError(f"quantity must be one of {classify.QUANTITIES}, not {quantity!r}")
        key = (self.signature(), self._classification, quantity)
        tex = self._opacity_texture
        if tex is not None and tex.tex is not None and key == self._opacity_texture_key:
            return tex
        window = self._host.render_window
        if window is None:
            raise RuntimeError("the opacity texture needs a rendered frame (a GL context)")
        nx, ny, nz = self._host.dims
        if tex is None or tex.tex is None or tex.shape != (nz, ny, nx):
            if tex is not None:
                tex.release()
            self._opacity_texture = tex = None
            self._opacity_texture_key = None
            tex = Texture3D(window, (nz, ny, nx))
            self._opacity_texture = tex
        chunked = self._host.precomputing
        stats = self._classify_stats
        t0 = time.perf_counter()
        classifier = self._gpu_classifier()
        if classifier is not None:
            uploads = classifier.scalar_uploads
            try:
                plan = self._classification_plan(quantity)
                yield from classifier.run_steps(plan, self._host.image, tex, chunked=chunked)
            except GLUnavailableError as exc:
                if self._classification == "gpu":
                    raise
                self._disable_gpu_classification(str(exc).splitlines()[0])
                classifier = None
            else:
                stats.update(backend="gpu", reason="",
                             gpu_classifications=stats["gpu_classifications"] + 1,
                             scalar_uploads=stats["scalar_uploads"]
                             + classifier.scalar_uploads - uploads,
                             scalar_upload_ms=classifier.upload_ms,
                             scalar_bytes=classifier.scalar_bytes)
        if classifier is None:
            opacity = yield from self.opacity_volume_steps()
            if quantity == "optical_depth":
                opacity = classify.optical_depth(opacity)
            if chunked:
                slab = max(1, OPACITY_SLAB_VOXELS // max(1, nx * ny))
                for z0 in range(0, nz, slab):
                    tex.upload_slab(opacity[z0:z0 + slab], z0)
                    gl(window).glFinish()
                    yield min(1.0, (z0 + slab) / nz)
            else:
                tex.upload(opacity)
            tex.tex.Deactivate()
            stats.update(backend="cpu", cpu_classifications=stats["cpu_classifications"] + 1,
                         opacity_uploads=stats["opacity_uploads"] + 1)
        stats["classify_ms"] = (time.perf_counter() - t0) * 1e3
        self._opacity_texture_key = key
        return tex

    def release(self) -> None:
        """Free the opacity texture and the classifier's scalars, tables and programs (with the
        technique that used them: local shading holds no data-sized GPU memory of ours)."""
        if self._opacity_texture is not None:
            self._opacity_texture.release()
            self._opacity_texture = None
        self._opacity_texture_key = None
        if self._classifier is not None:
            self._classifier.release()
            self._classifier = None

    def _gpu_classifier(self) -> classify.GpuClassifier | None:
        """The GPU classifier when :attr:`classification` and this volume allow it (else None,
        with the reason in the stats: one warning per reason)."""
        stats = self._classify_stats
        if self._classification == "cpu":
            stats["reason"] = "classification = 'cpu'"
            return None
        host = self._host
        reason = self._classify_failed or classify.unsupported_reason(host.volume, host.image)
        if reason:
            return self._numpy_classification(reason)
        if self._classifier is None:
            window = self._host.render_window
            assert window is not None
            if not compute_supported(window):
                self._disable_gpu_classification("this OpenGL context has no compute shaders")
                return self._gpu_classifier()
            self._classifier = classify.GpuClassifier(window)
        too_large = self._classifier.unsupported(self._host.image)
        if too_large:
            return self._numpy_classification(too_large)
        return self._classifier

    def _numpy_classification(self, reason: str) -> None:
        """The GPU cannot classify this volume for ``reason``: an error when
        :attr:`classification` is ``"gpu"``, else numpy classifies (one warning per reason)."""
        if self._classification == "gpu":
            raise GLUnavailableError(f"GPU classification is not possible: {reason}")
        if self._classify_stats["reason"] != reason:
            logger.warning("vtkvol: classification on the CPU (numpy): %s", reason)
        self._classify_stats["reason"] = reason

    def _disable_gpu_classification(self, why: str) -> None:
        self._classify_failed = why
        if self._classifier is not None:
            self._classifier.release()
            self._classifier = None
        logger.warning("vtkvol: GPU classification unavailable, classifying with numpy (%s)",
                       why)
        self._classify_stats["reason"] = why

    def _classification_plan(self, quantity: str = "alpha") -> classify.Plan:
        """Tables and per-axis rows of the current transfer functions, crop and weights."""
        mapper = self._host.volume.GetMapper()
        img = self._host.image
        nx, ny, nz = img.GetDimensions()
        weights = _axis_weight_vectors(self._host._weights, (nz, ny, nx)) if (
            self._host._weights is not None) else None
        regions = None
        flags = 0
        if mapper.GetCropping():
            regions = tuple(self._crop_regions(axis, n, 0)
                            for axis, n in enumerate((nx, ny, nz)))
            flags = int(mapper.GetCroppingRegionFlags())
        return classify.build_plan(self._host.volume, img, weights, regions, flags,
                                   self._clip_coefficients(), quantity)

    def _crop_regions(self, axis: int, n: int, first: int) -> np.ndarray:
        """Cropping region (0 below the first plane, 1 between, 2 above) of the voxel indices
        ``first…first + n`` along ``axis``."""
        img = self._host.image
        origin, spacing = img.GetOrigin(), img.GetSpacing()
        planes = self._host.volume.GetMapper().GetCroppingRegionPlanes()
        coord = origin[axis] + spacing[axis] * np.arange(first, first + n)
        lo, hi = planes[2 * axis], planes[2 * axis + 1]
        tol = 1e-6 * spacing[axis]
        return (coord >= lo - tol).astype(np.int64) + (coord > hi + tol).astype(np.int64)

    def _clip_coefficients(self) -> list[tuple[float, float, float, float]]:
        """Each clipping plane's side as ``a·i + b·j + c·k + d`` of the voxel index (i, j, k)
        (world space through the volume's matrix; VTK keeps side ≥ 0), in float64."""
        clipping = self._host.volume.GetMapper().GetClippingPlanes()
        if clipping is None or not clipping.GetNumberOfItems():
            return []
        img = self._host.image
        origin, spacing = np.array(img.GetOrigin()), np.array(img.GetSpacing())
        matrix = self._host.volume.GetMatrix()
        m = np.array([[matrix.GetElement(i, j) for j in range(4)] for i in range(4)])
        out = []
        for k in range(clipping.GetNumberOfItems()):
            plane = clipping.GetItem(k)
            o, n = np.array(plane.GetOrigin()), np.array(plane.GetNormal())
            per_index = (n @ m[:3, :3]) * spacing
            const = float(n @ (m[:3, :3] @ origin + m[:3, 3] - o))
            out.append((*(float(v) for v in per_index), const))
        return out

    def classify_2d(self, c: int, what: Literal["alpha", "rgb"] = "alpha") -> np.ndarray | None:
        """Component ``c``'s 2-D table read at every voxel as VTK's shader reads it (its
        gradient, its texture coordinates, bilinear): ``"alpha"`` per ``unit_distance`` of the
        component, float32 ``[z, y, x]``, or ``"rgb"`` in 0…1, ``[z, y, x, 3]``. ``None`` when
        the property is not in 2-D mode or holds no table for ``c``. The opacity volume (slab by
        slab) and every technique that needs the colour (translucency's tint) read the tables
        at the same cached coordinates (``_table_coords``), so they agree voxel for voxel
        (docs/transfer-functions-2d.md)."""
        prop = self._host.volume.GetProperty()
        image = prop.GetTransferFunction2D(c)
        if prop.GetTransferFunctionMode() != vtk.vtkVolumeProperty.TF_2D or image is None:
            return None
        img = self._host.image
        nx, ny, nz = img.GetDimensions()
        scalars = img.GetPointData().GetScalars()
        values = vtk_to_numpy(scalars).reshape(nz, ny, nx, -1)[..., c]
        if what == "rgb":
            table = tf2d.rgb_table(image)
        else:
            step = float(self._host.volume.GetMapper().GetSampleDistance())
            table = tf2d.unit_alpha_table(image, step, prop.GetScalarOpacityUnitDistance(c))
        return self._lookup_2d(table, c, values, scalars.GetRange(c))

    def _lookup_2d(self, table: np.ndarray, c: int, values: np.ndarray,
                   value_range: tuple[float, float]) -> np.ndarray:
        """``table`` ``(h, w[, k])`` read bilinearly at component ``c``'s VTK coordinates."""
        return tf2d.lookup(table, *self._table_coords(c, values, self._host.spacing, value_range))

    def _table_coords(self, c: int, values: np.ndarray, spacing: tuple[float, float, float],
                      value_range: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
        """VTK's 2-D table coordinates (s, t) of component ``c``'s voxels, cached per data."""
        key = (self._host.image.GetMTime(), values.shape, spacing, tuple(value_range))
        cached = self._coords_cache.get(c)
        if cached is None or cached[0] != key:
            coords = (tf2d.normalised_values(values, value_range),
                      tf2d.normalised_gradient(values, spacing, value_range))
            if values.size > _COORDS_CACHE_VOXELS:
                return coords  # 8 bytes a voxel: large volumes recompute instead
            self._coords_cache[c] = cached = (key, coords)
        return cached[1]

    def _apply_crop(self, opacity: np.ndarray, z0: int = 0) -> None:
        """Zero what the mapper does not show: its cropping regions (any of VTK's 27-region
        flags, not only the sub-volume) and its clipping planes. ``opacity`` holds the z
        slices from ``z0`` on."""
        mapper = self._host.volume.GetMapper()
        img = self._host.image
        origin, spacing = img.GetOrigin(), img.GetSpacing()
        nz, ny, nx = opacity.shape
        if mapper.GetCropping():
            flags = int(mapper.GetCroppingRegionFlags())
            region = [self._crop_regions(axis, n, z0 if axis == 2 else 0)
                      for axis, n in enumerate((nx, ny, nz))]
            index = (region[0][None, None, :] + 3 * region[1][None, :, None]
                     + 9 * region[2][:, None, None])
            visible = np.array([(flags >> i) & 1 for i in range(27)], bool)
            opacity[~visible[index]] = 0.0
        clipping = mapper.GetClippingPlanes()
        if clipping is not None and clipping.GetNumberOfItems():
            # Clipping planes are in world space; VTK keeps the side the normal points to.
            matrix = self._host.volume.GetMatrix()
            m = np.array([[matrix.GetElement(i, j) for j in range(4)] for i in range(4)])
            x = origin[0] + spacing[0] * np.arange(nx)
            y = origin[1] + spacing[1] * np.arange(ny)
            z = origin[2] + spacing[2] * np.arange(z0, z0 + nz)
            world = [m[i, 0] * x[None, None, :] + m[i, 1] * y[None, :, None]
                     + m[i, 2] * z[:, None, None] + m[i, 3] for i in range(3)]
            for k in range(clipping.GetNumberOfItems()):
                plane = clipping.GetItem(k)
                o, n = plane.GetOrigin(), plane.GetNormal()
                side = sum((world[i] - o[i]) * n[i] for i in range(3))
                opacity[np.broadcast_to(side < 0, opacity.shape)] = 0.0

    def signature(self) -> tuple:
        """Cheap key of every input of the opacity (VTK modification times, crop, clip,
        matrix, slice-weights version): equal keys, equal opacity."""
        mapper = self._host.volume.GetMapper()
        prop = self._host.volume.GetProperty()
        img = self._host.image
        ncomp = img.GetPointData().GetScalars().GetNumberOfComponents() if img else 0
        funcs = tuple(prop.GetScalarOpacity(c).GetMTime() for c in range(max(1, ncomp)))
        if prop.GetTransferFunctionMode() == vtk.vtkVolumeProperty.TF_2D:
            tables = tuple(
                tf2d.unit_alpha_mtime(prop.GetTransferFunction2D(c))
                if prop.GetTransferFunction2D(c) is not None else None
                for c in range(max(1, ncomp)))
            # A foreign table holds alpha per step: its conversion depends on the step.
            classification: tuple = ("2d", tables, float(mapper.GetSampleDistance()) if any(
                prop.GetTransferFunction2D(c) is not None and prop.GetTransferFunction2D(c)
                .GetPointData().GetArray(tf2d.UNIT_ALPHA_ARRAY) is None
                for c in range(max(1, ncomp))) else None)
        else:
            classification = ("1d", tuple(
                prop.GetGradientOpacity(c).GetMTime() if gradient_opacity_on(prop, c) else None
                for c in range(max(1, ncomp))))
        weights = tuple(prop.GetComponentWeight(c) for c in range(max(1, ncomp)))
        units = tuple(prop.GetScalarOpacityUnitDistance(c) for c in range(max(1, ncomp)))
        matrix = self._host.volume.GetMatrix()
        return (
            img.GetMTime(),
            funcs,
            classification,
            weights,
            units,
            bool(prop.GetIndependentComponents()),
            bool(mapper.GetCropping()),
            tuple(mapper.GetCroppingRegionPlanes()),
            int(mapper.GetCroppingRegionFlags()),
            _clipping_signature(mapper),
            tuple(matrix.GetElement(i, j) for i in range(4) for j in range(4)),
            self._host._weights_version,
        )

    def clear_caches(self) -> None:
        """Drop the cached 2-D table coordinates (at the host's release)."""
        self._coords_cache.clear()
