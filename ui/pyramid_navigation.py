"""Pyramid navigation of the app window: Refine selection (the crop region at the finest
level that fits the GPU-memory budget) and Back to overview, read in the background
(:class:`PyramidNavigation`). What is shifted and restricted is in
:mod:`vtkvol.ui.pyramid_view`; what "Back to overview" returns to is the document's
``overview``."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from PySide6.QtWidgets import QStatusBar

from vtkvol.io import VolumeData, read_volume
from vtkvol.io.volume_data import format_bytes
from vtkvol.model.document import Document, is_pyramid
from vtkvol.model.scene import CropBox, SceneModel
from vtkvol.ui.pyramid_view import (
    LEVEL_WHY_KEY,
    crop_region_um,
    restrict_weights,
    weight_fractions,
)


class PyramidHost(Protocol):
    """The app window as its pyramid navigation sees it (:class:`vtkvol.ui.app.MainWindow`,
    not imported: it imports this module)."""

    document: Document
    model: SceneModel

    @property
    def reading(self) -> bool: ...

    def statusBar(self) -> QStatusBar: ...

    def gpu_budget(self) -> int: ...

    def run_read(self, label: str, job: Callable[..., Any], on_success: Callable[[Any], None],
                 on_failure: Callable[[BaseException], None]) -> None: ...

    def read_failed(self, exc: BaseException, action: str) -> None: ...

    def show_pyramid_level(self, new: VolumeData, *, crop: dict[str, Any],
                           slice_weights: dict[str, Any],
                           overview: dict[str, Any] | None) -> None: ...


class PyramidNavigation:
    """Refine selection and Back to overview for ``host``."""

    def __init__(self, host: PyramidHost) -> None:
        self.host = host

    def refine_selection(self) -> None:
        """Load the crop region at the finest pyramid level that fits the budget.

        The region is the crop box (µm) widened by half a shown voxel on each side. The new
        data is shown with its first voxel at the world origin and the camera, point lights
        and clipping plane shifted by the region's offset, so the object stays where it was;
        TFs, lights, method and camera are kept, the crop becomes the whole (new) extent."""
        host, model = self.host, self.host.model
        data = host.document.data
        if not is_pyramid(data) or host.reading:
            return
        assert data is not None
        if model.volume.voxel_size_um is not None:
            host.statusBar().showMessage("Refine selection reads the file's own voxel sizes: "
                                         "use Edit → Voxel size → Use the file's value first",
                                         8000)
            return
        region = crop_region_um(data, model.crop)
        budget = host.gpu_budget()
        source = str(data.source)
        time_index = model.volume.time_index
        current = int(data.metadata["level"])

        def job(progress, cancel):
            return read_volume(source, time_index=time_index, region_um=region,
                               memory_budget_bytes=budget, progress=progress, cancel=cancel)

        def success(new: VolumeData) -> None:
            if int(new.metadata["level"]) >= current:
                host.statusBar().showMessage(
                    f"Refine selection: level {current} is already the finest level at which "
                    f"this region fits {format_bytes(budget)}; crop a smaller region or raise "
                    "the GPU memory budget", 10000)
                return
            overview = host.document.overview
            if overview is None:
                overview = {"level": current, "crop": model.crop.model_dump(),
                            "slice_weights": model.slice_weights.model_dump()}
            fractions = weight_fractions(data, new.metadata["region_um"])
            weights = {axis: restrict_weights(getattr(model.slice_weights, axis), lo, hi)
                       for axis, (lo, hi) in zip("xyz", fractions, strict=True)}
            host.show_pyramid_level(new, crop=CropBox().model_dump(), slice_weights=weights,
                                    overview=overview)

        host.run_read("Refining the selection…", job, success,
                      lambda exc: host.read_failed(exc, "Could not refine the selection"))

    def back_to_overview(self) -> None:
        """Show the overview level again, whole, with the crop and slice weights it had."""
        host = self.host
        data, overview = host.document.data, host.document.overview
        if data is None or overview is None or host.reading:
            return
        budget = host.gpu_budget()
        source = str(data.source)
        time_index = host.model.volume.time_index

        def job(progress, cancel):
            return read_volume(source, time_index=time_index, level=overview["level"],
                               memory_budget_bytes=budget, progress=progress, cancel=cancel)

        def success(new: VolumeData) -> None:
            if overview["level"] is not None:  # else the budget chose it, and says so
                new.metadata[LEVEL_WHY_KEY] = "the overview shown before Refine selection"
            host.show_pyramid_level(new, crop=overview["crop"],
                                    slice_weights=overview["slice_weights"], overview=None)

        host.run_read("Reading the overview…", job, success,
                      lambda exc: host.read_failed(exc, "Could not show the overview"))
