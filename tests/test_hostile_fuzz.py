"""Fuzzing the headers vtkvol trusts least: TIFF tags, NRRD fields, ``.npy`` headers, NIfTI,
MRC and Imaris headers, OME-Zarr metadata, session, keyframe and transfer-function JSON, and
the command line's numeric options. Whatever the bytes say, the outcome is the documented
error (:class:`VolumeReadError` from ``read_volume``, :class:`SessionError` from
``read_session``, :class:`KeyframeError`, a one-line ``vtkvol:`` message from the command
line) or a valid result — never another exception.

Bounded in time (a fixed number of examples, derandomised so CI sees the same ones: 100 for
the older readers, 30 for the newer ones; the whole module ran in 21 s on the 2-core
development machine, several times that while it was loaded by other jobs). For a longer hunt:
``VTKVOL_FUZZ_EXAMPLES=5000 pytest tests/test_hostile_fuzz.py``, which also draws new
examples.
"""

from __future__ import annotations

import gzip
import json
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import tifffile

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, example, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from tests_support_hostile import lying_tiff, npy_with_header  # noqa: E402

from vtkvol.io import VolumeData, VolumeReadError, read_volume  # noqa: E402
from vtkvol.model.scene import MAX_COORDINATE_UM, SceneModel  # noqa: E402
from vtkvol.model.session import (  # noqa: E402
    MAX_NESTING,
    Session,
    SessionError,
    read_session,
    save_session,
)
from vtkvol.model.transfer_function import MAX_POINTS  # noqa: E402

EXAMPLES = int(os.environ.get("VTKVOL_FUZZ_EXAMPLES", "0"))
FUZZ = settings(
    max_examples=EXAMPLES or 100,
    derandomize=not EXAMPLES,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
#: The readers and documents added for issue 26 (NIfTI, MRC, Imaris, OME-Zarr, keyframes, TF
#: files, command-line options) write a file or start a library per example: fewer by default.
FUZZ_MORE = settings(FUZZ, max_examples=EXAMPLES or 30)


@pytest.fixture(scope="module", autouse=True)
def bounded_address_space():
    """At most 4 GiB more address space while fuzzing: a header that makes a reader allocate
    what it claims then fails its example (MemoryError, reported as 'not enough free memory')
    instead of having the whole test run killed by the kernel's OOM killer."""
    resource = pytest.importorskip("resource")
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    status = Path("/proc/self/status")
    if not status.exists():
        yield
        return
    size_kb = next(int(line.split()[1]) for line in status.read_text().splitlines()
                   if line.startswith("VmSize:"))
    limit = size_kb * 1024 + 4 * 2**30
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def check_read(path: Path, *, must_refuse: bool = False) -> None:
    """``read_volume(path)`` either refuses with VolumeReadError (having allocated nothing
    large) or returns a valid volume; with ``must_refuse`` (a damaged file) it refuses."""
    try:
        data = read_volume(path)
    except VolumeReadError as exc:
        assert str(exc).startswith(f"{path.name}: "), str(exc)
        assert "not enough free memory" not in str(exc), f"allocated what it claims: {exc}"
        return
    assert not must_refuse, f"a damaged file was read: {data.shape_zyx}, notes {data.notes}"
    assert isinstance(data, VolumeData)
    c, z, y, x = data.array.shape
    assert 1 <= c <= 4 and min(z, y, x) >= 1
    assert data.array.dtype in (np.uint8, np.uint16, np.int16, np.float32)
    assert all(np.isfinite(v) and v > 0 for v in data.voxel_size_um)


def scratch() -> Path:
    return Path(tempfile.mkdtemp(prefix="vtkvol-fuzz-"))


# -- TIFF ----------------------------------------------------------------------------------
sides = st.one_of(st.integers(0, 64), st.integers(0, 2**32 - 1))


@FUZZ
@given(
    width=sides, height=sides, pages=st.integers(1, 4),
    bits=st.sampled_from([0, 1, 4, 7, 8, 12, 16, 24, 32, 64, 128]),
    samples=st.sampled_from([0, 1, 2, 3, 4, 5, 60000]),
    compression=st.sampled_from([0, 1, 5, 7, 8, 32773, 34925, 50000]),
    rows=st.one_of(st.none(), st.integers(0, 2**32 - 1)),
    offset=st.one_of(st.none(), st.integers(0, 2**32 - 1)),
    count=st.one_of(st.none(), st.integers(0, 2**32 - 1)),
    data=st.binary(max_size=256), circular=st.booleans(),
    loop_to=st.one_of(st.none(), st.integers(0, 3)),
)
@example(width=65535, height=65535, pages=4, bits=64, samples=4, compression=8, rows=None,
         offset=None, count=None, data=b"x\x9c\x03\x00", circular=False, loop_to=None)
# Found by this test: a 15 GiB page from 100 bytes (decoded twice over: the run was OOM-killed)
@example(width=63754, height=63754, pages=1, bits=16, samples=2, compression=50000, rows=None,
         offset=None, count=None, data=bytes(100), circular=False, loop_to=None)
# … and 0-bit samples, allocated as float64
@example(width=33, height=6742005, pages=1, bits=0, samples=3, compression=0, rows=None,
         offset=None, count=None, data=b"", circular=False, loop_to=None)
# A valid page whose chain loops back on itself (read as one page before it was refused)
@example(width=4, height=4, pages=1, bits=8, samples=1, compression=1, rows=None, offset=None,
         count=None, data=bytes(range(16)), circular=True, loop_to=None)
@example(width=4, height=4, pages=3, bits=8, samples=1, compression=1, rows=None, offset=None,
         count=None, data=bytes(range(16)), circular=False, loop_to=1)
def test_fuzzed_tiff_tags(width, height, pages, bits, samples, compression, rows, offset, count,
                          data, circular, loop_to):
    """Lying tags, and page chains that loop (``circular``: the last page points back at the
    first; ``loop_to``: at that page, the last itself included): a loop is always refused."""
    folder = scratch()
    path = lying_tiff(folder / "fuzz.tif", width=width, height=height, pages=pages, bits=bits,
                      samples=samples, compression=compression, rows_per_strip=rows,
                      strip_offset=offset, strip_bytes=count, data=data, circular=circular,
                      loop_to=loop_to)
    check_read(path, must_refuse=circular or loop_to is not None)


@pytest.fixture(scope="module")
def valid_tiffs(tmp_path_factory) -> dict[str, bytes]:
    folder = tmp_path_factory.mktemp("tiffs")
    stack = np.arange(3 * 8 * 8, dtype=np.uint16).reshape(3, 8, 8)
    tifffile.imwrite(folder / "ij.tif", stack, imagej=True,
                     metadata={"axes": "ZYX", "spacing": 2.0, "unit": "micron"})
    tifffile.imwrite(folder / "ome.tif", stack.reshape(3, 1, 8, 8), ome=True,
                     metadata={"axes": "ZCYX", "PhysicalSizeX": 0.2})
    tifffile.imwrite(folder / "zlib.tif", stack, compression="zlib")
    return {name: (folder / name).read_bytes() for name in ("ij.tif", "ome.tif", "zlib.tif")}


@FUZZ
@given(which=st.sampled_from(["ij.tif", "ome.tif", "zlib.tif"]),
       flips=st.lists(st.tuples(st.integers(0, 4095), st.integers(0, 255)), min_size=1,
                      max_size=8))
@example(which="ij.tif", flips=[(26, 0)])  # found: tifffile's parser raised TypeError
def test_fuzzed_bytes_of_real_tiffs(valid_tiffs, which, flips):
    """Real TIFFs (ImageJ, OME, compressed) with bytes of their headers changed."""
    blob = bytearray(valid_tiffs[which])
    for position, value in flips:
        blob[position % len(blob)] = value
    path = scratch() / which
    path.write_bytes(bytes(blob))
    check_read(path)


# -- NRRD ----------------------------------------------------------------------------------
def nrrd_number() -> st.SearchStrategy[str]:
    return st.one_of(
        st.integers(-5, 70000).map(str), st.just(str(2**40)),
        st.floats(allow_nan=True, allow_infinity=True).map(repr),
        st.text(alphabet="0123456789.-eEnaif ()", max_size=8),
    )


@FUZZ
@given(
    kind=st.sampled_from(["uchar", "uint8", "short", "ushort", "int", "uint", "float", "double",
                          "int64", "block", "bogus", ""]),
    dimension=st.one_of(st.integers(-1, 6).map(str), st.text(max_size=3)),
    sizes=st.lists(st.one_of(st.integers(-2, 9), st.integers(0, 70000)), max_size=5),
    encoding=st.sampled_from(["raw", "gzip", "bzip2", "ascii", "hex", "zstd", ""]),
    endian=st.sampled_from(["little", "big", "middle"]),
    extra=st.dictionaries(
        st.sampled_from(["spacings", "space directions", "kinds", "space units", "byte skip",
                         "line skip", "space origin", "units"]),
        st.lists(nrrd_number(), min_size=1, max_size=4).map(" ".join), max_size=4),
    detached=st.booleans(),
    data=st.binary(max_size=300),
    compress=st.booleans(),
)
def test_fuzzed_nrrd_headers(kind, dimension, sizes, encoding, endian, extra, detached, data,
                             compress):
    folder = scratch()
    fields = {"type": kind, "dimension": dimension, "sizes": " ".join(map(str, sizes)),
              "encoding": encoding, "endian": endian, **extra}
    payload = gzip.compress(data) if compress else data
    if detached:
        (folder / "d.raw").write_bytes(payload)
        fields["data file"] = "d.raw"
    header = "NRRD0004\n" + "".join(f"{k}: {v}\n" for k, v in fields.items())
    path = folder / ("fuzz.nhdr" if detached else "fuzz.nrrd")
    path.write_bytes(header.encode() + (b"" if detached else b"\n" + payload))
    check_read(path)


# -- .npy ----------------------------------------------------------------------------------
@FUZZ
@given(
    descr=st.one_of(st.sampled_from(["<u1", "|u1", "<u2", ">u2", "<i2", "<f4", ">f8", "<c8",
                                     "|b1", "|O", "<M8[s]", "|V8", "<U4", "x9"]),
                    st.text(max_size=6)),
    fortran=st.sampled_from(["True", "False", "1", "'no'"]),
    shape=st.one_of(st.lists(st.one_of(st.integers(-2, 8), st.integers(0, 2**62)), max_size=5)
                    .map(lambda dims: "(" + "".join(f"{d}, " for d in dims) + ")"),
                    st.text(max_size=12)),
    junk=st.one_of(st.just(""), st.text(max_size=20)),
    version=st.sampled_from([1, 2]),
    payload=st.binary(max_size=600),
)
@example(descr="<u1", fortran="True", shape="()", junk="[", version=1, payload=b"")  # found:
# numpy's header parser raised tokenize.TokenError
def test_fuzzed_npy_headers(descr, fortran, shape, junk, version, payload):
    header = f"{{'descr': {descr!r}, 'fortran_order': {fortran}, 'shape': {shape}, {junk}}}"
    path = npy_with_header(scratch() / "fuzz.npy", header, payload, version)
    check_read(path)


# -- session JSON --------------------------------------------------------------------------
json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-10**6, 10**6) | st.floats(allow_nan=False)
    | st.text(max_size=12),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner,
                                                                 max_size=4),
    max_leaves=12,
)


@pytest.fixture(scope="module")
def session_document(tmp_path_factory) -> dict[str, Any]:
    path = save_session(tmp_path_factory.mktemp("session") / "valid", SceneModel())
    return json.loads(path.read_text(encoding="utf-8"))


def _paths(value: Any, prefix: tuple = ()) -> list[tuple]:
    out = [prefix]
    if isinstance(value, dict):
        for key, item in value.items():
            out += _paths(item, (*prefix, key))
    elif isinstance(value, list):
        for i, item in enumerate(value):
            out += _paths(item, (*prefix, i))
    return out


def _replace(document: Any, path: tuple, value: Any, delete: bool) -> Any:
    if not path:
        return value
    head, rest = path[0], path[1:]
    copy = dict(document) if isinstance(document, dict) else list(document)
    if delete and not rest:
        del copy[head]
    else:
        copy[head] = _replace(copy[head], rest, value, delete)
    return copy


def _edited(document: Any, edits: list[tuple[int, Any, bool]]) -> Any:
    """``document`` with each edit applied in turn: (which value, by its index among all the
    values' paths, modulo their count; the new value; or delete it)."""
    for index, value, delete in edits:
        paths = _paths(document)
        document = _replace(document, paths[index % len(paths)], value, delete)
    return document


@FUZZ
@given(edits=st.lists(st.tuples(st.integers(0, 10**6), json_values, st.booleans()), min_size=1,
                      max_size=4))
def test_fuzzed_session_json(session_document, edits):
    """A valid session with values replaced by any JSON or keys removed, anywhere."""
    document = _edited(session_document, edits)
    path = scratch() / "fuzz.vtkvol.json"
    path.write_text(json.dumps(document), encoding="utf-8")
    check_session(path)


@FUZZ
@given(blob=st.one_of(st.binary(max_size=300), st.text(max_size=300).map(str.encode)))
def test_fuzzed_session_bytes(blob):
    path = scratch() / "fuzz.vtkvol.json"
    path.write_bytes(blob)
    check_session(path)


#: Marks a number written as ``1e999`` (parsed as infinity by Python's JSON reader).
OVERFLOW = 9.87654321e307
coordinate = st.one_of(
    st.floats(-1e3, 1e3), st.sampled_from([0.0, -0.0, 1e12, -1e13, 1e154, 1e200, 1e308,
                                           -1e308, 5e-324, OVERFLOW]),
    st.floats(allow_nan=True, allow_infinity=True),
)
vector = st.one_of(st.tuples(coordinate, coordinate, coordinate),
                   st.sampled_from([(0.0, 0.0, 0.0), (7.5, 7.5, 7.5)]))


@st.composite
def points(draw, n: int, width: int) -> list[list[float]]:
    xs = np.sort(np.asarray(draw(st.lists(st.floats(-1e6, 1e6), min_size=2, max_size=2))))
    values = np.linspace(xs[0], xs[1], n)
    return [[float(v), *([float(i % 2)] * (width - 1))] for i, v in enumerate(values)]


def nested(depth: int, leaf: str) -> str:
    """JSON text of ``leaf`` (JSON text) inside ``depth`` alternating arrays and objects, built
    as text (json.dumps recurses, and stops far short of 50 000 levels)."""
    opening = "".join('{"k": ' if level % 2 else "[" for level in range(depth))
    closing = "".join("}" if level % 2 else "]" for level in reversed(range(depth)))
    return opening + leaf + closing


@FUZZ
@given(
    position=st.one_of(st.none(), vector), focal=st.one_of(st.none(), vector),
    up=vector, direction=vector, light_position=vector,
    parallel_scale=st.sampled_from([1.0, 1e12, 1e300]),
    n_colors=st.sampled_from([1, 2, 17, MAX_POINTS, MAX_POINTS + 1, 1500]),
    n_opacity=st.sampled_from([1, 2, 17, MAX_POINTS, MAX_POINTS + 1, 1500]),
    data=st.data(),
    depth=st.sampled_from([0, 0, 5, MAX_NESTING - 2, MAX_NESTING, 500, 50_000]),
    where=st.sampled_from(["window", "scene.overlays", "scene.illumination.parameters",
                           "scene.channels.0.tf"]),
)
@example(position=(1e308, 1e308, 1e308), focal=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0),
         direction=(0.3, 0.5, 0.8), light_position=(0.0, 0.0, 1.0), parallel_scale=1.0,
         n_colors=2, n_opacity=2, data=None, depth=0, where="window")
@example(position=(7.5, 7.5, 7.5), focal=(7.5, 7.5, 7.5), up=(0.0, 0.0, 0.0),
         direction=(1e200, 1e200, 1e200), light_position=(0.0, 0.0, 1.0), parallel_scale=1.0,
         n_colors=100_000, n_opacity=100_000, data=None, depth=0, where="window")
def test_fuzzed_session_views(session_document, position, focal, up, direction, light_position,
                              parallel_scale, n_colors, n_opacity, data, depth, where):
    """Non-finite, huge and degenerate cameras and lights, very large transfer functions and
    deep nesting: refused with a SessionError, or read as a view that can be rendered."""
    document = json.loads(json.dumps(session_document))
    scene = document["scene"]
    scene["camera"].update(position=position, focal_point=focal, view_up=up,
                           parallel_scale=parallel_scale)
    scene["lights"][0].update(direction=direction, position=light_position)
    tf = scene["channels"][0]["tf"]
    if data is None:  # an @example: a fixed span
        tf["colors"] = [[float(x), 0.5, 0.5, 0.5] for x in np.linspace(0, 255, n_colors)]
        tf["opacity"] = [[float(x), float(i % 2)] for i, x in
                         enumerate(np.linspace(0, 255, n_opacity))]
    else:
        tf["colors"] = data.draw(points(n_colors, 4))
        tf["opacity"] = data.draw(points(n_opacity, 2))
    deep = ""
    if depth:
        *parents, key = where.split(".")
        target = document
        for part in parents:
            target = target[int(part)] if isinstance(target, list) else target[part]
        deep = nested(depth, json.dumps(target[key]))
        target[key] = "__DEEP__"
    text = json.dumps(document).replace(repr(OVERFLOW), "1e999")
    text = text.replace('"__DEEP__"', deep)
    path = scratch() / "view.vtkvol.json"
    path.write_text(text, encoding="utf-8")
    session = check_session(path)
    if session is None:
        return
    camera = session.model.camera
    for vec in (camera.position, camera.focal_point, session.model.lights[0].position):
        assert vec is None or max(map(abs, vec)) <= MAX_COORDINATE_UM
    assert camera.parallel_scale <= MAX_COORDINATE_UM
    up_vec = np.asarray(camera.view_up, float)
    up_vec = up_vec / np.abs(up_vec).max()
    assert np.linalg.norm(up_vec) > 0
    if camera.position is not None and camera.focal_point is not None:
        forward = np.subtract(camera.focal_point, camera.position)
        assert np.linalg.norm(forward) > 0
        forward /= np.linalg.norm(forward)
        assert np.linalg.norm(np.cross(up_vec / np.linalg.norm(up_vec), forward)) > 1e-6
    assert np.isfinite(np.sum(np.square(session.model.lights[0].direction)))
    for channel in session.model.channels:
        assert len(channel.tf.colors) <= MAX_POINTS and len(channel.tf.opacity) <= MAX_POINTS


def check_session(path: Path) -> Session | None:
    """The session read (and applied to a fresh model), or None when it was refused with a
    :class:`SessionError` naming the file; any other exception fails."""
    try:
        session = read_session(path)
    except SessionError as exc:
        assert str(exc).startswith(f"{path.name}: "), str(exc)
        return None
    assert isinstance(session, Session)
    session.apply_to(SceneModel())  # a session that reads is one that applies
    return session


# -- NIfTI headers -------------------------------------------------------------------------
nifti_floats = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=32),
                         st.sampled_from([0.0, 1.0, -1.0, 1e-30, 3e38]))


@FUZZ_MORE
@given(
    dims=st.lists(st.one_of(st.integers(-3, 9), st.integers(-32768, 32767)), min_size=8,
                  max_size=8),
    datatype=st.sampled_from([0, 1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 768, 1024, 1280, 1536,
                              1792, 2048, 2304, 32767]),
    bitpix=st.sampled_from([0, 1, 8, 16, 24, 32, 64, 128, 256, -8]),
    pixdim=st.lists(nifti_floats, min_size=8, max_size=8),
    vox_offset=st.one_of(st.sampled_from([352.0, 0.0, 348.0, 353.0, 1e9, -1.0]), nifti_floats),
    scaling=st.tuples(nifti_floats, nifti_floats),
    units=st.integers(0, 255),
    sizeof_hdr=st.sampled_from([348, 540, 0, 1000]),
    compress=st.booleans(),
    payload=st.binary(max_size=600),
)
@example(dims=[3, 1500, 1000, 1000, 1, 1, 1, 1], datatype=512, bitpix=16, pixdim=[1.0] * 8,
         vox_offset=352.0, scaling=(1.0, 0.0), units=2, sizeof_hdr=348, compress=True,
         payload=bytes(600))  # issue 26: a 1 KiB gzip declaring 3 GB
def test_fuzzed_nifti_headers(dims, datatype, bitpix, pixdim, vox_offset, scaling, units,
                              sizeof_hdr, compress, payload):
    import struct

    nib = pytest.importorskip("nibabel")
    image = nib.Nifti1Image(np.arange(60, dtype=np.uint8).reshape(3, 4, 5), np.eye(4))
    blob = bytearray(image.to_bytes())[:352]
    struct.pack_into("<i", blob, 0, sizeof_hdr)
    struct.pack_into("<8h", blob, 40, *dims)
    struct.pack_into("<2h", blob, 70, datatype, bitpix)
    struct.pack_into("<8f", blob, 76, *pixdim)
    struct.pack_into("<3f", blob, 108, vox_offset, *scaling)
    blob[123] = units
    data = bytes(blob) + payload
    path = scratch() / ("fuzz.nii.gz" if compress else "fuzz.nii")
    path.write_bytes(gzip.compress(data) if compress else data)
    check_read(path)


# -- MRC headers ---------------------------------------------------------------------------
@FUZZ_MORE
@given(
    size=st.lists(st.one_of(st.integers(-2, 8), st.integers(0, 2**31 - 1)), min_size=3,
                  max_size=3),
    mode=st.sampled_from([0, 1, 2, 3, 4, 6, 12, 101, 5, -1, 2**31 - 1]),
    axes=st.lists(st.integers(-1, 8), min_size=3, max_size=3),
    cell=st.lists(st.floats(allow_nan=True, allow_infinity=True, width=32), min_size=3,
                  max_size=3),
    nsymbt=st.one_of(st.just(0), st.integers(-5, 2**31 - 1)),
    payload=st.binary(max_size=400),
)
@example(size=[2, -2, 65], mode=2, axes=[0, 0, 0], cell=[0.0, 0.0, 0.0], nsymbt=0,
         payload=b"")  # found: numpy's memmap raised OverflowError for the negative size
def test_fuzzed_mrc_headers(size, mode, axes, cell, nsymbt, payload):
    import struct

    mrcfile = pytest.importorskip("mrcfile")
    path = scratch() / "fuzz.mrc"
    with mrcfile.new(str(path)) as mrc:
        mrc.set_data(np.zeros((3, 4, 5), np.int16))
    blob = bytearray(path.read_bytes()[:1024])
    struct.pack_into("<4i", blob, 0, *size, mode)
    struct.pack_into("<3f", blob, 40, *cell)
    struct.pack_into("<3i", blob, 64, *axes)
    struct.pack_into("<i", blob, 92, nsymbt)
    path.write_bytes(bytes(blob) + payload)
    check_read(path)


# -- Imaris headers ------------------------------------------------------------------------
imaris_text = st.one_of(st.integers(-2, 9).map(str), st.just(str(2**40)),
                        st.floats(allow_nan=True, allow_infinity=True).map(repr),
                        st.text(alphabet="0123456789.-eE xyz", max_size=6))


@FUZZ_MORE
@given(
    attrs=st.dictionaries(st.sampled_from(["X", "Y", "Z", "ExtMin0", "ExtMax0", "ExtMin1",
                                           "ExtMax1", "ExtMin2", "ExtMax2", "Unit"]),
                          imaris_text, max_size=10),
    time_name=st.sampled_from(["TimePoint 0", "TimePoint zero", "TimePoint -1", "TimePoint 00",
                               "TimePoint", "TimePoint 1"]),
    channel_name=st.sampled_from(["Channel 0", "Channel A", "Channel 1", "Channel 0x"]),
    kind=st.sampled_from(["data", "data-as-group", "channel-as-dataset", "level-as-dataset",
                          "time-as-dataset"]),
    shape=st.lists(st.integers(0, 6), min_size=1, max_size=4),
    level1=st.one_of(st.none(), st.dictionaries(
        st.sampled_from(["ImageSizeX", "ImageSizeY", "ImageSizeZ"]), imaris_text)),
)
@example(attrs={"X": "4", "Y": "3", "Z": "2"}, time_name="TimePoint zero",
         channel_name="Channel 0", kind="data", shape=[2, 3, 4], level1=None)  # issue 26
@example(attrs={"X": "4", "Y": "3", "Z": "2"}, time_name="TimePoint 0",
         channel_name="Channel 0", kind="level-as-dataset", shape=[2, 3, 4], level1=None)
def test_fuzzed_imaris_headers(attrs, time_name, channel_name, kind, shape, level1):
    h5py = pytest.importorskip("h5py")
    path = scratch() / "fuzz.ims"
    with h5py.File(path, "w") as f:
        image = f.create_group("DataSetInfo/Image")
        for key, value in attrs.items():
            image.attrs[key] = np.array([c.encode() for c in value] or [b""], dtype="S1")
        level = "DataSet/ResolutionLevel 0"
        where = f"{level}/{time_name}/{channel_name}"
        data = np.zeros(shape, np.uint8)
        if kind == "level-as-dataset":
            f.create_dataset(level, data=data)
        elif kind == "time-as-dataset":
            f.create_dataset(f"{level}/{time_name}", data=data)
        elif kind == "channel-as-dataset":
            f.create_dataset(where, data=data)
        elif kind == "data-as-group":
            f.create_group(f"{where}/Data")
        else:
            f.create_dataset(f"{where}/Data", data=data)
        if level1 is not None:
            group = f.create_group(f"DataSet/ResolutionLevel 1/{time_name}/{channel_name}")
            for key, value in level1.items():
                group.attrs[key] = np.array([c.encode() for c in value] or [b""], dtype="S1")
            group.create_dataset("Data", data=data)
    check_read(path)


# -- OME-Zarr metadata ---------------------------------------------------------------------
@pytest.fixture(scope="module")
def ome_zarr_folder(tmp_path_factory) -> Path:
    zarr = pytest.importorskip("zarr")
    path = tmp_path_factory.mktemp("omezarr") / "valid.ome.zarr"
    group = zarr.open_group(str(path), mode="w", zarr_format=3)
    for level, side in (("0", 8), ("1", 4)):
        array = group.create_array(level, shape=(1, 2, side, side), chunks=(1, 2, side, side),
                                   dtype="uint16", dimension_names=["c", "z", "y", "x"])
        array[:] = np.arange(2 * side * side, dtype=np.uint16).reshape(1, 2, side, side)
    group.attrs["ome"] = {"version": "0.5", "multiscales": [{
        "axes": [{"name": "c", "type": "channel"},
                 *({"name": a, "type": "space", "unit": "micrometer"} for a in "zyx")],
        "datasets": [{"path": level, "coordinateTransformations": [
            {"type": "scale", "scale": [1.0, 2.0, s, s]}]} for level, s in (("0", 0.5),
                                                                         ("1", 1.0))]}],
        "omero": {"channels": [{"label": "nuclei", "color": "00FF00"}]}}
    return path


@FUZZ_MORE
@given(edits=st.lists(st.tuples(st.integers(0, 10**6), json_values, st.booleans()), min_size=1,
                      max_size=4))
def test_fuzzed_ome_zarr_metadata(ome_zarr_folder, edits):
    """A valid OME-Zarr image whose group metadata has values replaced or keys removed."""
    import shutil

    folder = scratch() / "fuzz.ome.zarr"
    shutil.copytree(ome_zarr_folder, folder)
    document: Any = json.loads((folder / "zarr.json").read_text())
    document["attributes"] = _edited(document["attributes"], edits)
    (folder / "zarr.json").write_text(json.dumps(document))
    check_read(folder)


# -- keyframe and transfer-function JSON ---------------------------------------------------
@pytest.fixture(scope="module")
def keyframe_document() -> dict[str, Any]:
    camera = {"position": [0.0, -100.0, 0.0], "focal_point": [0.0, 0.0, 0.0],
              "view_up": [0.0, 0.0, 1.0], "view_angle": 30.0, "parallel_projection": False,
              "parallel_scale": 10.0}
    return {"format": "vtkvol-keyframes", "version": 1, "easing": "smooth",
            "time_index_interpolation": "linear", "keyframes": [
                {"time": 0.0, "camera": camera, "time_index": 0,
                 "lights": [{"direction": [0.0, 0.0, -1.0], "intensity": 1.0}]},
                {"time": 2.0, "camera": dict(camera, position=[100.0, 0.0, 0.0]),
                 "time_index": 3, "lights": [{"direction": [1.0, 0.0, 0.0], "intensity": 0.5}]}]}


big_numbers = st.one_of(st.floats(allow_nan=False, allow_infinity=False),
                        st.sampled_from([1e308, -1e308, 10**400, 1e-320, 0]))


@FUZZ_MORE
@given(edits=st.lists(st.tuples(st.integers(0, 10**6), st.one_of(json_values, big_numbers),
                                st.booleans()), min_size=1, max_size=4))
# issue 26: a last keyframe at 1e308 s (OverflowError), a camera at 1e308 µm (numpy warnings)
@example(edits=[(33, 1e308, False)])
@example(edits=[(36, 1e308, False)])
def test_fuzzed_keyframe_json(keyframe_document, edits):
    """A valid keyframe file with values replaced or keys removed: KeyframeError naming the
    file, or an animation that counts its frames and interpolates without numpy warnings."""
    import warnings

    from vtkvol.model.keyframes import MAX_FRAMES, KeyframeError, read_keyframes

    document = _edited(keyframe_document, edits)
    path = scratch() / "fuzz.keyframes.json"
    path.write_text(json.dumps(document), encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a numpy overflow warning fails the example
        try:
            animation = read_keyframes(path)
        except KeyframeError as exc:
            assert str(exc).startswith("fuzz.keyframes.json: ") and "\n" not in str(exc)
            return
        try:
            count = animation.frame_count(30)
        except KeyframeError as exc:
            assert "frames; at most" in str(exc)
            return
        assert 1 <= count <= MAX_FRAMES
        for t in (0.0, animation.duration / 3, animation.duration):
            state = animation.state_at(t)
            assert all(np.isfinite(state.camera.position))


@FUZZ_MORE
@given(edits=st.lists(st.tuples(st.integers(0, 10**6), st.one_of(json_values, big_numbers),
                                st.booleans()), min_size=1, max_size=4),
       nest=st.sampled_from([0, 0, 0, 20, 5000]))
def test_fuzzed_tf_json(edits, nest):
    """A saved transfer function with values replaced, keys removed, or wrapped in brackets:
    a one-line ValueError naming the file, or a transfer function."""
    pytest.importorskip("PySide6")
    from vtkvol.model.transfer_function import TransferFunction
    from vtkvol.ui.docks.transfer_function import read_tf_file, write_tf_file

    path = write_tf_file(scratch() / "fuzz.tf.json",
                         TransferFunction.ramp(0.0, 100.0, (0.2, 0.9, 0.3)))
    document = _edited(json.loads(path.read_text()), edits)
    path.write_text("[" * nest + json.dumps(document) + "]" * nest)
    try:
        tf = read_tf_file(path)
    except ValueError as exc:
        assert str(exc).startswith("fuzz.tf.json: ") and "\n" not in str(exc), str(exc)
        return
    assert isinstance(tf, TransferFunction)


# -- the command line's numeric options ----------------------------------------------------
option_values = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-2**70, 2**70).map(str),
    st.sampled_from(["nan", "inf", "-inf", "1e999", "0", "-0", "1", "3", "1e308", "1e-308"]),
)
RENDER_OPTIONS = {"--size": 2, "--azimuth": 1, "--elevation": 1, "--time": 1,
                  "--turntable": 1, "--frames": 1, "--fps": 1, "--iterations": 1,
                  "--time-budget": 1, "--param": 1}
BATCH_OPTIONS = {"--size": 2, "--azimuth": 1, "--elevation": 1, "--workers": 1, "--time": 1,
                 "--connect-timeout": 1, "--iterations": 1, "--time-budget": 1,
                 "--voxel-size": 3, "--param": 1, "--egl-devices": 1}


@FUZZ_MORE
@given(command=st.sampled_from(["render", "batch", "info", "convert", "bench"]),
       options=st.lists(st.tuples(st.integers(0, 100), st.lists(option_values, min_size=3,
                                                                max_size=3)),
                        min_size=1, max_size=3))
@example(command="render", options=[(4, ["nan", "0", "0"])])  # --turntable nan (issue 26)
@example(command="render", options=[(4, ["360", "0", "0"]), (5, ["1000000000", "0", "0"])])
@example(command="batch", options=[(4, ["0:1000000000000", "0", "0"])])
def test_fuzzed_cli_numeric_options(command, options):
    """Any numbers for the numeric options: refused in one ``vtkvol:`` line, or passed on to
    the work (stubbed here: nothing renders) as finite values within their limits."""
    import contextlib
    import io

    from vtkvol import cli

    folder = scratch()
    np.save(folder / "v.npy", np.zeros((4, 4, 4), np.uint8))
    table = {"render": RENDER_OPTIONS, "batch": BATCH_OPTIONS,
             "info": {"--voxel-size": 3}, "convert": {"--voxel-size": 3, "--time": 1},
             "bench": {"--size": 1}}[command]
    base = {"render": ["render", "sample", "-o", str(folder / "x.png")],
            "batch": ["batch", "sample", "-o", str(folder / "out")],
            "info": ["info", str(folder / "v.npy")],
            "convert": ["convert", str(folder / "v.npy"), str(folder / "v.zarr")],
            "bench": ["bench", "-o", str(folder / "bench")]}[command]
    argv = list(base)
    names = list(table)
    for pick, values in options:
        name = names[pick % len(names)]
        if name == "--param":
            argv.append(f"--param=shadow_strength={values[0]}")
        elif name == "--time" and command == "batch":
            argv.append(f"--time={values[0].lstrip('-')}:{values[1].lstrip('-')}")
        else:
            argv += [f"{name}={values[0]}"] if table[name] == 1 else [name, *values[:table[name]]]
    reached: list[dict[str, Any]] = []

    def record(**kwargs: Any) -> Any:
        reached.append(kwargs)
        return kwargs.get("result")

    err = io.StringIO()
    with pytest.MonkeyPatch.context() as mp, contextlib.redirect_stderr(err), \
            contextlib.redirect_stdout(io.StringIO()):
        import vtkvol.batch
        import vtkvol.bench.runner
        import vtkvol.engine.api
        import vtkvol.io
        import vtkvol.io.convert
        import vtkvol.movie

        tiny = VolumeData.from_array(np.zeros((1, 4, 4, 4), np.uint8), (1.0, 1.0, 1.0))
        mp.setattr(vtkvol.io, "confocal_phantom", lambda *a, **k: tiny)
        mp.setattr(vtkvol.engine.api, "render_image",
                   lambda data, **k: record(result=np.zeros((k["size"][1], k["size"][0], 3),
                                                            np.uint8), **k))
        mp.setattr(vtkvol.movie, "turntable_frames", lambda data, **k: record(result=[], **k))
        mp.setattr(vtkvol.movie, "write_movie", lambda frames, out, **k: record(
            result=[Path(out)], **k))
        mp.setattr(cli, "_write_png", lambda image, path, replace=True: None)
        mp.setattr(vtkvol.batch, "run_batch", lambda jobs, **k: record(result=[], jobs=jobs, **k))

        def convert(*args: Any, **kwargs: Any) -> Any:
            record(**kwargs)
            raise vtkvol.io.convert.ConvertError("stub: nothing converted")

        mp.setattr(vtkvol.io.convert, "convert_to_ome_zarr", convert)
        mp.setattr(vtkvol.bench.runner, "main", lambda **k: record(result=0, **k))
        try:
            code = cli.main(argv)
        except SystemExit as exc:  # argparse: a value of the wrong type
            code = exc.code
    text = err.getvalue()
    if code not in (0, None) and not reached:
        lines = text.splitlines()
        assert len(lines) == 1 and lines[0].startswith("vtkvol: "), (argv, text)
        return
    for kwargs in reached:  # what reached the work is usable
        for key, value in kwargs.items():
            for v in (value if isinstance(value, (list, tuple)) else [value]):
                if isinstance(v, float):
                    assert np.isfinite(v), (argv, key, value)
        if "n_frames" in kwargs:
            assert 1 <= kwargs["n_frames"] <= 100_000, argv
        if "jobs" in kwargs:
            assert len(kwargs["jobs"]) <= 100_000, argv
        if "workers" in kwargs and kwargs.get("scheduler") is None:
            assert kwargs["workers"] <= vtkvol.batch.max_local_workers(), argv
