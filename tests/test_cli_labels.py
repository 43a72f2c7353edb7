"""`vtkvol render --labels`: a segmentation shown one colour per id, and its refusals."""

from __future__ import annotations

import numpy as np
import pytest
import tifffile

from vtkvol.cli import main
from vtkvol.model.labels import label_colors


def label_stack(path, dtype=np.uint16, ids=(3, 7, 12)):
    arr = np.zeros((16, 32, 32), dtype)
    for n, label in enumerate(ids):
        arr[4:12, 4:28, 2 + 10 * n: 10 + 10 * n] = label
    tifffile.imwrite(path, arr, imagej=True, metadata={"axes": "ZYX"})
    return path


def hues(image: np.ndarray) -> np.ndarray:
    """Unit RGB directions of the pixels that show the volume (the background is (20, 20, 26);
    a dark label colour such as glasbey's (0, 83, 0) must count too)."""
    px = image.reshape(-1, 3).astype(float)
    px = px[px.max(axis=1) > 45]
    return px / np.linalg.norm(px, axis=1, keepdims=True)


@pytest.mark.gl
def test_labels_render_in_their_glasbey_colours(tmp_path, capsys):
    src = label_stack(tmp_path / "seg.tif")
    plain, labelled = tmp_path / "plain.png", tmp_path / "labels.png"
    assert main(["render", str(src), "-o", str(plain), "--size", "64", "64"]) == 0
    assert main(["render", str(src), "-o", str(labelled), "--size", "64", "64", "--labels"]) == 0
    import imageio.v3 as iio

    got = hues(iio.imread(labelled)[..., :3])
    expected = label_colors([3, 7, 12])[:, :3].astype(float)
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    # the lit pixels have the hue of one of the ids (shading scales brightness, not hue;
    # specular highlights add white) ...
    def share_in_label_hues(rgb: np.ndarray) -> float:
        return float(np.mean(np.max(rgb @ expected.T, axis=1) > 0.98))

    assert len(got) > 50 and share_in_label_hues(got) > 0.85
    assert share_in_label_hues(hues(iio.imread(plain)[..., :3])) < 0.5  # without: one tint
    # ... and each id's colour shows up
    assert all(np.sum(got @ e > 0.98) >= 5 for e in expected)
    assert not np.array_equal(iio.imread(plain), iio.imread(labelled))


@pytest.mark.parametrize(
    ("kind", "message"),
    [("float", "holds float32 values; label ids are integers"),
     ("empty", "has no label other than 0"),
     ("span", "span 1…9000, more than 4000: renumber them first")],
)
def test_labels_refusals_name_the_problem(tmp_path, capsys, kind, message):
    if kind == "float":
        src = label_stack(tmp_path / "seg.tif", dtype=np.float32)
    elif kind == "empty":
        src = label_stack(tmp_path / "seg.tif", ids=(0, 0, 0))
    else:
        src = label_stack(tmp_path / "seg.tif", ids=(1, 500, 9000))
    out = tmp_path / "never.png"
    assert main(["render", str(src), "-o", str(out), "--size", "32", "32", "--labels"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("vtkvol: --labels: seg.tif") and message in err
    assert not out.exists()
