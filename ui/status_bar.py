"""The app window's status bar labels: the probe, frame times, refinement, the data on
screen and the missing-voxel-size badge (:class:`StatusLabels`)."""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtCore import QObject, Qt
from PySide6.QtWidgets import QLabel, QPushButton, QStatusBar

from vtkvol.io.volume_data import format_bytes
from vtkvol.model.document import Document
from vtkvol.ui.elided_label import ElidedLabel
from vtkvol.ui.pyramid_view import level_text, level_words
from vtkvol.ui.time_series import TimeSeriesPlayer
from vtkvol.ui.viewport import Viewport
from vtkvol.ui.voxel_size import user_note


class StatusLabels(QObject):
    """The labels of ``status`` fed by ``viewport``'s signals; the badge's click calls
    ``choose_voxel_size``."""

    def __init__(self, status: QStatusBar, viewport: Viewport,
                 choose_voxel_size: Callable[[], None]) -> None:
        super().__init__(status)
        self.data_label = ElidedLabel("No data")
        self.data_label.setObjectName("status_data")
        self.frame_label = QLabel("")
        self.frame_label.setObjectName("status_frame")
        self.frame_label.setToolTip("Last frame's render time and the illumination "
                                    "technique's last precomputation time")
        # Room for the widest value, so the bar does not re-layout (or clip) every frame.
        self.frame_label.setMinimumWidth(
            self.frame_label.fontMetrics().horizontalAdvance("frame 99999 ms · light 99999 ms"))
        self.frame_label.setAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
        self.refine_label = QLabel("")
        self.refine_label.setObjectName("status_refine")
        self.refine_label.setToolTip("A progressive illumination method is refining the light; "
                                     "moving the camera does not restart it")
        self.quality_label = QLabel("")
        self.quality_label.setObjectName("status_quality")
        self.quality_label.setToolTip("This machine renders a full-quality frame slower than the "
                                      "window may wait: a coarse image is shown first and full "
                                      "quality is drawn in strips while you are idle")
        viewport.refinementChanged.connect(self.quality_label.setText)
        self.probe_label = QLabel("")
        self.probe_label.setObjectName("status_probe")
        self.probe_label.setToolTip("Intensity probe: the first visible voxel under the mouse "
                                    "pointer (position in µm, voxel index, every channel's "
                                    "value)")
        viewport.probed.connect(self.probe_label.setText)
        status.addWidget(self.probe_label)
        status.addPermanentWidget(self.quality_label)
        # A file without a voxel size is shown at 1 × 1 × 1 µm, which distorts anisotropic
        # stacks; a note in the (truncated) data label was easy to miss (issue 25), so a
        # badge stays until a voxel size is chosen.
        self.voxel_badge = QPushButton("⚠ Voxel size unknown — set…")
        self.voxel_badge.setObjectName("status_voxel_badge")
        self.voxel_badge.setFlat(True)
        self.voxel_badge.setStyleSheet("color: #b35c00; font-weight: bold;")
        self.voxel_badge.setToolTip("The file stores no voxel size: it is shown as 1 × 1 × 1 µm "
                                    "voxels, so lengths and the z/xy aspect may be wrong. "
                                    "Click to set the voxel size (Edit → Voxel size…).")
        self.voxel_badge.clicked.connect(choose_voxel_size)
        self.voxel_badge.hide()
        status.addPermanentWidget(self.voxel_badge)
        status.addPermanentWidget(self.refine_label)
        status.addPermanentWidget(self.data_label)
        status.addPermanentWidget(self.frame_label)
        viewport.frameRendered.connect(self.show_frame)
        # Arrives from inside a frame: queued, as the window's illumination messages.
        viewport.illuminationProgress.connect(self.show_refining,
                                              Qt.ConnectionType.QueuedConnection)

    def show_frame(self, frame_ms: float, illumination_ms: float) -> None:
        """The last frame's render time and the technique's last precomputation (ms)."""
        self.frame_label.setText(f"frame {frame_ms:.0f} ms · light {illumination_ms:.0f} ms")

    def show_refining(self, iteration: int, converged: bool) -> None:
        """A progressive technique's iteration, until it converged."""
        self.refine_label.setText("" if converged else f"Refining lighting — iteration {iteration}")

    def show_data(self, document: Document, time_player: TimeSeriesPlayer) -> None:
        """What is on screen: name, size, channels, time point, type, voxel size, memory and
        pyramid level; the badge while the voxel size is the assumed one."""
        data = document.data
        self.voxel_badge.setVisible(document.voxel_size_missing())
        if data is None:
            self.data_label.setText("No data")
            return
        c, z, y, x = data.array.shape
        sx, sy, sz = data.voxel_size_um
        name = document.data_name()
        channels = f", {c} channels" if c > 1 else ""
        if time_player.is_series:
            channels += f", time point {time_player.shown_index} of {time_player.count}"
        level = level_text(data)
        where = " · " + level_words(int(data.metadata["level"]),
                                    len(data.metadata["levels"])) + (
            " (refined region)" if data.metadata.get("region_um") else "") if level else ""
        self.data_label.setText(
            f"{name} — {x}×{y}×{z}{channels}, {data.array.dtype}, voxel {sx:.3g}×{sy:.3g}×"
            f"{sz:.3g} µm, {format_bytes(data.nbytes)}{where}")
        tip = user_note(data.describe())
        self.data_label.setToolTip(f"{level[:1].upper()}{level[1:]}\n\n{tip}" if level else tip)
