"""The app window and its document (:class:`vtkvol.model.document.Document`): each open,
voxel size and save is one document event, and the title, voxel-size badge and menus follow
that event."""

from __future__ import annotations


def test_open_voxel_size_and_save_are_one_document_event_each(main_window, qtbot,
                                                              small_volume_file, tmp_path):
    window = main_window
    events: list[frozenset[str]] = []
    window.document.changed.connect(events.append)
    try:
        assert window.data is None and not window.save_session_action.isEnabled()
        with qtbot.waitSignal(window.dataShown, timeout=30_000):
            window.open_path(small_volume_file)
        assert len(events) == 1
        assert {"data", "as_read", "file_voxel"} <= events[0]
        assert window.document.data is window.data and window.model is window.document.scene
        assert window.windowTitle() == "nuclei.npy — vtkvol"
        # A .npy file stores no voxel size: the badge says so until one is chosen.
        assert window.voxel_badge.isVisibleTo(window)
        assert window.save_session_action.isEnabled() and window.voxel_size_action.isEnabled()

        events.clear()
        window.set_voxel_size((0.5, 0.5, 2.0))
        assert events == [frozenset({"data", "voxel_size_chosen", "unsaved_data_edit"})]
        assert tuple(window.data.voxel_size_um) == (0.5, 0.5, 2.0)
        assert not window.voxel_badge.isVisibleTo(window)
        assert window.has_unsaved_changes()

        events.clear()
        written = window.save_session(tmp_path / "view.vtkvol.json")
        assert written == tmp_path / "view.vtkvol.json"
        assert events == [frozenset({"session_path", "unsaved_data_edit"})]
        assert window.windowTitle() == "view.vtkvol.json — vtkvol"
        assert not window.has_unsaved_changes()
    finally:
        window.document.changed.disconnect(events.append)
