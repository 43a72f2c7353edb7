"""Files whose metadata disagree with their contents, and the smallest valid files: read with a
note saying what was done, or refused in one line; never silently wrong."""

from __future__ import annotations

import numpy as np
import pytest
import tifffile

from vtkvol.io import VolumeReadError, read_volume


def imagej_lie(path, description: str, pages: int = 10):
    data = np.arange(pages, dtype=np.uint8)[:, None, None] * np.ones((1, 6, 7), np.uint8)
    tifffile.imwrite(path, data, description=description, metadata=None)
    return data


@pytest.mark.parametrize(
    ("description", "images"),
    [("slices=5\n", 5), ("channels=3\nhyperstack=true\n", 3),
     ("channels=3\nslices=3\nhyperstack=true\n", 9)],
)
def test_imagej_description_promising_fewer_images_than_pages_loses_no_page(tmp_path,
                                                                            description,
                                                                            images):
    path = tmp_path / "stack.tif"
    data = imagej_lie(path, "ImageJ=1.11a\nimages=10\n" + description)
    volume = read_volume(path)
    # every page is there, in order, as a z slice ...
    np.testing.assert_array_equal(volume.array[0], data)
    # ... and the note says what the description claimed and what was done instead
    assert f"describes {images} images but the file has 10 pages" in volume.notes[0]
    assert "every page read as a z slice" in volume.notes[0]


def test_a_truthful_imagej_hyperstack_is_read_by_its_description(tmp_path):
    path = tmp_path / "hyper.tif"
    data = np.zeros((3, 2, 6, 7), np.uint8)  # z, c, y, x
    data[:, 1] = 9
    tifffile.imwrite(path, data, imagej=True, metadata={"axes": "ZCYX"})
    volume = read_volume(path)
    assert volume.array.shape == (2, 3, 6, 7)
    assert not any("describes" in n for n in volume.notes)


def test_a_one_voxel_tiff_is_a_volume_not_corrupt(tmp_path):
    path = tmp_path / "one.tif"
    tifffile.imwrite(path, np.array([[[7]]], np.uint16))
    volume = read_volume(path)
    assert volume.array.shape == (1, 1, 1, 1) and int(volume.array.ravel()[0]) == 7


@pytest.mark.parametrize(
    ("kind", "values", "message"),
    [("uchar", "300 5", "hold 300, which is not a uint8 value (whole numbers 0…255)"),
     ("short", "-40000 1", "hold -40000, which is not a int16 value"),
     ("uchar", "2.5 1", "hold 2.5, which is not a uint8 value"),
     ("uchar", "7 x", "the text data hold a non-number")],
)
def test_ascii_nrrd_values_outside_the_type_are_refused_not_wrapped(tmp_path, kind, values,
                                                                   message):
    path = tmp_path / "a.nrrd"
    path.write_text(f"NRRD0004\ntype: {kind}\ndimension: 3\nsizes: 2 1 1\nencoding: ascii\n\n"
                    f"{values}\n")
    with pytest.raises(VolumeReadError, match=r"^a\.nrrd: ") as info:
        read_volume(path)
    assert message in str(info.value)


def test_ascii_nrrd_values_inside_the_type_read_exactly(tmp_path):
    path = tmp_path / "a.nrrd"
    path.write_text("NRRD0004\ntype: short\ndimension: 3\nsizes: 3 1 1\nencoding: ascii\n\n"
                    "-32768 0 32767\n")
    np.testing.assert_array_equal(read_volume(path).array.ravel(), [-32768, 0, 32767])


@pytest.mark.parametrize("depth", [70, 600, 5000])
def test_a_session_nested_absurdly_deep_is_a_session_error(tmp_path, depth):
    from vtkvol.model.session import SessionError, read_session

    path = tmp_path / "deep.vtkvol.json"
    path.write_text('{"format": "vtkvol-session", "version": 6, "scene": '
                    + "[" * depth + "]" * depth + "}")
    with pytest.raises(SessionError, match=r"deep\.vtkvol\.json: is nested (more than 64 "
                                           r"levels deep|too deeply)"):
        read_session(path)
