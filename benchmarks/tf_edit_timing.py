"""Transfer-function edit time with classification on the CPU (numpy, then uploaded) and on
the GPU (``Illuminator.classification``), measured side by side in one run, for the techniques
that read the opacity texture: shadow_volume (full and half light grid) and cone_traced.
Results go to docs/shadow-volume.md ("Recompute time") and docs/benchmarks.md.

Run from the checkout::

    python benchmarks/tf_edit_timing.py                       # 256³ and 512×512×128
    python benchmarks/tf_edit_timing.py --shapes 128,128,128 --repeats 2

Per shape, method and backend (interleaved: cpu, gpu, cpu, gpu …, so both see the same load):

* ``edit_ms``: edit the opacity function → the next frame rendered with the recomputed light,
  ``glFinish`` (end to end, what the user waits for);
* ``frame_ms``: the same frame without an edit (a camera-free re-render, ``glFinish``);
* ``recompute_ms`` = edit_ms − frame_ms: what the edit adds to a frame.

And the classification alone (1-D TF, with gradient opacity, a 2-D TF, two channels):
``Illuminator.opacity_texture()`` after an edit, ``glFinish`` (cpu: numpy over every voxel +
upload; gpu: the compute shader), and numpy's ``opacity_volume()`` by itself.

Data: uint8 Gaussian blobs (``blobs``), 1 µm voxels, opacity ramp 20 → 0, 200 → 0.8; one
directional light; jitter off, empty-space skipping on (the default).
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import vtk

from vtkvol.engine import tf2d

Row = dict[str, Any]

METHODS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("shadow_volume full", "shadow_volume", {"resolution": "full"}),
    ("shadow_volume half", "shadow_volume", {"resolution": "half"}),
    ("cone_traced", "cone_traced", {}),
)


def blobs(shape_zyx: Sequence[int], count: int = 12, seed: int = 1) -> np.ndarray:
    """uint8 sum of ``count`` Gaussian blobs (radii 4–12 % of the smallest edge), clipped."""
    rng = np.random.default_rng(seed)
    nz, ny, nx = shape_zyx
    out = np.zeros((nz, ny, nx), np.float32)
    axes = [np.arange(n, dtype=np.float32) for n in (nz, ny, nx)]
    for _ in range(count):
        c = rng.random(3) * np.array([nz, ny, nx])
        r = (0.04 + 0.08 * rng.random()) * min(nz, ny, nx)
        gz, gy, gx = (np.exp(-((a - ci) ** 2) / (2 * r * r)) for a, ci in zip(axes, c,
                                                                                 strict=True))
        out += 230.0 * gz[:, None, None] * gy[None, :, None] * gx[None, None, :]
    return np.clip(out, 0, 255).astype(np.uint8)


def _finish(rw: Any) -> None:
    from vtkvol.engine.gl import gl

    rw.MakeCurrent()
    gl(rw).glFinish()


def _timed_render(rw: Any) -> float:
    t0 = time.perf_counter()
    rw.Render()
    _finish(rw)
    return (time.perf_counter() - t0) * 1e3


def measure(shape_zyx: Sequence[int], *, window: int = 256, repeats: int = 3,
            techniques: bool = True) -> list[Row]:
    """Rows per method × backend for one data shape (see the module docstring); with
    ``techniques`` False only the classification alone."""
    from vtkvol.engine.illuminator import Illuminator
    from vtkvol.engine.offscreen import simple_volume_scene
    from vtkvol.model import Light

    data = blobs(shape_zyx)
    rw, ren, volume = simple_volume_scene(data, size=(window, window), elevation=20.0,
                                          opacity=[(0.0, 0.0), (20.0, 0.0), (200.0, 0.8)])
    otf = volume.GetProperty().GetScalarOpacity()
    il = Illuminator(volume, ren, method="local", lights=[Light(direction=(0.35, 0.2, 1.0))])
    rows: list[Row] = []
    shape = "×".join(str(n) for n in shape_zyx[::-1])
    edits = 0

    def edit() -> None:
        nonlocal edits
        edits += 1
        otf.AddPoint(120.0, 0.3 + 0.01 * (edits % 7))  # a real edit: a node moves

    try:
        rw.Render()
        for label, method, params in METHODS if techniques else ():
            il.set_method(method, params)
            samples: dict[str, dict[str, list[float]]] = {
                b: {"edit": [], "frame": []} for b in ("cpu", "gpu")}
            for backend in ("cpu", "gpu"):  # warm up both (compile, allocate)
                il.classification = backend
                edit()
                _timed_render(rw)
            for _ in range(repeats):
                for backend in ("cpu", "gpu"):
                    il.classification = backend
                    _timed_render(rw)  # settle: the backend switch itself reclassifies
                    edit()
                    samples[backend]["edit"].append(_timed_render(rw))
                    samples[backend]["frame"].append(_timed_render(rw))
                    assert il.classification_stats()["backend"] == backend
                    assert il.failed_method is None, il.last_error
            for backend in ("cpu", "gpu"):
                e = statistics.median(samples[backend]["edit"])
                f = statistics.median(samples[backend]["frame"])
                rows.append({"shape": shape, "method": label, "classification": backend,
                             "edit_ms": e, "frame_ms": f, "recompute_ms": e - f,
                             "edit_min_ms": min(samples[backend]["edit"])})
        rows += _classification_alone(il, rw, edit, shape, "1-D TF", 2 * repeats)
        gof = vtk.vtkPiecewiseFunction()
        gof.AddPoint(0.0, 0.2)
        gof.AddPoint(20.0, 1.0)
        volume.GetProperty().SetGradientOpacity(gof)
        rows += _classification_alone(il, rw, edit, shape, "1-D TF × gradient opacity",
                                      2 * repeats)
        prop = volume.GetProperty()
        prop.DisableGradientOpacityOn()
        table = tf2d.TableImage()
        h, w = tf2d.TABLE_SHAPE
        rgba = np.ones((h, w, 4), np.float32)
        value = np.linspace(0.0, 1.0, w, dtype=np.float32)[None, :]
        gradient = np.linspace(0.0, 1.0, h, dtype=np.float32)[:, None]
        rgba[..., 3] = np.clip((value - 0.1) * 3, 0, 0.8) * (gradient < 0.3)
        step = float(volume.GetMapper().GetSampleDistance())
        unit = prop.GetScalarOpacityUnitDistance()
        table.set_table(rgba, step, unit)
        prop.SetTransferFunctionMode(vtk.vtkVolumeProperty.TF_2D)
        prop.SetTransferFunction2D(0, table.image)

        def edit_2d() -> None:
            nonlocal edits
            edits += 1
            rgba[..., 3] *= 0.99 if edits % 2 else 1 / 0.99
            table.set_table(rgba, step, unit)

        rows += _classification_alone(il, rw, edit_2d, shape, "2-D TF", 2 * repeats)
    finally:
        il.release()
        rw.Finalize()
    return rows


def measure_channels(shape_zyx: Sequence[int], *, repeats: int = 3) -> list[Row]:
    """The classification alone for two independent uint8 channels with 1-D TFs."""
    from vtkvol.engine.illuminator import Illuminator
    from vtkvol.engine.offscreen import image_from_array, simple_volume_scene

    data = np.stack([blobs(shape_zyx, seed=1), blobs(shape_zyx, seed=2)], axis=-1)
    rw, ren, volume = simple_volume_scene(data[..., 0], size=(64, 64))
    volume.GetMapper().SetInputData(image_from_array(data))
    prop = volume.GetProperty()
    prop.IndependentComponentsOn()
    functions = []
    for c in range(2):
        otf = vtk.vtkPiecewiseFunction()
        otf.AddPoint(20.0, 0.0)
        otf.AddPoint(200.0, 0.8)
        prop.SetScalarOpacity(c, otf)
        ctf = vtk.vtkColorTransferFunction()
        ctf.AddRGBPoint(0.0, 1.0, 1.0, 1.0)
        prop.SetColor(c, ctf)
        functions.append(otf)
    il = Illuminator(volume, ren, method="local")
    edits = 0

    def edit() -> None:
        nonlocal edits
        edits += 1
        functions[edits % 2].AddPoint(120.0, 0.3 + 0.01 * (edits % 7))

    try:
        return _classification_alone(il, rw, edit, "×".join(str(n) for n in shape_zyx[::-1]),
                                     "2 channels, 1-D TFs", 2 * repeats)
    finally:
        il.release()
        rw.Finalize()


def _classification_alone(il: Any, rw: Any, edit: Any, shape: str, what: str,
                          repeats: int) -> list[Row]:
    """The classification step alone: ``opacity_texture()`` after an edit, ``glFinish``
    (cpu: numpy + upload; gpu: the compute shader), and numpy's ``opacity_volume()``."""
    samples: dict[str, list[float]] = {"cpu": [], "gpu": [], "numpy": []}
    il.set_method("local")  # nothing else recomputes
    il.classification = "gpu"
    rw.Render()
    rw.MakeCurrent()
    il.opacity_texture()  # compile this variant, upload the scalars
    for _ in range(repeats):
        for backend in ("cpu", "gpu"):
            il.classification = backend
            edit()
            rw.MakeCurrent()
            t0 = time.perf_counter()
            il.opacity_texture()
            _finish(rw)
            samples[backend].append((time.perf_counter() - t0) * 1e3)
            assert il.classification_stats()["backend"] == backend
        edit()
        t0 = time.perf_counter()
        il.opacity_volume()
        samples["numpy"].append((time.perf_counter() - t0) * 1e3)
    return [{"shape": shape, "method": f"classification alone, {what}", "classification": b,
             "edit_ms": statistics.median(v), "edit_min_ms": min(v)}
            for b, v in samples.items()]



def _markdown(rows: Sequence[Row], columns: Sequence[str]) -> str:
    def fmt(v: Any) -> str:
        return f"{v:.0f}" if isinstance(v, float) else str(v)

    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(fmt(r.get(c, "")) for c in columns) + " |" for r in rows]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapes", default="256,256,256;128,512,512",
                        help="z,y,x shapes separated by ';' (default: 256³ and 512×512×128)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--window", type=int, default=256, help="view size (pixels)")
    parser.add_argument("--classification-only", action="store_true",
                        help="only the classification alone (no technique recomputes)")
    args = parser.parse_args()
    rows: list[Row] = []
    for text in args.shapes.split(";"):
        shape = tuple(int(v) for v in text.split(","))
        rows += measure(shape, window=args.window, repeats=args.repeats,
                        techniques=not args.classification_only)
        rows += measure_channels(shape, repeats=args.repeats)
    print(_markdown(rows, ["shape", "method", "classification", "edit_ms", "edit_min_ms",
                           "frame_ms", "recompute_ms"]))


if __name__ == "__main__":
    main()
