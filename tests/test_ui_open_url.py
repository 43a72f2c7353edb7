"""File → Open URL…: an OME-Zarr store served over HTTP (a real local server) opens at the
level the GPU budget allows, and Refine selection fetches only the chunks of the region.
Needs X (pytest-xvfb) and GL."""

from __future__ import annotations

import math

import pytest
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication, QDialogButtonBox

pytest.importorskip("zarr")
pytest.importorskip("fsspec")
pytest.importorskip("aiohttp")
pytest.importorskip("ome_zarr.writer")

from tests_support_http import CountingServer, chunk_files, write_served_stores

from vtkvol.ui.open_url import OpenUrlDialog, url_problem

pytestmark = pytest.mark.gui

#: Level 2 (2 channels × 64×16×16 uint16 = 64 KiB) fits, level 1 does not.
BUDGET = 2 * 64 * 16 * 16 * 2


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    root = write_served_stores(tmp_path_factory.mktemp("served"))
    with CountingServer(root) as srv:
        yield srv, root


def test_url_problems():
    assert url_problem("") == "Enter the address of an OME-Zarr store."
    assert url_problem("/data/x.zarr") == ("The address must start with http://, https://, "
                                           "s3://.")
    assert url_problem("https:///x.zarr") == "The address names no host."
    assert url_problem(" https://h/x.ome.zarr ") is None


def test_dialog_enables_open_only_for_an_address(qtbot):
    dialog = OpenUrlDialog()
    qtbot.addWidget(dialog)
    button = dialog.buttons.button(QDialogButtonBox.StandardButton.Open)
    assert not button.isEnabled() and dialog.problem.text() == ""
    dialog.edit.setText("data/x.zarr")
    assert not button.isEnabled() and "must start with" in dialog.problem.text()
    dialog.edit.setText("http://127.0.0.1:8000/x.ome.zarr ")
    assert button.isEnabled() and dialog.problem.text() == ""
    assert dialog.url() == "http://127.0.0.1:8000/x.ome.zarr"


def test_open_url_then_refine_a_quarter(main_window, qtbot, served):
    server, root = served
    window = main_window
    window.budget_override = BUDGET
    url = f"{server.url}/cells.ome.zarr"

    def type_and_accept() -> None:
        dialog = QApplication.activeModalWidget()
        assert isinstance(dialog, OpenUrlDialog)
        dialog.edit.setText(url)
        dialog.buttons.button(QDialogButtonBox.StandardButton.Open).click()

    server.reset()
    QTimer.singleShot(200, type_and_accept)
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.open_url_action.trigger()
    data = window.data
    assert data.source == url and data.metadata["level"] == 2
    assert data.array.shape == (2, 64, 16, 16)
    assert url in window.recent_files()
    assert window.refine_action.isEnabled()
    fetched = {p.split("/")[2] for p in server.sent if not p.endswith(
        (".zarray", ".zattrs", ".zgroup", ".zmetadata", "zarr.json"))}
    assert fetched == {"s2"}

    # A quarter of the xy extent (level 2's voxels are 2 µm in x and y).
    server.reset()
    window.budget_override = 4 * BUDGET  # the quarter fits at level 0
    window.model.crop.update({"x": (0.0, 14.0), "y": (0.0, 14.0)})
    with qtbot.waitSignal(window.dataShown, timeout=30_000):
        window.refine_action.trigger()
    refined = window.data
    assert refined.metadata["level"] == 0
    (x0, x1), (y0, y1), _ = refined.metadata["region_voxels"]
    assert x1 - x0 <= 40 and y1 - y0 <= 40  # about a quarter of 64², widened by half a voxel
    # The chunks that region overlaps: every byte the server sent beyond them is metadata.
    files = chunk_files(root / "cells.ome.zarr" / "s0")
    needed = sum(f.stat().st_size for (c, z, y, x), f in files.items()
                 if y * 16 < y1 and (y + 1) * 16 > y0 and x * 16 < x1 and (x + 1) * 16 > x0)
    sent = server.total()
    print(f"app refine: {sent} bytes sent, region chunks {needed} bytes ({sent / needed:.3f}×)")
    assert needed <= sent <= 1.2 * needed
    quarter = sum(f.stat().st_size for (c, z, y, x), f in files.items() if y < 2 and x < 2)
    assert sent <= math.ceil(2.5 * quarter)  # 3×3 of 4×4 chunk columns at most, not all 16
    window.budget_override = None
