"""VTK image data: ``.vti`` (XML), legacy ``.vtk`` structured points, MetaImage ``.mha/.mhd``,
and in-memory ``vtkImageData`` objects.

VTK is imported lazily, inside the functions, so that ``import vtkvol.io`` stays free of
VTK (docs/architecture.md). VTK stores no length unit; spacing is taken as µm.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from vtkvol.io.errors import VolumeReadError
from vtkvol.io.limits import check_declared_bytes
from vtkvol.io.progress import Progress
from vtkvol.io.registry import ReaderSpec
from vtkvol.io.volume_data import Spacing, VolumeData, normalize_volume, resolve_channels
from vtkvol.io.vtk_headers import check_legacy_vtk_header, check_metaimage_header
from vtkvol.io.xml_arrays import check_xml_arrays

if TYPE_CHECKING:
    from vtkmodules.vtkCommonDataModel import vtkImageData

__all__ = ["VTK_READER", "from_vtk_image", "read_vtk_image_file"]


def _image_to_volume(image: vtkImageData, source: str | None) -> VolumeData:
    """``vtkImageData`` → unchecked :class:`VolumeData` (point scalars; components → channels)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy

    nx, ny, nz = (int(v) for v in image.GetDimensions())
    if min(nx, ny, nz) <= 0:
        raise VolumeReadError(source, f"the image has a zero-size axis: dimensions {(nx, ny, nz)}")
    notes: list[str] = []
    dims = (nz, ny, nx)
    attributes = image.GetPointData()
    scalars = attributes.GetScalars()
    if scalars is None and attributes.GetNumberOfArrays() > 0:
        scalars = attributes.GetArray(0)
        if scalars is not None:
            notes.append(f"no active point scalars; used point array {scalars.GetName()!r}")
    if scalars is None:
        cells = image.GetCellData()
        scalars = cells.GetScalars() or (cells.GetArray(0) if cells.GetNumberOfArrays() else None)
        if scalars is None:
            raise VolumeReadError(source, "the image has no point or cell scalars to display")
        # Cell data: one value per cell of an (n-1)-sized grid.
        dims = (max(nz - 1, 1), max(ny - 1, 1), max(nx - 1, 1))
        notes.append("the image stores cell data; each cell is used as a voxel")
    n_comp = int(scalars.GetNumberOfComponents())
    if not 1 <= n_comp <= 4:
        raise VolumeReadError(
            source, f"the scalars have {n_comp} components; vtkvol reads 1–4 (one per channel)"
        )
    values = vtk_to_numpy(scalars)  # shares VTK's memory and keeps the VTK array alive
    expected = int(np.prod(dims))
    if values.shape[0] != expected:
        raise VolumeReadError(
            source,
            f"the scalars hold {values.shape[0]} tuples for a {dims[2]}×{dims[1]}×{dims[0]} grid",
        )
    if n_comp == 1:
        array = values.reshape(1, *dims)
    else:
        # VTK interleaves components (c fastest); vtkvol keeps channels planar.
        array = np.ascontiguousarray(np.moveaxis(values.reshape(*dims, n_comp), -1, 0))
    name = scalars.GetName() or ""
    if n_comp == 1:
        names = [name or "ch0"]
    else:
        names = [
            scalars.GetComponentName(i) or (f"{name}[{i}]" if name else f"ch{i}")
            for i in range(n_comp)
        ]
    declared = tuple(float(v) for v in image.GetSpacing())
    spacing_raw = [abs(v) for v in declared]
    for i, v in enumerate(spacing_raw):
        if not np.isfinite(v) or v == 0:
            if dims[2 - i] > 1:
                raise VolumeReadError(
                    source, f"invalid spacing {declared}: every axis with more than one voxel "
                            "needs a finite, non-zero spacing"
                )
            spacing_raw[i] = 1.0
            notes.append(f"spacing {declared[i]} on the single-voxel {'xyz'[i]} axis: using 1 µm")
    if any(v < 0 for v in declared):
        notes.append(f"negative spacing {declared}: its magnitude is used (the image is not "
                     "mirrored)")
    metadata: dict[str, Any] = {
        "format": "vtk-image",
        "origin": tuple(float(v) for v in image.GetOrigin()),
        "voxel_size_source": "VTK spacing (taken as µm)",
        "vtk_scalar_type": scalars.GetDataTypeAsString(),
    }
    direction = image.GetDirectionMatrix()
    if direction is not None:
        matrix = np.array([[direction.GetElement(r, c) for c in range(3)] for r in range(3)])
        if not np.allclose(matrix, np.eye(3)):
            notes.append("the image has a rotated direction matrix; it is ignored")
            metadata["direction"] = matrix.tolist()
    return VolumeData(
        array,
        Spacing(*spacing_raw),
        names,
        source=source,
        voxel_size_from_metadata=True,
        metadata=metadata,
        notes=notes,
    )


def from_vtk_image(image: vtkImageData, *, source: str | None = None) -> VolumeData:
    """Wrap any ``vtkImageData`` as a checked :class:`VolumeData`.

    Point scalars (or the first point array, or cell scalars) with 1–4 components become
    channels; spacing becomes the voxel size (x, y, z) in µm. Single-component data share
    VTK's memory when no dtype conversion is needed; multi-component data are copied (VTK
    interleaves components, vtkvol stores channels planar).
    """
    return normalize_volume(_image_to_volume(image, source))


def _vtk_reader_for(path: Path) -> Any:
    suffix = path.suffix.lower()
    if suffix == ".vti":
        from vtkmodules.vtkIOXML import vtkXMLImageDataReader

        return vtkXMLImageDataReader()
    if suffix in (".mha", ".mhd"):
        from vtkmodules.vtkIOImage import vtkMetaImageReader

        return vtkMetaImageReader()
    from vtkmodules.vtkIOLegacy import vtkStructuredPointsReader

    return vtkStructuredPointsReader()


def _check_declared_extent(reader: Any, path: Path) -> None:
    """Refuse a header whose grid, at the bytes per voxel its arrays declare (type ×
    components, all point arrays), exceeds this machine's memory: VTK would abort the process
    allocating it (``std::bad_alloc``)."""
    from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline

    reader.UpdateInformation()
    info = reader.GetOutputInformation(0)
    extent = info.Get(vtkStreamingDemandDrivenPipeline.WHOLE_EXTENT())
    if extent is None:
        return
    dims = [int(extent[2 * a + 1]) - int(extent[2 * a]) + 1 for a in range(3)]
    voxels = int(np.prod([max(d, 0) for d in dims], dtype=object))
    per_voxel, what = _declared_bytes_per_voxel(info)
    check_declared_bytes(path, voxels * per_voxel, f"a {dims[0]}×{dims[1]}×{dims[2]} grid{what}")


def _declared_bytes_per_voxel(info: Any) -> tuple[int, str]:
    """Bytes per voxel of the point arrays the reader's header declares (at least 1), and
    their description (``" of float64 × 4"``) for the message."""
    from vtkmodules.vtkCommonCore import vtkDataArray
    from vtkmodules.vtkCommonDataModel import vtkDataObject

    arrays = info.Get(vtkDataObject.POINT_DATA_VECTOR())
    total, parts = 0, []
    for i in range(arrays.GetNumberOfInformationObjects() if arrays is not None else 0):
        field = arrays.GetInformationObject(i)
        kind = field.Get(vtkDataObject.FIELD_ARRAY_TYPE())
        if kind is None:
            continue
        comps = max(1, field.Get(vtkDataObject.FIELD_NUMBER_OF_COMPONENTS()) or 1)
        total += vtkDataArray.GetDataTypeSize(kind) * comps
        name = _VTK_TYPE_NAMES.get(kind, "values")
        parts.append(f"{name} × {comps}" if comps > 1 else name)
    return max(total, 1), (f" of {' + '.join(parts)}" if parts else "")


#: VTK's scalar type codes (vtkType.h) as numpy dtypes, for messages.
_VTK_TYPE_NAMES = {2: "int8", 3: "uint8", 4: "int16", 5: "uint16", 6: "int32", 7: "uint32",
                   8: "int64", 9: "uint64", 10: "float32", 11: "float64", 12: "int64",
                   13: "uint64", 15: "int8", 16: "int64", 17: "uint64"}


_XML_SPACING = re.compile(rb"<ImageData\b[^>]*?\bSpacing\s*=\s*\"([^\"]*)\"", re.DOTALL)


def _check_xml_spacing(path: Path) -> None:
    """VTK's XML reader silently keeps spacing 1 where the file's ``Spacing`` does not parse
    (``nan``, words): check the attribute as written."""
    with path.open("rb") as fh:
        head = fh.read(65536)
    match = _XML_SPACING.search(head)
    if match is None:
        return
    text = match.group(1).decode("latin-1")
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        values = []
    if len(values) != 3 or not all(np.isfinite(v) for v in values):
        raise VolumeReadError(path, f'invalid Spacing="{text}": expected three finite numbers')


def read_vtk_image_file(
    path: Path,
    *,
    time_index: int = 0,
    channels: Sequence[int | str] | None = None,
    progress: Progress | None = None,
) -> VolumeData:
    """Read ``.vti``, legacy ``.vtk`` (structured points) or MetaImage ``.mha``/``.mhd``."""
    progress = progress or Progress()
    path = Path(path)
    if time_index != 0:
        raise VolumeReadError(
            path, f"time_index {time_index} is out of range: the file has 1 time point (index 0)"
        )
    from vtkmodules.vtkCommonCore import vtkCommand

    reader = _vtk_reader_for(path)
    errors: list[str] = []

    def on_error(_obj: Any, _event: str) -> None:
        errors.append("VTK reported an error while reading")

    # VTK reports problems through its error stream, not exceptions; observe both.
    reader.AddObserver(vtkCommand.ErrorEvent, on_error)
    reader.AddObserver(
        vtkCommand.ProgressEvent, lambda obj, _e: progress(0.9 * obj.GetProgress(), "reading")
    )
    # VTK trusts these headers' numbers (and aborts the process on some): check them first.
    if path.suffix.lower() in (".mha", ".mhd"):
        check_metaimage_header(path)
    elif path.suffix.lower() == ".vtk":
        check_legacy_vtk_header(path)
    if path.suffix.lower() == ".vtk" and hasattr(reader, "IsFileStructuredPoints"):
        reader.SetFileName(str(path))
        if not reader.IsFileStructuredPoints():
            raise VolumeReadError(path, "not a legacy VTK structured-points (image) file")
    reader.SetFileName(str(path))
    if path.suffix.lower() == ".vti":
        _check_xml_spacing(path)
    from vtkmodules.vtkCommonCore import vtkLogger, vtkOutputWindow, vtkStringOutputWindow

    # VTK prints reader errors to the console (output window and logger); collect them for
    # our message instead, and restore both afterwards.
    previous = vtkOutputWindow.GetInstance()
    verbosity = vtkLogger.GetCurrentVerbosityCutoff()
    captured = vtkStringOutputWindow()
    vtkOutputWindow.SetInstance(captured)
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)
    try:
        _check_declared_extent(reader, path)
        if path.suffix.lower() == ".vti":
            check_xml_arrays(path)
        reader.Update()
    finally:
        vtkOutputWindow.SetInstance(previous)
        vtkLogger.SetStderrVerbosity(verbosity)
    for line in captured.GetOutput().splitlines():
        if "rror" in line and line.strip():
            errors.append(line.strip())
    image = reader.GetOutput()
    if errors or image is None or image.GetNumberOfPoints() == 0:
        detail = next((e for e in errors if "Error" in e), "")
        detail = f" ({detail.split(': ', 1)[-1]})" if detail else ""
        raise VolumeReadError(
            path, f"VTK could not read an image from this file (corrupt or empty){detail}"
        )
    data = _image_to_volume(image, str(path))
    data.metadata["format"] = {".vti": "vti", ".vtk": "vtk-legacy"}.get(
        path.suffix.lower(), "metaimage"
    )
    chosen = resolve_channels(channels, data.channel_names, str(path))
    if chosen != list(range(data.n_channels)):
        data.array = np.ascontiguousarray(data.array[chosen])
        data.channel_names = [data.channel_names[c] for c in chosen]
    progress(1.0, f"read {path.name}")
    return data


VTK_READER = ReaderSpec(
    name="vtk",
    label="VTK image (.vti, legacy .vtk, MetaImage .mha/.mhd)",
    filename_patterns=("*.vti", "*.vtk", "*.mha", "*.mhd"),
    accepts_directories=False,
    read=read_vtk_image_file,
)
