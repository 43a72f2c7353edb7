""".npy/.npz, VTK files (.vti, legacy .vtk, .mha) and from_vtk_image."""

from __future__ import annotations

import numpy as np
import pytest

from vtkvol.io import VolumeReadError, from_vtk_image, read_volume


def _vol(shape, dtype=np.uint16):
    return (np.arange(int(np.prod(shape))) % 3000).astype(dtype).reshape(shape)


# -- numpy -----------------------------------------------------------------------------------
def test_npy_3d_is_memory_mapped(tmp_path, monkeypatch):
    monkeypatch.setattr("vtkvol.io.limits.COPY_MAPPED_UP_TO", 0)  # keep even small files mapped
    a = _vol((6, 5, 4))
    np.save(tmp_path / "v.npy", a)
    data = read_volume(tmp_path / "v.npy")
    assert isinstance(data.array, np.memmap)
    assert data.array.shape == (1, 6, 5, 4)
    np.testing.assert_array_equal(data.array[0], a)
    assert data.metadata["format"] == "npy"


def test_npy_4d_channels_and_voxel_size_argument(tmp_path):
    a = _vol((3, 6, 5, 4), np.float32)
    np.save(tmp_path / "v.npy", a)
    data = read_volume(tmp_path / "v.npy", voxel_size_um=(0.1, 0.1, 0.4), channels=[2, 1])
    np.testing.assert_array_equal(data.array, a[[2, 1]])
    assert data.voxel_size_um == pytest.approx((0.1, 0.1, 0.4))


def test_npy_fortran_order_is_copied_to_c_order(tmp_path):
    a = np.asfortranarray(_vol((6, 5, 4)))
    np.save(tmp_path / "f.npy", a)
    data = read_volume(tmp_path / "f.npy")
    assert data.array.flags.c_contiguous
    np.testing.assert_array_equal(data.array[0], a)
    assert any("Fortran-ordered" in n for n in data.notes)


def test_npy_errors(tmp_path):
    np.save(tmp_path / "flat.npy", np.zeros((4, 4)))
    with pytest.raises(
        VolumeReadError, match=r"flat\.npy: expected a 3-D \(z, y, x\) or 4-D .* got 2-D"
    ):
        read_volume(tmp_path / "flat.npy")
    np.save(tmp_path / "c.npy", np.zeros((2, 2, 2), np.complex64))
    with pytest.raises(
        VolumeReadError, match=r"c\.npy: complex data \(complex64\) is not supported"
    ):
        read_volume(tmp_path / "c.npy")
    (tmp_path / "junk.npy").write_bytes(b"\x93NUMPY garbage")
    with pytest.raises(VolumeReadError, match=r"junk\.npy: not a readable \.npy file"):
        read_volume(tmp_path / "junk.npy")
    np.save(tmp_path / "empty.npy", np.zeros((0, 4, 4), np.uint8))
    with pytest.raises(VolumeReadError, match=r"empty\.npy: the volume has a zero-size axis"):
        read_volume(tmp_path / "empty.npy")


def test_npz_with_metadata(tmp_path):
    a = _vol((2, 6, 5, 4))
    np.savez_compressed(
        tmp_path / "v.npz", volume=a, voxel_size_um=[0.2, 0.2, 0.6], channel_names=["n", "m"]
    )
    data = read_volume(tmp_path / "v.npz")
    np.testing.assert_array_equal(data.array, a)
    assert data.voxel_size_um == pytest.approx((0.2, 0.2, 0.6))
    assert data.voxel_size_from_metadata
    assert data.channel_names == ["n", "m"]


def test_npz_ambiguous_arrays(tmp_path):
    np.savez(tmp_path / "two.npz", a=np.zeros((2, 2, 2)), b=np.zeros((2, 2, 2)))
    with pytest.raises(VolumeReadError, match=r"two\.npz: cannot tell which array is the volume"):
        read_volume(tmp_path / "two.npz")


# -- VTK -------------------------------------------------------------------------------------
def _image(array_zyx_c: np.ndarray, spacing=(0.5, 0.5, 2.0), name="density"):
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonDataModel import vtkImageData

    nz, ny, nx, nc = array_zyx_c.shape
    image = vtkImageData()
    image.SetDimensions(nx, ny, nz)
    image.SetSpacing(*spacing)
    image.SetOrigin(1.0, 2.0, 3.0)
    flat = np.ascontiguousarray(array_zyx_c).reshape(-1, nc)
    scalars = numpy_to_vtk(flat if nc > 1 else flat[:, 0], deep=True)
    scalars.SetName(name)
    image.GetPointData().SetScalars(scalars)
    return image


def test_from_vtk_image_single_component():
    a = _vol((6, 5, 4))
    data = from_vtk_image(_image(a[..., None]))
    assert data.array.shape == (1, 6, 5, 4)
    np.testing.assert_array_equal(data.array[0], a)
    assert data.voxel_size_um == pytest.approx((0.5, 0.5, 2.0))
    assert data.channel_names == ["density"]
    assert data.metadata["origin"] == (1.0, 2.0, 3.0)


@pytest.mark.parametrize("components", [2, 3, 4])
def test_from_vtk_image_components_become_channels(components):
    a = _vol((6, 5, 4, components), np.uint8)
    data = from_vtk_image(_image(a, name="rgb"))
    assert data.array.shape == (components, 6, 5, 4)
    np.testing.assert_array_equal(data.array, np.moveaxis(a, -1, 0))
    assert data.channel_names == [f"rgb[{i}]" for i in range(components)]


def test_from_vtk_image_double_is_converted():
    a = np.linspace(0, 1, 6 * 5 * 4).reshape(6, 5, 4, 1)
    data = from_vtk_image(_image(a))
    assert data.array.dtype == np.float32
    assert any("float64 data converted" in n for n in data.notes)


def test_from_vtk_image_without_scalars():
    from vtkmodules.vtkCommonDataModel import vtkImageData

    image = vtkImageData()
    image.SetDimensions(2, 2, 2)
    with pytest.raises(VolumeReadError, match="array: the image has no point or cell scalars"):
        from_vtk_image(image)


def test_vti_round_trip(tmp_path):
    from vtkmodules.vtkIOXML import vtkXMLImageDataWriter

    a = _vol((6, 5, 4, 2), np.int16)
    writer = vtkXMLImageDataWriter()
    writer.SetFileName(str(tmp_path / "v.vti"))
    writer.SetInputData(_image(a, spacing=(0.25, 0.25, 1.0)))
    writer.Write()
    data = read_volume(tmp_path / "v.vti")
    np.testing.assert_array_equal(data.array, np.moveaxis(a, -1, 0))
    assert data.voxel_size_um == pytest.approx((0.25, 0.25, 1.0))
    assert data.metadata["format"] == "vti"
    one = read_volume(tmp_path / "v.vti", channels=[1])
    np.testing.assert_array_equal(one.array[0], a[..., 1])


def test_mha_and_legacy_vtk(tmp_path):
    from vtkmodules.vtkIOImage import vtkMetaImageWriter
    from vtkmodules.vtkIOLegacy import vtkStructuredPointsWriter

    a = _vol((6, 5, 4))
    image = _image(a[..., None], spacing=(0.3, 0.3, 0.9))
    mha = vtkMetaImageWriter()
    mha.SetFileName(str(tmp_path / "v.mha"))
    mha.SetInputData(image)
    mha.Write()
    legacy = vtkStructuredPointsWriter()
    legacy.SetFileName(str(tmp_path / "v.vtk"))
    legacy.SetInputData(image)
    legacy.SetFileTypeToBinary()
    legacy.Write()
    for name in ("v.mha", "v.vtk"):
        data = read_volume(tmp_path / name)
        np.testing.assert_array_equal(data.array[0], a)
        assert data.voxel_size_um == pytest.approx((0.3, 0.3, 0.9))


def test_mhd_with_raw_companion(tmp_path):
    from vtkmodules.vtkIOImage import vtkMetaImageWriter

    a = _vol((6, 5, 4))
    writer = vtkMetaImageWriter()
    writer.SetFileName(str(tmp_path / "v.mhd"))
    writer.SetRAWFileName(str(tmp_path / "v.raw"))
    writer.SetCompression(False)
    writer.SetInputData(_image(a[..., None]))
    writer.Write()
    for name in ("v.mhd", "v.raw"):  # opening the data file finds its header
        np.testing.assert_array_equal(read_volume(tmp_path / name).array[0], a)


def test_corrupt_vti(tmp_path):
    (tmp_path / "bad.vti").write_text("<VTKFile type='ImageData'><Image")
    with pytest.raises(VolumeReadError, match=r"^bad\.vti: VTK could not read an image"):
        read_volume(tmp_path / "bad.vti")
