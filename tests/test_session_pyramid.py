"""Sessions of a pyramid view (format v6: ``volume.level`` and ``volume.region_um``): saved and
reopened exactly, hostile values refused with their place named."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

zarr = pytest.importorskip("zarr")
writer = pytest.importorskip("ome_zarr.writer")
ome_format = pytest.importorskip("ome_zarr.format")

from vtkvol.io import VolumeReadError, read_volume  # noqa: E402
from vtkvol.model.defaults import scene_for  # noqa: E402
from vtkvol.model.migrations import VERSION  # noqa: E402
from vtkvol.model.session import (  # noqa: E402
    SessionError,
    load_session_with_data,
    read_session,
    save_session,
)


@pytest.fixture
def pyramid(tmp_path) -> Path:
    path = tmp_path / "p.zarr"
    data = np.random.default_rng(5).integers(0, 4000, size=(1, 8, 32, 32), dtype=np.uint16)
    group = zarr.open_group(str(path), mode="w", zarr_format=3)
    writer.write_image(data, group, axes="czyx", fmt=ome_format.FormatV05(), scale_factors=(2,),
                       scale={"c": 1.0, "z": 1.0, "y": 0.5, "x": 0.5},
                       axes_units={a: "micrometer" for a in "zyx"})
    return path


def saved_region(tmp_path: Path, pyramid: Path) -> Path:
    region = ((2.0, 6.0), (1.0, 9.0), (0.0, 7.0))
    data = read_volume(pyramid, level=0, region_um=region)
    model = scene_for(data)
    model.volume.update({"path": str(pyramid), "level": 0, "region_um": region})
    return save_session(tmp_path / "v.vtkvol.json", model, data=data)


def test_a_refined_view_reopens_exactly(tmp_path, pyramid):
    path = saved_region(tmp_path, pyramid)
    doc = json.loads(path.read_text())
    assert doc["version"] == VERSION
    assert doc["scene"]["volume"]["level"] == 0
    assert doc["scene"]["volume"]["region_um"] == [[2.0, 6.0], [1.0, 9.0], [0.0, 7.0]]
    model, data = load_session_with_data(path)
    assert model.volume.level == 0 and model.volume.region_um == ((2.0, 6.0), (1.0, 9.0),
                                                                  (0.0, 7.0))
    assert data.shape_zyx == (8, 17, 9) and data.metadata["level"] == 0
    expected = read_volume(pyramid, level=0).array[:, :, 2:19, 4:13]
    np.testing.assert_array_equal(data.array, expected)


def _edit(path: Path, **volume) -> Path:
    doc = json.loads(path.read_text())
    doc["scene"]["volume"].update(volume)
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize(("value", "message"), [
    ({"level": -1}, r"volume\.level = -1 is below 0"),
    ({"level": "fine"}, r"volume\.level"),
    ({"region_um": [[5.0, 1.0], [0.0, 1.0], [0.0, 1.0]]}, r"must be increasing"),
    ({"region_um": [[0.0, 1.0], [0.0, 1.0]]}, r"volume\.region_um"),
    ({"region_um": "all"}, r"volume\.region_um"),
])
def test_hostile_session_values_are_refused(tmp_path, pyramid, value, message):
    path = _edit(saved_region(tmp_path, pyramid), **value)
    with pytest.raises(SessionError, match=message):
        read_session(path)


def test_a_non_finite_region_is_refused(tmp_path, pyramid):
    path = saved_region(tmp_path, pyramid)
    doc = json.loads(path.read_text())
    doc["scene"]["volume"]["region_um"][0][0] = "NaN"
    path.write_text(json.dumps(doc).replace('"NaN"', "NaN"))
    with pytest.raises(SessionError, match="NaN is not a number JSON allows"):
        read_session(path)


def test_a_level_or_region_the_file_does_not_have(tmp_path, pyramid):
    path = _edit(saved_region(tmp_path, pyramid), level=5)
    with pytest.raises(VolumeReadError, match=r"level 5 is out of range: the pyramid has 2"):
        load_session_with_data(path)
    path = _edit(path, level=0, region_um=[[500.0, 600.0], [0.0, 1.0], [0.0, 1.0]])
    with pytest.raises(VolumeReadError, match=r"the region x = 500…600 µm lies outside"):
        load_session_with_data(path)
    npy = tmp_path / "plain.npy"
    np.save(npy, np.zeros((4, 4, 4), np.uint8))
    path = _edit(path, region_um=None)
    with pytest.raises(VolumeReadError, match=r"plain\.npy: is not a multiscale image"):
        load_session_with_data(path, data_path=npy)
