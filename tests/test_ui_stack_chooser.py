"""Opening a folder of several stacks in the app (issue 25 §3): a chooser instead of an error;
one stack, or all as channels; a mismatch reported naming the files. Needs X (pytest-xvfb)."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import QMimeData, QPointF, Qt, QUrl
from PySide6.QtGui import QDropEvent

from vtkvol.ui.stack_chooser import StackChooser

pytestmark = pytest.mark.gui


def _chooser(window, qtbot) -> StackChooser:
    found: list[StackChooser] = []

    def visible() -> bool:
        found[:] = [d for d in window.findChildren(StackChooser) if d.isVisible()]
        return bool(found)

    qtbot.waitUntil(visible, timeout=30_000)
    return found[0]


@pytest.fixture
def stacks(tmp_path, small_volume):
    """A folder of two .npy stacks of one shape (nucleus = the small volume, membrane = its
    inverse) and a third of another shape in a second folder."""
    folder = tmp_path / "two"
    folder.mkdir()
    nucleus = small_volume.array[0]
    np.save(folder / "nucleus.npy", nucleus)
    np.save(folder / "membrane.npy", (nucleus.max() - nucleus).astype(nucleus.dtype))
    odd = tmp_path / "odd"
    odd.mkdir()
    np.save(odd / "a.npy", nucleus)
    np.save(odd / "b.npy", nucleus[:10])
    return folder, odd


def test_a_folder_of_stacks_offers_them_and_opens_all_as_channels(main_window, qtbot, stacks,
                                                                   dialogs):
    folder, _ = stacks
    main_window.open_path(folder)
    chooser = _chooser(main_window, qtbot)
    assert dialogs == []  # no error dialog: a choice
    assert [chooser.list.item(i).text() for i in range(chooser.list.count())] == [
        "membrane.npy", "nucleus.npy"]
    assert chooser.intro.text().startswith("two holds 2 stacks, not the slices of one.")
    assert chooser.channels_button.isEnabled()
    with qtbot.waitSignal(main_window.dataShown, timeout=30_000):
        chooser.channels_button.click()
    assert main_window.data.channel_names == ["membrane", "nucleus"]
    assert main_window.data.array.shape == (2, 24, 48, 48)
    assert [c.name for c in main_window.model.channels] == ["membrane", "nucleus"]


def test_dropping_a_folder_of_stacks_opens_the_chosen_one(main_window, qtbot, stacks):
    folder, _ = stacks
    mime = QMimeData()
    mime.setUrls([QUrl.fromLocalFile(str(folder))])
    event = QDropEvent(QPointF(50, 50), Qt.DropAction.CopyAction, mime,
                       Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier)
    main_window.dropEvent(event)
    chooser = _chooser(main_window, qtbot)
    chooser.list.setCurrentRow(1)
    with qtbot.waitSignal(main_window.dataShown, timeout=30_000):
        chooser.open_button.click()
    assert main_window.data.source == str(folder / "nucleus.npy")
    assert main_window.data.n_channels == 1


def test_stacks_that_do_not_match_are_reported_naming_both(main_window, qtbot, stacks,
                                                          dialogs):
    _, odd = stacks
    before = main_window.data
    main_window.open_path(odd)
    chooser = _chooser(main_window, qtbot)
    with qtbot.waitSignal(main_window.openFailed, timeout=30_000):
        chooser.channels_button.click()
    assert len(dialogs) == 1
    assert dialogs[0].informativeText().startswith(
        "b.npy: its shape (z, y, x) (10, 48, 48) differs from a.npy's (24, 48, 48)")
    assert main_window.data is before
