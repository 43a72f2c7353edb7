"""Fuzzing the headers vtkvol trusts least: TIFF tags, NRRD fields, ``.npy`` headers and session
JSON. Whatever the bytes say, the outcome is the documented error (:class:`VolumeReadError`
from ``read_volume``, :class:`SessionError` from ``read_session``) or a valid result — never
another exception.

Bounded in time (a fixed number of examples, derandomised so CI sees the same ones; the whole
module runs in about 30 s on a loaded 2-core machine). For a longer hunt:
``VTKVOL_FUZZ_EXAMPLES=5000 pytest tests/test_hostile_fuzz.py``, which also draws new examples.
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
from vtkvol.model.scene import SceneModel  # noqa: E402
from vtkvol.model.session import (  # noqa: E402
    MAX_COORDINATE_UM,
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


@FUZZ
@given(edits=st.lists(st.tuples(st.integers(0, 10**6), json_values, st.booleans()), min_size=1,
                      max_size=4))
def test_fuzzed_session_json(session_document, edits):
    """A valid session with values replaced by any JSON or keys removed, anywhere."""
    document: Any = session_document
    for index, value, delete in edits:
        paths = _paths(document)
        document = _replace(document, paths[index % len(paths)], value, delete)
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
