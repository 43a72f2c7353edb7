"""Development study (not part of the installed library): what a camera move costs a library
user's illuminated volume with the renderer's default lights, before → after the change of
``illuminate``'s default (issue 26).

before: ``lights="renderer"``, the renderer's lights followed at every frame; VTK's headlight
turns with the camera, so every camera move recomputes the precomputed light.
after: the default (``lights=None``), the renderer's lights taken at the first frame and fixed
in the world; a camera move recomputes nothing.

Run from the checkout: ``python benchmarks/library_camera_moves.py [N] [IMAGE] [methods]``
(default 128³ data, 256² image, shadow volume and translucency). The scene is a plain VTK
pipeline (vtkImageData, vtkOpenGLGPUVolumeRayCastMapper, a shaded vtkVolumeProperty, the
renderer's automatic headlight) holding the nuclei channel of the built-in confocal phantom.
Each configuration has its own render window, all open together; every step turns each
camera by 5° and renders each window once, in turn, so a change of machine load hits all
alike. Prints a markdown table: median frame time of ``FRAMES`` moves after two warm-up frames,
and its ratio to ``local`` in the same run.
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np
import vtk

FRAMES = 8


def _scene(array: np.ndarray, image_size: int, method: str, lights: str | None):
    import vtkvol
    from vtkvol.engine.offscreen import image_from_array, make_render_window

    image = image_from_array(array)
    mapper = vtk.vtkOpenGLGPUVolumeRayCastMapper()
    mapper.SetInputData(image)
    prop = vtk.vtkVolumeProperty()
    otf = vtk.vtkPiecewiseFunction()
    otf.AddPoint(float(array.min()), 0.0)
    otf.AddPoint(float(array.max()), 0.6)
    prop.SetScalarOpacity(otf)
    ctf = vtk.vtkColorTransferFunction()
    ctf.AddRGBPoint(float(array.min()), 0.1, 0.2, 0.1)
    ctf.AddRGBPoint(float(array.max()), 0.6, 1.0, 0.6)
    prop.SetColor(ctf)
    prop.ShadeOn()
    volume = vtk.vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)
    window = make_render_window((image_size, image_size))
    renderer = vtk.vtkRenderer()
    window.AddRenderer(renderer)
    renderer.AddVolume(volume)
    renderer.ResetCamera()
    renderer.GetActiveCamera().Elevation(20.0)
    renderer.GetActiveCamera().OrthogonalizeViewUp()
    illuminator = vtkvol.illuminate(volume, renderer, method=method, lights=lights)
    return window, renderer, illuminator


def main(argv: list[str]) -> None:
    from vtkvol.engine.offscreen import grab
    from vtkvol.io.sample import confocal_phantom

    n = int(argv[0]) if argv else 128
    image_size = int(argv[1]) if len(argv) > 1 else 256
    methods = argv[2].split(",") if len(argv) > 2 else ["shadow_volume", "translucency"]
    data = confocal_phantom(shape_zyx=(n, n, n))
    nuclei = np.ascontiguousarray(data.array[0]).astype(np.float32)
    print(f"{n}³ nuclei channel, {image_size}² image, {FRAMES} moves of 5° each\n")
    print("| method | local ms | before: follow ms (÷ local) | after: fixed ms (÷ local) | "
          "light recomputed, before / after |")
    print("|---|---|---|---|---|")
    for method in methods:
        configs = {"local": ("local", None), "follow": (method, "renderer"),
                   "fixed": (method, None)}
        views = {name: _scene(nuclei, image_size, m, lights)
                 for name, (m, lights) in configs.items()}
        recomputed = {name: 0 for name in views}
        for name, (_window, _renderer, il) in views.items():
            grab(_window)
            grab(_window)
            technique = il.technique
            original = technique.prepare

            def counting(changes, values, name=name, original=original, seen=recomputed):
                seen[name] += bool(changes.lights)
                return original(changes, values)

            technique.prepare = counting
        times: dict[str, list[float]] = {name: [] for name in views}
        for _ in range(FRAMES):
            for name, (window, renderer, _il) in views.items():
                renderer.GetActiveCamera().Azimuth(5.0)
                renderer.ResetCameraClippingRange()
                t0 = time.perf_counter()
                grab(window)
                times[name].append((time.perf_counter() - t0) * 1e3)
        ms = {name: statistics.median(t) for name, t in times.items()}
        print(f"| {method} | {ms['local']:.0f} | {ms['follow']:.0f} "
              f"({ms['follow'] / ms['local']:.2f}×) | {ms['fixed']:.0f} "
              f"({ms['fixed'] / ms['local']:.2f}×) | {recomputed['follow']} / "
              f"{recomputed['fixed']} of {FRAMES} |")
        for window, _renderer, il in views.values():
            il.release()
            window.Finalize()


if __name__ == "__main__":
    main(sys.argv[1:])
