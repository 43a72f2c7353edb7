"""OME-Zarr over HTTP: a real local server (tests_support_http) serves a generated 5-level
pyramid; the bytes it sends are counted. No internet is used."""

from __future__ import annotations

import socket
from pathlib import Path

import numpy as np
import pytest

zarr = pytest.importorskip("zarr")
pytest.importorskip("fsspec")
pytest.importorskip("aiohttp")
writer = pytest.importorskip("ome_zarr.writer")
ome_format = pytest.importorskip("ome_zarr.format")

from tests_support_http import (  # noqa: E402
    SIDE,
    VOXEL,
    CountingServer,
    chunk_files,
    phantom,
    write_served_stores,
)

from vtkvol import cli  # noqa: E402
from vtkvol.io import VolumeReadError, read_volume  # noqa: E402
from vtkvol.io import remote as remote_module  # noqa: E402
from vtkvol.io.remote import is_remote  # noqa: E402


@pytest.fixture(scope="module")
def store(tmp_path_factory) -> Path:
    return write_served_stores(tmp_path_factory.mktemp("served"))


@pytest.fixture
def server(store):
    with CountingServer(store) as srv:
        yield srv


def _level_bytes(store: Path, level: str) -> int:
    return sum(f.stat().st_size for f in chunk_files(store / "cells.ome.zarr" / level).values())


def test_addresses_are_told_from_paths():
    assert is_remote("https://example.org/a.ome.zarr") and is_remote("s3://bucket/a.zarr")
    assert is_remote("HTTP://host/x.zarr")
    assert not is_remote("/data/a.ome.zarr") and not is_remote(Path("http:/x"))


def test_default_open_fetches_only_the_chosen_levels_chunks(server, store):
    data = read_volume(f"{server.url}/cells.ome.zarr")
    assert data.metadata["level"] == 0  # 1 MiB fits the default GPU budget
    assert data.source == f"{server.url}/cells.ome.zarr"
    np.testing.assert_array_equal(data.array, phantom())
    assert data.channel_names == ["DAPI", "GFP"]
    assert data.voxel_size_um == pytest.approx((0.5, 0.5, 1.0))
    chosen = _level_bytes(store, "s0")
    sent = server.total()
    print(f"default open: {sent} bytes sent, level 0 chunks {chosen} bytes "
          f"({sent / chosen:.3f}×)")
    assert chosen <= sent <= 1.2 * chosen
    coarser = [p for p in server.sent if p.split("/")[2] in ("s1", "s2", "s3", "s4") and
               Path(p).name not in (".zarray", ".zattrs", ".zgroup", "zarr.json")]
    assert coarser == []


def test_budget_chooses_a_coarse_level_and_no_finer_chunk_moves(server, store):
    budget = 2 * 64 * 16 * 16 * 2  # level 2 (2 channels × 64×16×16 uint16) fits, 1 does not
    data = read_volume(f"{server.url}/cells.ome.zarr", memory_budget_bytes=budget)
    assert data.metadata["level"] == 2 and data.array.shape == (2, 64, 16, 16)
    fetched_levels = {p.split("/")[2] for p in server.sent
                      if Path(p).name not in (".zarray", ".zattrs", ".zgroup", ".zmetadata",
                                                "zarr.json")}
    assert fetched_levels == {"s2"}
    level2 = _level_bytes(store, "s2")
    assert server.total() - level2 < 8000  # the rest is metadata: a few hundred bytes a file


def test_refining_a_quarter_fetches_that_quarters_chunks(server, store):
    url = f"{server.url}/cells.ome.zarr"
    read_volume(url, memory_budget_bytes=2 * 64 * 16 * 16 * 2)  # the overview, as the app does
    server.reset()
    half = (SIDE // 2 - 1) * VOXEL["x"]  # voxel centres 0…31 in x and y: 2×2 of 4×4 chunks
    region = ((0.0, half), (0.0, half), (0.0, (SIDE - 1) * VOXEL["z"]))
    data = read_volume(url, region_um=region)
    assert data.metadata["level"] == 0
    assert data.array.shape == (2, SIDE, SIDE // 2, SIDE // 2)
    np.testing.assert_array_equal(data.array, phantom()[:, :, :32, :32])
    files = chunk_files(store / "cells.ome.zarr" / "s0")
    inside = sum(f.stat().st_size for (c, z, y, x), f in files.items() if y < 2 and x < 2)
    sent = server.total()
    print(f"quarter refine: {sent} bytes sent, region chunks {inside} bytes "
          f"({sent / inside:.3f}×)")
    assert inside <= sent <= 1.2 * inside


def test_progress_is_reported_while_fetching(server):
    seen: list[tuple[float, str]] = []
    read_volume(f"{server.url}/cells.ome.zarr", progress=lambda f, m: seen.append((f, m)))
    fractions = [f for f, _ in seen]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    # One report per chunk row of z and channel (4 × 2 here), not one per 32 MiB slab.
    assert sum("reading level 0" in m for _, m in seen) >= 8


def _cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("vtkvol: "), err
    return lines[0]


def test_cli_info_names_the_address_and_shows_progress(server, capsys):
    url = f"{server.url}/cells.ome.zarr"
    code, out, err = _cli(capsys, "info", url, "--gpu-budget", "20000")
    assert code == 0, err
    assert f"source: {url}" in out
    assert "pyramid level 3 of 5" in out
    assert "fetching 127.0.0.1" in err and "100%" in err


def test_cli_convert_copies_the_remote_image(server, tmp_path, capsys):
    out_path = tmp_path / "copy.ome.zarr"
    code, out, err = _cli(capsys, "convert", f"{server.url}/cells.ome.zarr", str(out_path))
    assert code == 0, err
    assert "wrote" in out and "64×64×64" in out
    copy = read_volume(out_path)
    np.testing.assert_array_equal(copy.array, phantom())
    assert copy.channel_names == ["DAPI", "GFP"]


@pytest.mark.gl
def test_cli_render_of_an_address(server, tmp_path, capsys):
    from PIL import Image

    png = tmp_path / "view.png"
    code, _, err = _cli(capsys, "render", f"{server.url}/cells.ome.zarr", "-o", str(png),
                          "--size", "96", "96", "--gpu-budget", "70000")
    assert code == 0, err
    image = np.asarray(Image.open(png).convert("RGB"), dtype=float)
    assert image.shape == (96, 96, 3) and image.std() > 5


# --- every failure class: one line naming the address ---------------------------------------


def test_unreachable_host(capsys):
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    sock.close()  # nothing listens there now
    url = f"http://127.0.0.1:{port}/cells.ome.zarr"
    code, _, err = _cli(capsys, "info", url)
    assert code == 1
    assert _one_line(err) == (f"vtkvol: {url}: cannot reach the host 127.0.0.1:{port} "
                              "(connection refused)")


def test_unknown_host_name(capsys):
    url = "http://no-such-host.invalid/cells.ome.zarr"
    code, _, err = _cli(capsys, "info", url)
    assert code == 1
    assert _one_line(err) == (f"vtkvol: {url}: cannot reach the host no-such-host.invalid "
                              "(the name does not resolve)")


def test_404(server, capsys):
    url = f"{server.url}/missing.ome.zarr"
    code, _, err = _cli(capsys, "info", url)
    assert code == 1
    assert _one_line(err) == (f"vtkvol: {url}: no Zarr store at this address (HTTP 404 Not "
                              "Found for zarr.json, .zgroup, .zattrs)")


def test_403(store, capsys):
    with CountingServer(store, mode="forbidden") as srv:
        url = f"{srv.url}/cells.ome.zarr"
        code, _, err = _cli(capsys, "info", url)
    assert code == 1
    assert _one_line(err) == (f"vtkvol: {url}: the server refuses access (HTTP 403 Forbidden): "
                              "it needs credentials or the store is not public")


def test_timeout(store, capsys, monkeypatch):
    monkeypatch.setattr(remote_module, "TIMEOUT_S", 0.3)
    with CountingServer(store, delay_s=1.5) as srv:
        url = f"{srv.url}/cells.ome.zarr"
        code, _, err = _cli(capsys, "info", url)
    assert code == 1
    assert _one_line(err) == (f"vtkvol: {url}: the server did not answer within 0.3 s "
                              "(timeout)")


def test_store_that_is_not_ome_zarr(server, capsys):
    url = f"{server.url}/plain.zarr"
    code, _, err = _cli(capsys, "info", url)
    assert code == 1
    assert _one_line(err) == (f"vtkvol: {url}: a Zarr group without OME-Zarr 'multiscales' "
                              "metadata (not an OME-Zarr image)")


def test_server_without_range_requests(store, capsys):
    with CountingServer(store, mode="no_range") as srv:
        url = f"{srv.url}/cells.ome.zarr"
        code, _, err = _cli(capsys, "info", url)
    assert code == 1
    assert _one_line(err) == (f"vtkvol: {url}: the server does not support HTTP range requests "
                              "(it sent the whole file for 'Range: bytes=0-0'); vtkvol reads "
                              "chunks as byte ranges and needs them")


def test_library_raises_volume_read_error(server):
    with pytest.raises(VolumeReadError, match=r"^http://127\.0\.0\.1:\d+/missing\.zarr: no Zarr"):
        read_volume(f"{server.url}/missing.zarr")


def test_session_keeps_the_address_and_reopens_it(server, tmp_path):
    from vtkvol.model.defaults import scene_for
    from vtkvol.model.session import load_session_with_data, read_session, save_session

    url = f"{server.url}/cells.ome.zarr"
    data = read_volume(url, memory_budget_bytes=2 * 64 * 16 * 16 * 2)
    model = scene_for(data)
    model.volume.level = 2
    saved = save_session(tmp_path / "remote.vtkvol.json", model, data=data)
    assert read_session(saved).data_path == url
    _, again = load_session_with_data(saved)
    assert again.source == url and again.metadata["level"] == 2
    np.testing.assert_array_equal(again.array, data.array)
