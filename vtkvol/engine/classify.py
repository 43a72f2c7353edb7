"""Classification on the GPU: the opacity volume techniques read, computed by a compute shader
(``resources/shaders/host_classify.comp.glsl``) from the scalars on the GPU and the transfer
functions' tables, so that a transfer-function, crop or weight edit costs no pass of numpy over
the voxels and no upload of a volume (docs/architecture.md, "Classification on the GPU").

The numpy definition stays :meth:`vtkvol.engine.illuminator.Illuminator.opacity_volume`; this
module reproduces it:

* **Scalars**: uploaded once per data set into a host-owned shader storage buffer, uint8 and
  uint16 packed as they are (4 or 2 per 32-bit word, unpacked exactly in the shader), any other
  type as float32 (int8/int16 exactly, int32/float64 rounded). GPU memory: one more copy of
  the scalars (1, 2 or 4 bytes per voxel and component), up to the driver's storage-buffer
  limit (128 MiB on llvmpipe; beyond it numpy classifies). Storage buffers, not textures: on
  llvmpipe plain loads and stores cost 4–5× less than texel fetches and image stores. VTK's
  own scalar texture is not used: it is uploaded inside the mapper's draw, after the
  renderer's ``StartEvent`` where techniques prepare, so on the first frame and after every
  data change it does not exist yet or holds the previous data, and its format, scale and bias
  are VTK internals.
* **Output**: α (or −ln(1 − α)) slab by slab (:data:`SLAB_VOXELS`) into a storage buffer that
  is copied into the host's r32f 3-D texture on the GPU.
* **1-D tables** (scalar opacity, gradient opacity): integer data get one entry per integer of
  the component's range (≤ :data:`MAX_EXACT_ENTRIES`), read at integral positions, so they are
  numpy's values exactly; float data (and wider integer ranges) a table of
  :data:`FLOAT_TABLE_ENTRIES` samples of the piecewise-linear function over the range, read
  linearly (the difference to numpy is at most |Δslope|·h/4 at a node, h the table step;
  gradient-opacity tables likewise over t = |∇I| / (¼ range) in 0…1).
* **2-D tables**: the component's alpha-per-unit-distance table as an r32f 2-D texture, read
  bilinearly by hand as :func:`vtkvol.engine.tf2d.lookup` does.
* **Crop, clipping planes, slice weights**: the per-axis crop region and weight of every voxel
  index and each plane's side as a linear function of the voxel index are computed in float64
  here (a few thousand numbers), the shader combines them.

Dependent components (RGB/RGBA colour data) stay on the numpy path (:func:`unsupported_reason`).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

from vtkvol.engine import tf2d
from vtkvol.engine.gl import ComputeProgram, StorageBuffer, Texture2D, Texture3D, gl
from vtkvol.engine.shaders import compute_source

COMPUTE_SOURCE = "host_classify.comp.glsl"
#: Entries of a float component's 1-D table (and of every gradient-opacity table).
FLOAT_TABLE_ENTRIES = 16384
#: Integer components whose range has at most this many values get one entry per integer.
MAX_EXACT_ENTRIES = 65536
#: Most clipping planes the shader takes (VTK's mapper supports six).
MAX_CLIP_PLANES = 6
#: Invocations per work group along x (the shader's local_size_x) and voxels per invocation.
GROUP_X = 64
BLOCK = 4
#: Voxels per dispatch (the output slab buffer: 16 MiB); a chunk of a chunked classification.
SLAB_VOXELS = 1 << 22
#: Opacity clamp of the optical-depth output (``vtkvol.reference``'s and the techniques').
MAX_OPACITY = 0.999999
#: What :meth:`Illuminator.opacity_texture` holds.
QUANTITIES = ("alpha", "optical_depth")
#: How the shader unpacks the scalars (``VV_TYPE``); other types are uploaded as float32.
_PACKED = {np.dtype(np.uint8): 0, np.dtype(np.uint16): 1}


def unsupported_reason(volume: vtk.vtkVolume, image: vtk.vtkImageData) -> str:
    """Why this volume's classification cannot run on the GPU ("" when it can)."""
    scalars = image.GetPointData().GetScalars()
    if scalars is None:
        return "the image has no point scalars"
    ncomp = scalars.GetNumberOfComponents()
    prop = volume.GetProperty()
    if ncomp > 1 and not prop.GetIndependentComponents():
        return "dependent components (colour data) are classified by numpy"
    if ncomp > 4:
        return f"{ncomp} components (at most 4)"
    clipping = volume.GetMapper().GetClippingPlanes()
    if clipping is not None and clipping.GetNumberOfItems() > MAX_CLIP_PLANES:
        return f"more than {MAX_CLIP_PLANES} clipping planes"
    return ""


@dataclass
class Plan:
    """What one classification needs besides the scalars: defines (the program variant),
    uniforms, the 1-D tables and per-axis crop/weight rows (one float array) and the 2-D
    tables."""

    defines: dict[str, str]
    ints: dict[str, list[int]] = field(default_factory=dict)
    floats: dict[str, list[float]] = field(default_factory=dict)
    lut: np.ndarray = field(default_factory=lambda: np.zeros(1, np.float32))
    tables_2d: dict[int, np.ndarray] = field(default_factory=dict)


def _nodes(function: vtk.vtkPiecewiseFunction) -> tuple[np.ndarray, np.ndarray]:
    n = function.GetSize()
    if n == 0:
        return np.zeros(1), np.zeros(1)
    nodes = np.empty((n, 2))
    node = [0.0] * 4
    for i in range(n):
        function.GetNodeValue(i, node)
        nodes[i] = node[:2]
    return nodes[:, 0], nodes[:, 1]


def _integral(dtype: np.dtype) -> bool:
    return dtype.kind in "ui"


def optical_depth(alpha: np.ndarray) -> np.ndarray:
    """s = −ln(1 − α), α clamped at :data:`MAX_OPACITY` (the numpy twin of the shader's
    ``VV_OPTICAL_DEPTH`` output), float32."""
    a = np.clip(np.asarray(alpha, np.float32), 0.0, np.float32(MAX_OPACITY))
    return (-np.log1p(-a)).astype(np.float32)


def build_plan(volume: vtk.vtkVolume, image: vtk.vtkImageData,
               weights: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
               crop_regions: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
               crop_flags: int, clip: list[tuple[float, float, float, float]],
               quantity: str = "alpha") -> Plan:
    """The classification of ``volume``'s current transfer functions (cheap: tables only).

    ``weights``: per-axis slice weights at voxel centres (wX, wY, wZ) or None;
    ``crop_regions``: per-axis crop region 0/1/2 of every voxel index or None; ``clip``: each
    clipping plane's side ``a·i + b·j + c·k + d`` (voxel indices; < 0 is cut); ``quantity``:
    ``"alpha"`` or ``"optical_depth"`` (:func:`optical_depth` of it)."""
    prop = volume.GetProperty()
    mapper = volume.GetMapper()
    scalars = image.GetPointData().GetScalars()
    ncomp = scalars.GetNumberOfComponents()
    dtype = np.dtype(vtk_to_numpy(scalars).dtype)
    two_d = prop.GetTransferFunctionMode() == vtk.vtkVolumeProperty.TF_2D
    step = float(mapper.GetSampleDistance())
    u0 = prop.GetScalarOpacityUnitDistance(0)
    spacing = image.GetSpacing()
    mean = sum(spacing) / 3.0
    defines = {"VV_COMPONENTS": str(ncomp), "VV_TYPE": str(_PACKED.get(dtype, 2)),
               "VV_FLOAT_DATA": "0" if _integral(dtype) else "1", "VV_BLOCK": str(BLOCK),
               "VV_GROUP_X": str(GROUP_X),
               "VV_OPTICAL_DEPTH": "1" if quantity == "optical_depth" else "0",
               "VV_MAX_OPACITY": repr(MAX_OPACITY)}
    ints: dict[str, list[int]] = {k: [0] * 4 for k in
                                  ("vv_opOffset", "vv_opLength", "vv_goOffset", "vv_goLength")}
    floats: dict[str, list[float]] = {k: [0.0] * 4 for k in (
        "vv_opLo", "vv_opScale", "vv_nanAlpha", "vv_weight", "vv_unitExponent", "vv_rangeLo",
        "vv_rangeSpan", "vv_gradSpan")}
    floats["vv_gradDivisor"] = [float(np.float32(2.0 * s / mean)) for s in spacing]
    pieces: list[np.ndarray] = []
    offset = 0

    def add(table: np.ndarray) -> tuple[int, int]:
        nonlocal offset
        pieces.append(np.asarray(table, np.float32))
        start, offset = offset, offset + len(table)
        return start, len(table)

    gradient = False
    tables_2d: dict[int, np.ndarray] = {}
    for c in range(4):
        mode = exact = unit = 0
        if c < ncomp:
            weight = prop.GetComponentWeight(c) if ncomp > 1 else 1.0
            lo, hi = (float(r) for r in scalars.GetRange(c))
            span = hi - lo
            valid = bool(np.isfinite(span) and span > 0.0)
            floats["vv_weight"][c] = float(weight)
            uc = prop.GetScalarOpacityUnitDistance(c)
            floats["vv_unitExponent"][c] = 1.0 if uc == u0 else float(u0 / uc)
            unit = int(uc != u0)
            floats["vv_rangeLo"][c] = lo if np.isfinite(lo) else 0.0
            floats["vv_rangeSpan"][c] = span if valid else 0.0
            floats["vv_gradSpan"][c] = float(np.float32(
                tf2d.GRADIENT_RANGE_FRACTION * (span if valid else 1.0)))
            if weight > 0:
                if two_d and prop.GetTransferFunction2D(c) is not None:
                    mode = 3
                    tables_2d[c] = np.ascontiguousarray(tf2d.unit_alpha_table(
                        prop.GetTransferFunction2D(c), step, uc), np.float32)
                else:
                    mode = 1
                    xs, ys = _nodes(prop.GetScalarOpacity(c))
                    floats["vv_nanAlpha"][c] = float(np.float32(ys[0]))
                    exact = (_integral(dtype) and np.isfinite(lo)
                             and 0 <= hi - lo < MAX_EXACT_ENTRIES)
                    if exact:
                        exact = 1
                        table = np.interp(np.arange(lo, hi + 1, dtype=np.float64), xs, ys)
                        scale, start_value = 1.0, lo
                    elif valid:
                        n = FLOAT_TABLE_ENTRIES
                        table = np.interp(np.linspace(lo, hi, n), xs, ys)
                        scale, start_value = (n - 1) / span, lo
                    else:  # one value (or no finite range): its opacity
                        table = np.interp(np.array([lo if np.isfinite(lo) else xs[0]]), xs, ys)
                        scale, start_value = 0.0, 0.0
                    ints["vv_opOffset"][c], ints["vv_opLength"][c] = add(table)
                    floats["vv_opLo"][c] = float(start_value)
                    floats["vv_opScale"][c] = float(scale)
                    if (not two_d and prop.HasGradientOpacity(c)
                            and not prop.GetDisableGradientOpacity(c)):
                        mode = 2
                        gxs, gys = _nodes(prop.GetGradientOpacity(c))
                        top = float(np.float32(floats["vv_gradSpan"][c]))
                        t = np.linspace(0.0, 1.0, FLOAT_TABLE_ENTRIES)
                        ints["vv_goOffset"][c], ints["vv_goLength"][c] = add(
                            np.interp(t * top, gxs, gys))
            gradient = gradient or mode in (2, 3)
        defines[f"VV_MODE_{c}"] = str(mode)
        defines[f"VV_EXACT_{c}"] = str(int(exact))
        defines[f"VV_UNIT_{c}"] = str(unit)
    defines["VV_GRADIENT"] = "1" if gradient else "0"
    defines["VV_CROP"] = "1" if crop_regions is not None else "0"
    defines["VV_WEIGHTS"] = "1" if weights is not None else "0"
    if crop_regions is not None or weights is not None:
        nx, ny, nz = image.GetDimensions()
        width = max(nx, ny, nz)
        axes = np.zeros((6, width), np.float32)
        axes[:3] = 1.0
        if weights is not None:
            for a, w in enumerate(weights):
                axes[a, :len(w)] = w
        if crop_regions is not None:
            for a, r in enumerate(crop_regions):
                axes[3 + a, :len(r)] = r
            ints["vv_cropFlags"] = [int(crop_flags)]
        ints["vv_axesOffset"], ints["vv_axesWidth"] = [add(axes.ravel())[0]], [width]
    lut = np.concatenate(pieces) if pieces else np.zeros(1, np.float32)
    defines["VV_CLIP_PLANES"] = str(len(clip))
    if clip:
        floats["vv_clip"] = [float(v) for plane in clip for v in plane]
    return Plan(defines, ints, floats, lut, tables_2d)


class GpuClassifier:
    """The host's classification resources in VTK's context (context current): the scalars
    (a storage buffer, uploaded once per data set), the tables, the output slab and one
    compute program per variant (kept until :meth:`release`)."""

    def __init__(self, render_window: vtk.vtkRenderWindow) -> None:
        self.render_window = render_window
        self._programs: dict[tuple, ComputeProgram] = {}
        self._scalars: StorageBuffer | None = None
        self._scalars_key: tuple | None = None
        self._tables: StorageBuffer | None = None
        self._out: StorageBuffer | None = None
        self._tables_2d: dict[int, Texture2D] = {}
        self.max_buffer_bytes = int(np.asarray(gl(render_window).glGetIntegerv(
            gl(render_window).GL_MAX_SHADER_STORAGE_BLOCK_SIZE)).ravel()[0])
        self.scalar_bytes = 0
        self.scalar_uploads = 0
        self.upload_ms = 0.0

    @staticmethod
    def _packed(image: vtk.vtkImageData) -> np.ndarray:
        """The point scalars as the shader reads them (component-interleaved, x fastest):
        uint8/uint16 as they are, anything else as float32."""
        values = vtk_to_numpy(image.GetPointData().GetScalars()).reshape(-1)
        if np.dtype(values.dtype) not in _PACKED:
            return np.ascontiguousarray(values, np.float32)
        pad = (-values.nbytes) % 4  # whole 32-bit words
        if pad:
            values = np.concatenate([values, np.zeros(pad // values.itemsize, values.dtype)])
        return np.ascontiguousarray(values)

    def unsupported(self, image: vtk.vtkImageData) -> str:
        """Why this data set does not fit (the driver's storage-buffer limit), or ""."""
        scalars = image.GetPointData().GetScalars()
        itemsize = np.dtype(vtk_to_numpy(scalars).dtype).itemsize
        nbytes = scalars.GetNumberOfValues() * (itemsize if itemsize <= 2 else 4)
        if nbytes > self.max_buffer_bytes:
            return (f"the scalars ({nbytes / 2**20:.0f} MiB) exceed this driver's "
                    f"storage-buffer limit ({self.max_buffer_bytes / 2**20:.0f} MiB)")
        return ""

    # -- resources ------------------------------------------------------------------------------
    def program(self, defines: dict[str, str]) -> ComputeProgram:
        key = tuple(sorted(defines.items()))
        prog = self._programs.get(key)
        if prog is None:
            prog = ComputeProgram(self.render_window, compute_source(COMPUTE_SOURCE, defines),
                                  "host classification")
            self._programs[key] = prog
        return prog

    def ensure_scalars(self, image: vtk.vtkImageData) -> None:
        """Upload the image's point scalars unless this data set is there already."""
        scalars = image.GetPointData().GetScalars()
        key = (image.GetMTime(), scalars.GetMTime(), tuple(image.GetDimensions()),
               scalars.GetNumberOfComponents(), scalars.GetDataType())
        if key == self._scalars_key and self._scalars is not None:
            return
        t0 = time.perf_counter()
        data = self._packed(image)
        if self._scalars is None:
            self._scalars = StorageBuffer(self.render_window)
        self._scalars.upload(data)
        self._scalars_key = key
        self.scalar_bytes = int(data.nbytes)
        self.scalar_uploads += 1
        self.upload_ms = (time.perf_counter() - t0) * 1e3

    def _texture2d(self, current: Texture2D | None, data: np.ndarray) -> Texture2D:
        if current is not None and current.shape == data.shape:
            current.upload(data)
            return current
        if current is not None:
            current.release()
        return Texture2D(self.render_window, data)

    # -- classification -------------------------------------------------------------------------
    def run_steps(self, plan: Plan, image: vtk.vtkImageData, out: Texture3D, *,
                  chunked: bool) -> Iterator[float]:
        """Classify into ``out`` (r32f, the data's shape), yielding the fraction done after
        each slab of about :data:`SLAB_VOXELS` voxels (dispatch, then a copy of the slab into
        ``out`` on the GPU); with ``chunked`` each slab is waited for (``glFinish``)."""
        GL = gl(self.render_window)
        prog = self.program(plan.defines)  # compiled before anything is touched
        self.ensure_scalars(image)
        if self._tables is None:
            self._tables = StorageBuffer(self.render_window)
        self._tables.upload(plan.lut)
        for c in list(self._tables_2d):
            if c not in plan.tables_2d:
                self._tables_2d.pop(c).release()
        for c, table in plan.tables_2d.items():
            self._tables_2d[c] = self._texture2d(self._tables_2d.get(c), table)
        nx, ny, nz = (int(d) for d in image.GetDimensions())
        slab = max(1, min(nz, SLAB_VOXELS // max(1, nx * ny)))
        if self._out is None:
            self._out = StorageBuffer(self.render_window)
        if self._out.nbytes < nx * ny * slab * 4:
            self._out.allocate(nx * ny * slab * 4)
        assert self._scalars is not None
        for z0 in range(0, nz, slab):
            z1 = min(nz, z0 + slab)
            prog.use()
            for c, table in self._tables_2d.items():
                prog.set_uniform(f"vv_tf2d_{c}", table.activate())
            prog.set_uniform("vv_dims", nx, ny, nz)
            prog.set_uniform("vv_z0", z0)
            prog.set_uniform("vv_z1", z1)
            # The plan fills every uniform of the program family; a variant compiled without a
            # feature (gradient opacity, 2-D tables, crop, clip planes) does not read that
            # feature's uniforms, so they are optional here (the checked ones are above).
            for name, values in plan.ints.items():
                if len(values) == 1:
                    prog.set_uniform(name, values[0], optional=True)
                else:
                    prog.set_uniform_array(name, values, kind="i", optional=True)
            for name, values in plan.floats.items():
                if name == "vv_clip":
                    prog.set_uniform_array(name, values, size=4, optional=True)
                elif name == "vv_gradDivisor":
                    prog.set_uniform(name, *values, kind="f", optional=True)
                else:
                    prog.set_uniform_array(name, values, optional=True)
            self._scalars.bind(0)
            self._tables.bind(1)
            self._out.bind(2)
            GL.glDispatchCompute(-(-nx // (GROUP_X * BLOCK)), ny, z1 - z0)
            StorageBuffer.unbind(self.render_window, 3)
            for table in self._tables_2d.values():
                if table.tex is not None:
                    table.tex.Deactivate()
            prog.done()
            self._out.copy_to_texture(out, z0, z1 - z0)
            out.tex.Deactivate()
            if chunked:
                GL.glFinish()
            yield z1 / nz

    def release(self) -> None:
        for buffer in (self._scalars, self._tables, self._out):
            if buffer is not None:
                buffer.release()
        self._scalars = self._tables = self._out = None
        self._scalars_key = None
        self.scalar_bytes = 0
        for tex in self._tables_2d.values():
            tex.release()
        self._tables_2d.clear()
        for prog in self._programs.values():
            prog.release()
        self._programs.clear()


def stats_template() -> dict[str, Any]:
    """The keys of :meth:`Illuminator.classification_stats`, before any classification."""
    return {"backend": "", "reason": "", "gpu_classifications": 0, "cpu_classifications": 0,
            "scalar_uploads": 0, "opacity_uploads": 0, "classify_ms": 0.0,
            "scalar_upload_ms": 0.0, "scalar_bytes": 0}
