"""Development study of multi-channel frame cost through the LIBRARY path (issue 26; not part
of the installed library): a plain VTK pipeline (``vtkImageData`` with two independent
components, ``vtkOpenGLGPUVolumeRayCastMapper``, ``vtkVolumeProperty`` with
``IndependentComponentsOn()``, ``ShadeOn()`` and one colour/opacity function per component)
given ``vtkvol.illuminate(volume, renderer, method=..., multichannel_lighting=...)``, beside
the app's scene path (``vtkvol.engine.api.offscreen_view``, as
``benchmarks/multichannel_timing.py`` measures it), on the same data with the same transfer
functions (the scene's defaults), in one run.

Pipelines (``PIPELINE_SPECS``): ``scene`` (the scene's defaults: 0.5-voxel ray step, jitter),
``lib`` (the plain pipeline: VTK's automatic sample distance, i.e. one voxel),
``scene_step1`` (the scene at a one-voxel step) and ``lib_step0.5`` (the plain pipeline with
``AutoAdjustSampleDistances`` off and a 0.5-voxel step), ``lib_lightkit`` (the plain
pipeline under a ``vtkLightKit``, PyVista's default lighting: four lights). For each, three
views: one channel (the nuclei alone), two channels lit per channel, two channels with
shared lighting. A
method's views are all open together and their frames interleaved (A, B, C, …, A, B, …) so
that a change of machine load affects them alike.

Run from the checkout: ``python benchmarks/library_multichannel_timing.py [ZxYxX] [IMAGE]
[methods] [pipelines]`` (default 64x128x128 voxels, a 256² image, ``local,shadow_volume``,
``scene,lib``); prints a markdown table with, per view, the median wall-clock time and the
least CPU time of this process (llvmpipe renders on this process's threads, so the CPU
time counts the rendering work and moves far less than the wall time on a loaded machine),
the ratios, and what each two-channel view's shader did with the lighting. Data: the
built-in confocal phantom (uint16, 0.5 µm voxels). Each time is the median of ``FRAMES``
full-quality frames after two warm-up frames (render + read-back).
"""

from __future__ import annotations

import contextlib
import statistics
import sys
import time
from typing import Any

import numpy as np

FRAMES = 7
PIPELINES = ("scene", "lib")
#: The configurations of one pipeline, in the order their frames are interleaved.
CONFIGS = ("one", "per_channel", "shared")
SHARE_CALL = "vtkvol<host_multichannel_lighting.glsl>"  # the shared sections, built in


def _timed_frames(views: dict[str, Any]) -> dict[str, tuple[float, float]]:
    """Median wall time and least CPU time (ms) of a frame of every open view, their frames
    interleaved. The CPU time is this process's, all threads: llvmpipe renders on threads of
    the process, so it counts the rendering work itself and moves far less than the wall
    time when other jobs load the machine; what they still add (cache and memory-bandwidth
    contention) only ever adds, hence the least of the frames."""
    from vtkvol.engine.offscreen import grab

    for rw in views.values():
        grab(rw)
        grab(rw)
    wall: dict[str, list[float]] = {name: [] for name in views}
    cpu: dict[str, list[float]] = {name: [] for name in views}
    for _ in range(FRAMES):
        for name, rw in views.items():
            t0, c0 = time.perf_counter(), time.process_time()
            grab(rw)
            wall[name].append((time.perf_counter() - t0) * 1e3)
            cpu[name].append((time.process_time() - c0) * 1e3)
    return {name: (statistics.median(wall[name]), min(cpu[name]))
            for name in views}


def _scene_view(stack: contextlib.ExitStack, data: Any, method: str, image: int,
                lighting: str, *, step_voxels: float | None) -> tuple[Any, Any]:
    """The app's path: a render window and its illuminator, closed with ``stack``.
    ``step_voxels``: the ray step in voxels (None: the scene's default, 0.5)."""
    from vtkvol.engine.api import offscreen_view
    from vtkvol.model.defaults import scene_for

    model = scene_for(data)
    model.render.multichannel_lighting = lighting
    if step_voxels is not None:
        model.render.sample_distance = step_voxels
    rw, scene, _ = stack.enter_context(
        offscreen_view(data, model=model, size=(image, image), method=method))
    return rw, scene.illuminator


def _library_view(stack: contextlib.ExitStack, data: Any, method: str, image: int,
                  lighting: str, *, step_voxels: float | None,
                  light_kit: bool = False) -> tuple[Any, Any]:
    """The plain VTK pipeline given ``illuminate()``: a render window and its illuminator.
    Transfer functions: the scene's defaults for ``data`` (so both paths classify alike);
    ``prop.ShadeOn()`` as a VTK user writes it. ``step_voxels``: the ray step in voxels, set
    on the mapper with its automatic sample distance off (None: VTK's defaults).
    ``light_kit``: the renderer gets a ``vtkLightKit`` (key, fill, back and head lights, as
    PyVista's default lighting), which ``illuminate()`` takes as four lights."""
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk

    from vtkvol import illuminate
    from vtkvol.engine.offscreen import make_render_window
    from vtkvol.model.defaults import scene_for

    arr = data.array
    n, nz, ny, nx = arr.shape
    flat = (np.ascontiguousarray(arr[0]).reshape(-1) if n == 1 else
            np.ascontiguousarray(np.moveaxis(np.asarray(arr), 0, -1)).reshape(-1, n))
    img = vtk.vtkImageData()
    img.SetDimensions(nx, ny, nz)
    img.SetSpacing(*(float(s) for s in data.voxel_size_um))
    img.GetPointData().SetScalars(numpy_to_vtk(flat, deep=True))

    prop = vtk.vtkVolumeProperty()
    prop.IndependentComponentsOn()
    prop.SetInterpolationTypeToLinear()
    prop.ShadeOn()
    for c, channel in enumerate(scene_for(data).channels):
        ctf = vtk.vtkColorTransferFunction()
        for value, r, g, b in channel.tf.colors:
            ctf.AddRGBPoint(value, r, g, b)
        otf = vtk.vtkPiecewiseFunction()
        for value, alpha in channel.tf.opacity:
            otf.AddPoint(value, alpha)
        prop.SetColor(c, ctf)
        prop.SetScalarOpacity(c, otf)
    mapper = vtk.vtkOpenGLGPUVolumeRayCastMapper()
    mapper.SetInputData(img)
    if step_voxels is not None:
        mapper.SetAutoAdjustSampleDistances(0)
        mapper.SetSampleDistance(step_voxels * min(data.voxel_size_um))
    volume = vtk.vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)

    rw = make_render_window((image, image))
    renderer = vtk.vtkRenderer()
    rw.AddRenderer(renderer)
    renderer.AddVolume(volume)
    if light_kit:
        kit = vtk.vtkLightKit()
        kit.AddLightsToRenderer(renderer)
    cam = renderer.GetActiveCamera()  # the scene's opening view: front, 30° / 20°
    cam.SetPosition(0.0, -1.0, 0.0)
    cam.SetViewUp(0.0, 0.0, 1.0)
    cam.Azimuth(30.0)
    cam.Elevation(20.0)
    cam.OrthogonalizeViewUp()
    renderer.ResetCamera()
    il = illuminate(volume, renderer, method=method, multichannel_lighting=lighting)

    def close() -> None:
        il.release()
        rw.Finalize()

    stack.callback(close)
    return rw, il


#: pipeline name -> (path, ray step in voxels or None for the path's default, light kit)
PIPELINE_SPECS: dict[str, tuple[str, float | None, bool]] = {
    "scene": ("scene", None, False),
    "lib": ("lib", None, False),
    "scene_step1": ("scene", 1.0, False),
    "lib_step0.5": ("lib", 0.5, False),
    "lib_lightkit": ("lib", None, True),
}


def study(shape: tuple[int, int, int] = (64, 128, 128), image: int = 256,
          methods: tuple[str, ...] = ("local", "shadow_volume"),
          pipelines: tuple[str, ...] = PIPELINES) -> list[dict[str, Any]]:
    from vtkvol.io import VolumeData, confocal_phantom

    two = confocal_phantom(shape, voxel_size_um=(0.5, 0.5, 0.5))
    one = VolumeData.from_array(np.ascontiguousarray(two.array[:1]), two.voxel_size_um,
                                ["nuclei"])
    rows = []
    for method in methods:
        with contextlib.ExitStack() as stack:
            views: dict[str, Any] = {}
            illuminators: dict[str, Any] = {}
            for pipeline in pipelines:
                path, step, light_kit = PIPELINE_SPECS[pipeline]
                for config in CONFIGS:
                    data = one if config == "one" else two
                    lighting = "shared" if config == "shared" else "per_channel"
                    if path == "scene":
                        rw, il = _scene_view(stack, data, method, image, lighting,
                                             step_voxels=step)
                    else:
                        rw, il = _library_view(stack, data, method, image, lighting,
                                               step_voxels=step, light_kit=light_kit)
                    views[f"{pipeline}/{config}"] = rw
                    illuminators[f"{pipeline}/{config}"] = il
            measured = _timed_frames(views)
            for pipeline in pipelines:
                states = {}
                for config in ("per_channel", "shared"):
                    il = illuminators[f"{pipeline}/{config}"]
                    states[config] = (il.multichannel_lighting_state,
                                      SHARE_CALL in il.fragment_source)
                mapper = illuminators[f"{pipeline}/one"].volume.GetMapper()
                row = {"method": method, "pipeline": pipeline,
                       "size": "×".join(map(str, shape)), "image": f"{image}²",
                       "step_um": (mapper.GetSampleDistance(),
                                   bool(mapper.GetAutoAdjustSampleDistances())),
                       "states": states}
                for config in CONFIGS:
                    row[f"{config}_ms"], row[f"{config}_cpu_ms"] = measured[f"{pipeline}/{config}"]
                rows.append(row)
                print(_row(rows[-1]), flush=True)
    return rows


def _ratios(r: dict[str, Any], suffix: str) -> str:
    one, per, shared = (r[f"{c}{suffix}"] for c in CONFIGS)
    return (f"{one:.0f} | {per:.0f} ({per / one:.2f}×) | {shared:.0f} ({shared / one:.2f}×) | "
            f"{shared / per:.2f}")


def _row(r: dict[str, Any]) -> str:
    step, auto = r["step_um"]
    return (f"| {r['method']} | {r['pipeline']} | {step:g}{' (auto)' if auto else ''} | "
            f"{_ratios(r, '_ms')} | {_ratios(r, '_cpu_ms')} | "
            + " / ".join(f"{state}, shared sections {'built' if built else 'absent'}"
                         for state, built in r["states"].values()) + " |")


if __name__ == "__main__":
    args = sys.argv[1:]
    size = tuple(int(v) for v in args[0].lower().split("x")) if args else (64, 128, 128)
    if len(size) == 1:
        size = size * 3
    image_size = int(args[1]) if len(args) > 1 else 256
    chosen = tuple(args[2].split(",")) if len(args) > 2 else ("local", "shadow_volume")
    chosen_pipelines = tuple(args[3].split(",")) if len(args) > 3 else PIPELINES
    print(f"Data {'×'.join(map(str, size))} (z×y×x), {image_size}² image; "
          f"{FRAMES} interleaved frames per view: median wall time, least CPU time")
    print("| method | pipeline | mapper step (µm) | 1 ch wall (ms) | 2 ch per channel | "
          "2 ch shared | shared ÷ per channel | 1 ch CPU (ms) | 2 ch per channel | "
          "2 ch shared | shared ÷ per channel | state (per channel / shared) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    study(size, image_size, chosen, chosen_pipelines)  # type: ignore[arg-type]
