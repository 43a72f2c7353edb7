"""The "Illuminated render" dock widget and "Open in vtkvol".

Qt through qtpy only (napari may run on PyQt5/6 or PySide6; vtkvol's app uses PySide6, so
the app is started in a separate process, never imported here). The render itself is
vtkvol's offscreen renderer (EGL/OSMesa, its own GL context), not napari's canvas.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from qtpy.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QProgressBar,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from vtkvol.napari._mapping import MappingError, camera_from_napari, layers_to_scene

__all__ = ["IlluminatedRenderWidget", "napari_camera", "open_in_vtkvol", "render_viewer",
           "viewer_scene"]


def _image_layers(viewer: Any) -> list[Any]:
    from napari.layers import Image

    # RGB layers (such as a render this widget added) are pictures, not channels.
    return [ly for ly in viewer.layers if isinstance(ly, Image) and ly.visible and not ly.rgb]


def napari_camera(viewer: Any) -> Any:
    """The viewer's 3-D camera: ``viewer.scene.camera`` (napari ≥ 0.9), else the older
    ``viewer.camera``."""
    scene = getattr(viewer, "scene", None)
    camera = getattr(scene, "camera", None)
    return camera if camera is not None else viewer.camera


def _canvas_height(viewer: Any) -> float | None:
    """napari's canvas height in pixels (the zoom's reference), or None without a window."""
    try:
        height = float(viewer.window._qt_viewer.canvas.size[0])
    except (AttributeError, TypeError, IndexError):
        canvas = getattr(viewer, "_canvas_size", None)
        height = float(canvas[0]) if canvas is not None else 0.0
    return height if height > 1 else None


def viewer_scene(viewer: Any, *, size: tuple[int, int], method: str | None = None,
                 light_azimuth: float | None = None, light_elevation: float | None = None):
    """``(data, model)`` for the viewer's visible image layers and 3-D camera (see
    :mod:`vtkvol.napari._mapping`); ``size`` (w, h) pixels of the image to render."""
    layers = _image_layers(viewer)
    data, model = layers_to_scene(layers)
    translate = tuple(float(v) for v in layers[0].translate[-3:])
    # napari's zoom is canvas pixels per µm: the world height shown is its canvas height
    # over the zoom, whatever the size rendered here.
    height = _canvas_height(viewer) or float(size[1])
    model.camera = camera_from_napari(napari_camera(viewer), data, canvas_height_px=height,
                                      translate_zyx=translate)  # type: ignore[arg-type]
    if method:
        model.illumination.method = method
    if light_azimuth is not None and light_elevation is not None and model.lights:
        az, el = np.radians(light_azimuth), np.radians(light_elevation)
        model.lights[0].direction = (float(np.cos(el) * np.sin(az)), float(np.sin(el)),
                                     float(np.cos(el) * np.cos(az)))
    return data, model


def render_viewer(viewer: Any, *, size: tuple[int, int] = (256, 256), method: str | None = None,
                  **light: float) -> np.ndarray:
    """The viewer's visible image layers rendered by vtkvol from napari's camera: (h, w, 3)."""
    from vtkvol.engine.api import render_image

    data, model = viewer_scene(viewer, size=size, method=method, **light)
    return render_image(data, model=model, size=size, method=model.illumination.method)


def open_in_vtkvol(viewer: Any, folder: str | Path | None = None, *, start: bool = True,
                   size: tuple[int, int] = (800, 600)) -> tuple[Path, subprocess.Popen | None]:
    """Write a session of the viewer (layers → channels, camera, scale) and start the vtkvol
    app on it in a separate process (napari's and vtkvol's Qt bindings must not share one).
    Layers read by vtkvol from one file refer to that file; others are saved as a ``.npy``
    beside the session, with the voxel size in the session. ``size`` (w, h): the image the
    camera's zoom is measured against (the app's view, or the widget's render size)."""
    from vtkvol.model.session import save_session

    folder = Path(folder or tempfile.mkdtemp(prefix="vtkvol-napari-"))
    folder.mkdir(parents=True, exist_ok=True)
    data, model = viewer_scene(viewer, size=size)
    if data.source is None:
        array_path = folder / "napari_layers.npy"
        np.save(array_path, np.asarray(data.array))
        data.source = str(array_path)
        model.volume.voxel_size_um = tuple(data.voxel_size_um)  # the .npy has no voxel size
    model.volume.path = data.source
    session = save_session(folder / "napari.vtkvol.json", model, data=data)
    process = _start_app([sys.executable, "-m", "vtkvol.cli", "open", str(session)]) \
        if start else None
    return session, process


def _start_app(argv: list[str]) -> subprocess.Popen:
    """Start the vtkvol app as a process of its own (its PySide6 never meets napari's Qt)."""
    return subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)


class IlluminatedRenderWidget(QWidget):
    """Render the visible image layers with vtkvol (method, light, size) → a new RGB layer,
    a PNG, or a turntable MP4 (with a progress bar); "Open in vtkvol" hands the view over."""

    def __init__(self, napari_viewer: Any) -> None:
        super().__init__()
        from vtkvol.model.techniques import technique_specs

        self.viewer = napari_viewer
        layout = QVBoxLayout(self)
        form = QFormLayout()
        self.method = QComboBox()
        self.method.addItems(sorted(technique_specs()))
        self.method.setCurrentText("shadow_volume")
        form.addRow("Method", self.method)
        self.light_azimuth = QDoubleSpinBox(minimum=-180.0, maximum=180.0, value=30.0)
        self.light_elevation = QDoubleSpinBox(minimum=-90.0, maximum=90.0, value=30.0)
        lights = QHBoxLayout()
        lights.addWidget(self.light_azimuth)
        lights.addWidget(self.light_elevation)
        form.addRow("Light az./el. (°)", lights)
        self.width_px = QSpinBox(minimum=16, maximum=4096, value=512)
        self.height_px = QSpinBox(minimum=16, maximum=4096, value=512)
        size = QHBoxLayout()
        size.addWidget(self.width_px)
        size.addWidget(self.height_px)
        form.addRow("Size (px)", size)
        self.output = QComboBox()
        self.output.addItems(["New layer", "PNG", "Turntable MP4"])
        form.addRow("Output", self.output)
        self.path = QLineEdit()
        self.path.setPlaceholderText("file for PNG / MP4")
        form.addRow("File", self.path)
        self.frames = QSpinBox(minimum=2, maximum=3600, value=72)
        form.addRow("Turntable frames", self.frames)
        layout.addLayout(form)
        self.render_button = QPushButton("Render")
        self.render_button.clicked.connect(self.render)
        layout.addWidget(self.render_button)
        self.open_button = QPushButton("Open in vtkvol")
        self.open_button.clicked.connect(
            lambda: open_in_vtkvol(self.viewer, size=self._options()["size"]))
        layout.addWidget(self.open_button)
        self.progress = QProgressBar()
        layout.addWidget(self.progress)
        self.status = QLabel("")
        self.status.setWordWrap(True)
        layout.addWidget(self.status)
        layout.addStretch(1)

    def _options(self) -> dict[str, Any]:
        return {"size": (self.width_px.value(), self.height_px.value()),
                "method": self.method.currentText(),
                "light_azimuth": self.light_azimuth.value(),
                "light_elevation": self.light_elevation.value()}

    def _target(self, suffix: str) -> Path | None:
        text = self.path.text().strip()
        if not text:
            text, _ = QFileDialog.getSaveFileName(self, "Save as", "", f"*{suffix}")
        return Path(text) if text else None

    def render(self) -> np.ndarray | None:
        """Render as the controls say; the image (h, w, 3), or None when refused."""
        from vtkvol.engine.api import render_image

        try:
            data, model = viewer_scene(self.viewer, **self._options())
        except MappingError as exc:
            self.status.setText(f"vtkvol: {exc}")
            return None
        size = self._options()["size"]
        kind = self.output.currentText()
        if kind == "Turntable MP4":
            return self._turntable(data, model, size)
        self.progress.setValue(0)
        image = render_image(data, model=model, size=size, method=model.illumination.method,
                             on_error=lambda m: self.status.setText(f"vtkvol: {m}"))
        self.progress.setValue(100)
        if kind == "PNG":
            target = self._target(".png")
            if target is None:
                return image
            from PIL import Image as PILImage

            PILImage.fromarray(image).save(target)
            self.status.setText(f"wrote {target}")
        else:
            self.viewer.add_image(image, rgb=True, name=f"vtkvol {model.illumination.method}")
        return image

    def _turntable(self, data: Any, model: Any, size: tuple[int, int]) -> np.ndarray | None:
        from qtpy.QtWidgets import QApplication

        from vtkvol.movie import even_size, turntable_frames, write_movie

        target = self._target(".mp4")
        if target is None:
            return None
        n = self.frames.value()
        size = even_size(size)
        self.progress.setRange(0, n)

        def progress(done: int, total: int) -> None:
            self.progress.setValue(done)
            QApplication.processEvents()  # the bar moves while frames render

        frames = turntable_frames(data, frames=n, model=model, size=size,
                                  method=model.illumination.method)
        try:
            written = write_movie(frames, target, n_frames=n, overwrite=True, progress=progress)
        except (OSError, ValueError) as exc:
            self.status.setText(f"vtkvol: {exc}")
            return None
        self.status.setText(f"wrote {written[0]} ({n} frames)")
        return None
