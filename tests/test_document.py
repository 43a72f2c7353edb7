"""The app's document model (:mod:`vtkvol.model.document`): Qt-free state the window observes.

Each change is announced once, with the names of the fields that really changed; transitions
(open, save, voxel size, pyramid level) are one event each; the state round-trips through
:meth:`Document.state` / :meth:`Document.restore` and, for the sample, through a session file.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vtkvol.io.volume_data import Spacing, VolumeData
from vtkvol.model.document import FIELDS, Document, is_pyramid, sample_kwargs
from vtkvol.model.session import read_session, save_session


def _volume(*, source: str | None = "/data/stack.tif", from_metadata: bool = True,
            levels: bool = False) -> VolumeData:
    metadata = {"levels": [[8, 8, 8], [4, 4, 4]], "level": 0} if levels else {}
    return VolumeData(array=np.zeros((1, 8, 8, 8), np.uint8),
                      voxel_size_um=Spacing(0.5, 0.5, 2.0), channel_names=["c0"],
                      source=source, voxel_size_from_metadata=from_metadata, metadata=metadata)


def _recorder(document: Document) -> list[frozenset[str]]:
    events: list[frozenset[str]] = []
    document.changed.connect(events.append)
    return events


def test_an_assignment_is_announced_once_and_a_repeat_not_at_all() -> None:
    document = Document()
    events = _recorder(document)
    document.session_path = "view.vtkvol.json"
    document.session_path = Path("view.vtkvol.json")  # the same path: no event
    document.budget_override = 1 << 30
    document.budget_override = 1 << 30
    assert events == [frozenset({"session_path"}), frozenset({"budget_override"})]
    assert document.session_path == Path("view.vtkvol.json")


def test_data_is_compared_by_identity() -> None:
    document = Document()
    events = _recorder(document)
    first, second = _volume(), _volume()  # equal voxels, two reads
    document.data = first
    document.data = first
    document.data = second
    assert events == [frozenset({"data"}), frozenset({"data"})]


def test_opening_is_one_event_with_fresh_provenance() -> None:
    document = Document()
    document.saved("old.vtkvol.json")
    document.overview = {"level": 1, "crop": {}, "slice_weights": {}}
    document.unsaved_data_edit = True
    document.voxel_size_chosen = True
    events = _recorder(document)
    data = _volume(from_metadata=False)
    document.opened(data, voxel_size_given=False, sample_args={"seed": 3})
    assert events == [frozenset({"data", "as_read", "sample_args", "file_voxel",
                                 "voxel_size_chosen", "overview", "session_path",
                                 "unsaved_data_edit"})]
    assert document.data is data and document.as_read is data
    assert document.file_voxel == ((0.5, 0.5, 2.0), False)
    assert document.session_path is None and document.overview is None
    assert not document.unsaved_data_edit and not document.voxel_size_chosen
    # The budget is this run's, not the data's: opening keeps it.
    assert "budget_override" not in events[0]


def test_voxel_size_missing_until_chosen() -> None:
    document = Document()
    assert not document.voxel_size_missing()  # no data
    document.opened(_volume(from_metadata=False), voxel_size_given=False)
    assert document.voxel_size_missing()
    events = _recorder(document)
    document.voxel_size_set(None)  # the assumed size confirmed: same data, chosen
    assert events == [frozenset({"voxel_size_chosen"})]
    assert not document.voxel_size_missing() and not document.unsaved_data_edit

    document.opened(_volume(from_metadata=False), voxel_size_given=True)
    assert document.file_voxel is None and not document.voxel_size_missing()
    document.opened(_volume(from_metadata=False), voxel_size_given=False)
    document.scene.volume.voxel_size_um = (1.0, 1.0, 3.0)  # a session's override
    assert not document.voxel_size_missing()


def test_a_new_voxel_size_is_an_unsaved_edit_until_saved() -> None:
    document = Document()
    document.opened(_volume(), voxel_size_given=False)
    resized = _volume()
    events = _recorder(document)
    document.voxel_size_set(resized)
    assert events == [frozenset({"voxel_size_chosen", "data", "unsaved_data_edit"})]
    assert document.data is resized and document.as_read is not resized
    document.saved("v.vtkvol.json")
    assert events[1] == frozenset({"session_path", "unsaved_data_edit"})
    assert not document.unsaved_data_edit


def test_pyramid_levels_and_overview() -> None:
    document = Document()
    overview_level = _volume(levels=True)
    document.opened(overview_level, voxel_size_given=False)
    assert is_pyramid(document.data) and document.can_refine()
    document.scene.volume.voxel_size_um = (1.0, 1.0, 1.0)
    assert not document.can_refine()  # refine reads the file's own voxel sizes
    document.scene.volume.voxel_size_um = None
    overview = {"level": 1, "crop": {"x": None}, "slice_weights": {}}
    refined = _volume(levels=True)
    events = _recorder(document)
    document.level_shown(refined, overview=overview)
    assert events == [frozenset({"data", "as_read", "overview", "unsaved_data_edit"})]
    assert document.overview == overview and document.overview is not overview
    document.level_shown(overview_level, overview=None)
    assert document.overview is None
    assert not is_pyramid(_volume(source=None, levels=True))  # no file to read levels from


def test_gpu_budget_prefers_this_runs_override() -> None:
    document = Document()
    assert document.gpu_budget(512 << 20) == 512 << 20
    document.budget_override = 2 << 30
    assert document.gpu_budget(512 << 20) == 2 << 30


def test_data_name() -> None:
    document = Document()
    assert document.data_name() == ""
    document.opened(_volume(source="/x/embryo.tif"), voxel_size_given=False)
    assert document.data_name() == "embryo.tif"
    document.opened(_volume(source=None), voxel_size_given=False, sample_args={"seed": 1})
    assert document.data_name() == "sample"
    document.opened(_volume(source=None), voxel_size_given=False)
    assert document.data_name() == "in-memory volume"


def test_state_round_trips_in_one_event() -> None:
    source = Document()
    source.opened(_volume(levels=True), voxel_size_given=False, sample_args={"seed": 7},
                  session_path="a.vtkvol.json",
                  overview={"level": 2, "crop": {"x": [0.0, 1.0]}, "slice_weights": {}})
    source.budget_override = 3 << 30
    source.voxel_size_set(_volume())
    state = source.state()
    assert list(state) == list(FIELDS)

    target = Document()
    events = _recorder(target)
    target.restore(state)
    assert len(events) == 1 and events[0] == frozenset(FIELDS)
    restored = target.state()
    assert restored["data"] is state["data"] and restored["as_read"] is state["as_read"]
    assert {k: v for k, v in restored.items() if k not in ("data", "as_read")} == {
        k: v for k, v in state.items() if k not in ("data", "as_read")}
    # state() copies: editing it does not edit the document.
    state["overview"]["level"] = 0
    assert source.overview["level"] == 2
    target.restore(target.state())
    assert len(events) == 1  # nothing changed: no event


def test_restore_rejects_an_unknown_field() -> None:
    with pytest.raises(ValueError, match="Document has no field 'colour'"):
        Document().restore({"colour": 1})


def test_sample_arguments_round_trip_through_a_session_file(tmp_path: Path) -> None:
    document = Document()
    args = {"shape_zyx": (16, 24, 32), "voxel_size_um": (0.3, 0.3, 0.9), "seed": 5}
    document.opened(_volume(source=None), voxel_size_given=False, sample_args=args)
    written = save_session(tmp_path / "view", document.scene, data=None,
                           window=document.window_extras())
    session = read_session(written)
    assert sample_kwargs(session.window["sample"]) == args
    assert Document().window_extras() == {}  # a file is referenced by the data path


def test_the_document_loads_neither_qt_nor_vtk() -> None:
    code = ("import sys, vtkvol.model.document; "
            "print(sorted({m.split('.')[0] for m in sys.modules} & "
            "{'PySide6', 'vtkmodules', 'vtk', 'pyvista'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"
