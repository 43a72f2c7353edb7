"""Vendor readers: CZI (files written by pylibCZIrw), ND2, LIF and bioio (no writer exists:
the adapters are tested against the libraries' objects, with the real libraries on bad files).
"""

from __future__ import annotations

import importlib.machinery
import sys
import types
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest

from vtkvol.io import VolumeReadError, read_volume
from vtkvol.io.registry import get_reader


def _one_line(exc: pytest.ExceptionInfo, name: str) -> str:
    text = str(exc.value)
    assert "\n" not in text and text.startswith(f"{name}: "), text
    return text


# -- CZI -------------------------------------------------------------------------------------
def _write_czi(path: Path, *, n_t: int = 2, n_z: int = 5, names=("DAPI", "GFP"),
               scale_m=(0.2e-6, 0.2e-6, 0.5e-6)) -> Path:
    pyczi = pytest.importorskip("pylibCZIrw.czi")
    with pyczi.create_czi(str(path), exist_ok=True) as w:
        for t in range(n_t):
            for c in range(len(names)):
                for z in range(n_z):
                    plane = np.full((6, 7, 1), 100 * t + 10 * c + z, np.uint16)
                    w.write(plane, plane={"T": t, "C": c, "Z": z})
        w.write_metadata("test", channel_names=dict(enumerate(names)), scale_x=scale_m[0],
                         scale_y=scale_m[1], scale_z=scale_m[2])
    return path


def test_czi_shape_voxel_size_channels_time(tmp_path):
    path = _write_czi(tmp_path / "cells.czi")
    assert get_reader(path).name == "czi"
    vol = read_volume(path, time_index=1)
    assert vol.array.shape == (2, 5, 6, 7)
    assert vol.voxel_size_um == pytest.approx((0.2, 0.2, 0.5))
    assert vol.voxel_size_um.x == 0.2  # metres → µm without float noise
    assert vol.channel_names == ["DAPI", "GFP"]
    assert vol.metadata["time_points"] == 2
    np.testing.assert_array_equal(vol.array[1, :, 0, 0], [110, 111, 112, 113, 114])
    gfp = read_volume(path, channels=["GFP"])
    np.testing.assert_array_equal(gfp.array[0, :, 3, 3], [10, 11, 12, 13, 14])


def test_czi_without_scaling_uses_1um_with_a_note(tmp_path):
    path = _write_czi(tmp_path / "plain.czi", n_t=1, scale_m=(0.0, 0.0, 0.0))
    vol = read_volume(path)
    assert vol.voxel_size_um == (1.0, 1.0, 1.0) and not vol.voxel_size_from_metadata
    assert any("no scaling" in n for n in vol.notes)


def test_czi_bgr_planes_become_red_green_blue(tmp_path):
    pyczi = pytest.importorskip("pylibCZIrw.czi")
    path = tmp_path / "brightfield.czi"
    with pyczi.create_czi(str(path), exist_ok=True) as w:
        for z in range(3):
            bgr = np.empty((6, 7, 3), np.uint8)
            bgr[..., 0], bgr[..., 1], bgr[..., 2] = 10 + z, 20 + z, 30 + z  # B, G, R in memory
            w.write(bgr, plane={"Z": z})
        w.write_metadata("rgb", scale_x=1e-6, scale_y=1e-6, scale_z=2e-6)
    vol = read_volume(path)
    assert vol.channel_names == ["red", "green", "blue"]
    np.testing.assert_array_equal(vol.array[:, :, 0, 0], [[30, 31, 32], [20, 21, 22],
                                                          [10, 11, 12]])
    assert vol.voxel_size_um == pytest.approx((1.0, 1.0, 2.0))


def test_czi_truncated_and_garbage(tmp_path):
    good = _write_czi(tmp_path / "good.czi", n_t=1).read_bytes()
    (tmp_path / "cut.czi").write_bytes(good[: len(good) // 2])
    with pytest.raises(VolumeReadError) as exc:
        read_volume(tmp_path / "cut.czi")
    assert "not a readable CZI file" in _one_line(exc, "cut.czi")
    (tmp_path / "junk.czi").write_bytes(bytes(range(256)) * 20)
    with pytest.raises(VolumeReadError) as exc:
        read_volume(tmp_path / "junk.czi")
    _one_line(exc, "junk.czi")
    with pytest.raises(VolumeReadError, match="out of range: the file has 1 time point"):
        read_volume(tmp_path / "good.czi", time_index=1)


class _FakeCziImage:
    """czifile.CziImage as its 2026 API has it: sizes, dims, dtype, channels, __call__."""

    def __init__(self, data: np.ndarray, dims: str, channels: dict) -> None:
        self.data, self.dims, self.channels = data, tuple(dims), channels
        self.sizes = dict(zip(dims, data.shape, strict=True))
        self.dtype = data.dtype
        self.selections: list[dict] = []

    def __call__(self, **selection):
        self.selections.append(selection)
        index = tuple(selection.get(d, slice(None)) for d in self.dims)
        return types.SimpleNamespace(asarray=lambda: self.data[index])


def test_czifile_adapter(tmp_path, monkeypatch):
    """The Python ≥ 3.12 path (czifile), against an object with czifile's CziImage API."""
    from vtkvol.io import czi

    data = np.arange(2 * 3 * 2 * 4 * 5, dtype=np.uint16).reshape(2, 3, 2, 4, 5)  # T C Z Y X
    image = _FakeCziImage(data, "TCZYX", {"DAPI": {}, "GFP": {}, "RFP": {}})
    xml = ("<ImageDocument><Metadata><Scaling><Items><Distance Id='X'><Value>1.1e-07</Value>"
           "</Distance><Distance Id='Y'><Value>1.1e-07</Value></Distance><Distance Id='Z'>"
           "<Value>3e-07</Value></Distance></Items></Scaling></Metadata></ImageDocument>")

    class FakeCziFile:
        def __init__(self, path):
            self.scenes = {0: image, 1: image}

        def metadata(self):
            return xml

        def close(self):
            pass

    module = types.SimpleNamespace(CziFile=FakeCziFile)
    monkeypatch.setattr(czi, "_backend", lambda path: ("czifile", module))
    path = tmp_path / "z.czi"
    path.write_bytes(b"")
    vol = read_volume(path, time_index=1, channels=["RFP", "DAPI"])
    assert vol.array.shape == (2, 2, 4, 5)
    np.testing.assert_array_equal(vol.array[0], data[1, 2])
    np.testing.assert_array_equal(vol.array[1], data[1, 0])
    assert vol.voxel_size_um == pytest.approx((0.11, 0.11, 0.3))
    assert vol.channel_names == ["RFP", "DAPI"]
    assert image.selections == [{"T": 1, "C": 2}, {"T": 1, "C": 0}]  # one channel at a time
    assert any("2 scenes" in n for n in vol.notes)


def test_czi_missing_library_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "czifile", None)
    monkeypatch.setitem(sys.modules, "pylibCZIrw.czi", None)
    path = tmp_path / "a.czi"
    path.write_bytes(b"ZISRAWFILE")
    with pytest.raises(VolumeReadError) as exc:
        read_volume(path)
    assert "pip install 'vtkvol[formats]'" in _one_line(exc, "a.czi")


# -- ND2 -------------------------------------------------------------------------------------
def _nd2_metadata(names, calibration=(0.108, 0.108, 0.3), calibrated=(True, True, True)):
    from nd2 import structures as s

    def channel(i, name):
        return s.Channel(
            channel=s.ChannelMeta(name=name, index=i, color=s.Color(255 * (i == 0), 255, 0)),
            loops=None,
            microscope=s.Microscope(),
            volume=s.Volume(
                axesCalibrated=calibrated, axesCalibration=calibration,
                axesInterpretation=("distance", "distance", "distance"),
                bitsPerComponentInMemory=16, bitsPerComponentSignificant=12,
                cameraTransformationMatrix=(1.0, 0.0, 0.0, 1.0), componentCount=1,
                componentDataType="unsigned", voxelCount=(5, 4, 3)),
        )

    return s.Metadata(channels=[channel(i, n) for i, n in enumerate(names)])


class _FakeND2:
    """nd2.ND2File's reading API: sizes, dtype, metadata, voxel_size(), to_dask(), close()."""

    def __init__(self, data, sizes, metadata):
        self._data, self.sizes, self.metadata = data, sizes, metadata
        self.dtype = data.dtype
        self.closed = False

    def voxel_size(self, channel: int = 0):
        from nd2._util import VoxelSize

        return VoxelSize(*self.metadata.channels[0].volume.axesCalibration)

    def to_dask(self):
        import dask.array as da

        chunks = (1,) * (self._data.ndim - 2) + self._data.shape[-2:]
        return da.from_array(self._data, chunks=chunks)

    def close(self):
        self.closed = True


def _patch_nd2(monkeypatch, fake):
    nd2 = pytest.importorskip("nd2")
    monkeypatch.setattr(nd2, "ND2File", lambda path: fake)


def test_nd2_axes_voxel_size_channels(tmp_path, monkeypatch):
    data = np.arange(2 * 3 * 2 * 4 * 5, dtype=np.uint16).reshape(2, 3, 2, 4, 5)
    fake = _FakeND2(data, {"T": 2, "Z": 3, "C": 2, "Y": 4, "X": 5}, _nd2_metadata(["DAPI", "GFP"]))
    _patch_nd2(monkeypatch, fake)
    path = tmp_path / "cells.nd2"
    path.write_bytes(b"")
    assert get_reader(path).name == "nd2"
    vol = read_volume(path, time_index=1)
    assert vol.array.shape == (2, 3, 4, 5)
    np.testing.assert_array_equal(vol.array[1], data[1, :, 1])
    assert vol.voxel_size_um == pytest.approx((0.108, 0.108, 0.3))
    assert vol.channel_names == ["DAPI", "GFP"]
    assert vol.metadata["channel_colors"][1] == (0.0, 1.0, 0.0)
    assert vol.metadata["time_points"] == 2
    assert fake.closed


def test_nd2_positions_and_uncalibrated(tmp_path, monkeypatch):
    data = np.ones((3, 2, 4, 5), np.uint16)  # P Z Y X
    meta = _nd2_metadata(["only"], calibration=(1.0, 1.0, 1.0), calibrated=(False, False, False))
    _patch_nd2(monkeypatch, _FakeND2(data, {"P": 3, "Z": 2, "Y": 4, "X": 5}, meta))
    path = tmp_path / "multi.nd2"
    path.write_bytes(b"")
    vol = read_volume(path)
    assert vol.array.shape == (1, 2, 4, 5)
    assert any("3 XY positions" in n for n in vol.notes)
    assert not vol.voxel_size_from_metadata  # nd2's 1 µm for "not calibrated" is not trusted
    assert any("not calibrated" in n for n in vol.notes)


def test_nd2_bad_files(tmp_path, monkeypatch):
    pytest.importorskip("nd2")
    junk = tmp_path / "junk.nd2"
    junk.write_bytes(bytes(range(256)) * 8)
    with pytest.raises(VolumeReadError) as exc:
        read_volume(junk)
    assert "not a readable ND2 file" in _one_line(exc, "junk.nd2")
    cut = tmp_path / "cut.nd2"
    cut.write_bytes(b"\xda\xce\xbe\x0a" + bytes(60))  # ND2 magic, then nothing
    with pytest.raises(VolumeReadError) as exc:
        read_volume(cut)
    _one_line(exc, "cut.nd2")
    wrong = _FakeND2(np.zeros((2, 4, 5), np.uint16), {"Z": 3, "Y": 4, "X": 5},
                     _nd2_metadata(["a"]))
    _patch_nd2(monkeypatch, wrong)
    with pytest.raises(VolumeReadError) as exc:
        read_volume(junk)
    assert "disagree with the axes" in _one_line(exc, "junk.nd2")


def test_nd2_missing_library_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "nd2", None)
    path = tmp_path / "a.nd2"
    path.write_bytes(b"")
    with pytest.raises(VolumeReadError, match=r"needs the optional package 'nd2': pip install "
                                              r"'vtkvol\[formats\]'"):
        read_volume(path)


# -- LIF -------------------------------------------------------------------------------------
def _leica_xml(dims: dict[int, tuple[int, float]], luts: list[str]) -> ElementTree.Element:
    """An image element as LAS X writes it: Data/Image/ImageDescription with Channels and
    Dimensions (DimID 1/2/3 = x/y/z, Length in metres)."""
    root = ElementTree.Element("Element", Name="img")
    desc = ElementTree.SubElement(ElementTree.SubElement(
        ElementTree.SubElement(root, "Data"), "Image"), "ImageDescription")
    channels = ElementTree.SubElement(desc, "Channels")
    for i, lut in enumerate(luts):
        ElementTree.SubElement(channels, "ChannelDescription", DataType="0", ChannelTag="0",
                               Resolution="16", NameOfMeasuredQuantity="", Min="0", Max="65535",
                               Unit="", LUTName=lut, IsLUTInverted="0", BytesInc=str(2 * i),
                               BitInc="0")
    dimensions = ElementTree.SubElement(desc, "Dimensions")
    for dim_id, (n, length) in dims.items():
        ElementTree.SubElement(dimensions, "DimensionDescription", DimID=str(dim_id),
                               NumberOfElements=str(n), Origin="0", Length=repr(length), Unit="m",
                               BitInc="0", BytesInc="2")
    return root


class _FakeLifImage:
    """liffile.LifImage's API as the reader uses it: name, dims, sizes, dtype, xml_element,
    asarray(out=...)."""

    def __init__(self, name, data, dims, xml):
        self.name, self._data, self.dims, self.xml_element = name, data, tuple(dims), xml
        self.sizes = dict(zip(dims, data.shape, strict=True))
        self.dtype = data.dtype

    def asarray(self, *, out=None):
        return self._data


def _patch_lif(monkeypatch, images):
    liffile = pytest.importorskip("liffile")

    class FakeLifFile:
        def __init__(self, path):
            self.images = images

        def close(self):
            pass

    monkeypatch.setattr(liffile, "LifFile", FakeLifFile)


def test_lif_picks_the_3d_image_with_voxel_size_and_luts(tmp_path, monkeypatch):
    overview = _FakeLifImage("overview", np.zeros((8, 8), np.uint16), "YX",
                             _leica_xml({1: (8, 7e-6), 2: (8, 7e-6)}, ["Gray"]))
    data = np.arange(2 * 4 * 2 * 6 * 5, dtype=np.uint16).reshape(2, 4, 2, 6, 5)  # T Z C Y X
    stack = _FakeLifImage("Series003", data, "TZCYX",
                          _leica_xml({1: (5, 4 * 0.25e-6), 2: (6, 5 * 0.25e-6),
                                      3: (4, 3 * 1.5e-6)}, ["Green", "Red"]))
    _patch_lif(monkeypatch, [overview, stack])
    path = tmp_path / "exp.lif"
    path.write_bytes(b"")
    assert get_reader(path).name == "lif"
    vol = read_volume(path, time_index=1, channels=["Red"])
    assert vol.array.shape == (1, 4, 6, 5)
    np.testing.assert_array_equal(vol.array[0], data[1, :, 1])
    assert vol.voxel_size_um == pytest.approx((0.25, 0.25, 1.5))  # Length/(n − 1), m → µm
    assert vol.channel_names == ["Red"]
    assert vol.metadata["channel_colors"] == [(1.0, 0.0, 0.0)]
    assert vol.metadata["image"] == "Series003"
    assert any("2 images" in n and "'overview'" in n for n in vol.notes)


def test_lif_bad_files(tmp_path, monkeypatch):
    pytest.importorskip("liffile")
    junk = tmp_path / "junk.lif"
    junk.write_bytes(bytes(range(256)) * 8)
    with pytest.raises(VolumeReadError) as exc:
        read_volume(junk)
    assert "not a readable Leica image file" in _one_line(exc, "junk.lif")
    cut = tmp_path / "cut.lif"
    cut.write_bytes(b"\x70\x00\x00\x00\xff\x00\x00\x00\x2a\x40\x00\x00\x00<\x00")  # header, cut
    with pytest.raises(VolumeReadError) as exc:
        read_volume(cut)
    _one_line(exc, "cut.lif")
    bad_axes = _FakeLifImage("lambda", np.zeros((3, 4, 5), np.uint16), "λYX",
                             _leica_xml({1: (5, 1e-6), 2: (4, 1e-6)}, ["Gray"]))
    _patch_lif(monkeypatch, [bad_axes])
    with pytest.raises(VolumeReadError) as exc:
        read_volume(junk)
    assert "unsupported axes λ=3" in _one_line(exc, "junk.lif")


# -- bioio fallback ---------------------------------------------------------------------------
def _fake_bioio(monkeypatch, supported_suffix: str) -> None:
    data = np.arange(2 * 3 * 4 * 5, dtype=np.uint8).reshape(1, 2, 3, 4, 5)  # T C Z Y X

    class BioImage:
        @staticmethod
        def determine_plugin(path):
            if not str(path).endswith(supported_suffix):
                raise ValueError("UnsupportedFileFormatError")
            return "plugin"

        def __init__(self, path):
            self.dims = types.SimpleNamespace(T=1, C=2, Z=3, Y=4, X=5)
            self.dtype = data.dtype
            self.scenes = ["Image:0"]
            self.channel_names = ["a", "b"]
            self.physical_pixel_sizes = types.SimpleNamespace(Z=2.0, Y=500.0, X=500.0)
            unit = types.SimpleNamespace(unit="nanometer")
            self.dimension_properties = types.SimpleNamespace(
                X=unit, Y=unit, Z=types.SimpleNamespace(unit="micrometer"))

        def get_image_dask_data(self, order, T, C):
            assert order == "ZYX"
            return data[T, C]

    module = types.ModuleType("bioio")
    module.__spec__ = importlib.machinery.ModuleSpec("bioio", None)
    module.BioImage = BioImage
    monkeypatch.setitem(sys.modules, "bioio", module)


def test_bioio_fallback_claims_only_what_its_plugins_read(tmp_path, monkeypatch):
    odd = tmp_path / "scan.oddformat"
    odd.write_bytes(b"x")
    other = tmp_path / "notes.xyz"
    other.write_bytes(b"x")
    monkeypatch.setitem(sys.modules, "bioio", None)
    with pytest.raises(VolumeReadError, match=r"unknown file type '\.oddformat'"):
        read_volume(odd)  # without bioio: the usual message
    _fake_bioio(monkeypatch, ".oddformat")
    assert get_reader(odd).name == "bioio"
    assert get_reader(other) is None
    assert get_reader(tmp_path / "x.tif").name == "tiff"  # vtkvol's own readers come first
    vol = read_volume(odd, channels=["b"])
    assert vol.array.shape == (1, 3, 4, 5)
    assert vol.channel_names == ["b"]
    assert vol.voxel_size_um == pytest.approx((0.5, 0.5, 2.0))  # nm → µm from bioio's units
