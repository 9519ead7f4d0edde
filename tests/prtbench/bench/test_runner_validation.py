"""Runner, store and cache checks of issue #12: degenerate views, strict JSON, output locations
checked before work, schema migration, unknown profiles, rebuilt artifacts' precompute time."""

from __future__ import annotations

import errno
import json
import math
import os
import sqlite3
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from prtbench.api import strict_json
from prtbench.api.cache import cached_arrays
from prtbench.api.errors import InvalidInputError, PrtbenchError, UnknownNameError
from prtbench.api.method import METHODS, Artifact, load_or_precompute
from prtbench.bench import outputs
from prtbench.bench.job import Job, Outputs
from prtbench.bench.runner import degenerate_reason
from prtbench.bench.runner import prepare as runner_prepare
from prtbench.bench.submit import run
from prtbench.store.results import COLUMNS, SCHEMA_VERSION, ResultRow, ResultsStore, load
from prtbench.transport.raytrace import geometry_mask


def _no_constant(name: str):
    raise ValueError(f"non-strict JSON token {name}")


def patch_render(monkeypatch, method: str, transform) -> None:
    """Make ``method``'s renderer return ``transform(image)`` from ``render``."""
    cls = METHODS.get(method)
    original = cls.renderer

    def renderer(klass, *args, **kwargs):
        made = original(*args, **kwargs)
        real = made.render
        made.render = lambda view, light: transform(real(view, light))
        return made

    monkeypatch.setattr(cls, "renderer", classmethod(renderer))


class Request:
    """A job with where its files and rows go, as ``prtbench run`` builds them."""

    def __init__(self, tmp_path: Path, **overrides):
        fields = dict(method="vertex", scene="sphere-over-plane", light="sky", profile="smoke",
                      out_dir=tmp_path / "out", results_path=tmp_path / "r.sqlite",
                      json_path=tmp_path / "summary.json")
        fields.update(overrides)
        self.out_dir, self.json_path = fields.pop("out_dir"), fields.pop("json_path")
        self.outputs = Outputs(out_dir=self.out_dir, json_path=self.json_path)
        self.results_path = fields.pop("results_path")
        self.job = Job(**fields)


def _request(tmp_path: Path, **overrides) -> Request:
    return Request(tmp_path, **overrides)


def prepare(request: Request):
    return runner_prepare(request.job, outputs=request.outputs, results_path=request.results_path)


def _run(request: Request):
    """Prepare, run and store the rows (the submit path of ``prtbench run``)."""
    return run(request.job, outputs=request.outputs, results_path=request.results_path,
               progress=False, echo=False).summary


# --- degenerate views -------------------------------------------------------------------------

def test_degenerate_reason_names_each_defect():
    rng = np.random.default_rng(0)
    image = rng.uniform(0.2, 0.8, (8, 8, 3)).astype(np.float32)
    mask = np.ones((8, 8), bool)
    good = {"psnr": 30.0, "psnr_masked": 28.0, "flip_masked": 0.1}
    assert degenerate_reason(image, image, image, mask, good) == ""
    black = np.zeros_like(image)
    assert degenerate_reason(black, black, image, mask, good) == "method image is all black"
    nan = np.full_like(image, np.nan)
    assert degenerate_reason(nan, nan, image, mask, good) == "method image has no finite pixel"
    holes = image.copy()
    holes[0, 0, 1] = np.inf
    holes[1, 2, 0] = np.nan
    assert degenerate_reason(holes, image, image, mask, good) == "method image has 2 non-finite values"
    assert degenerate_reason(image, image, black, mask, good) == "reference image is all black"
    assert "geometry mask is empty" in degenerate_reason(image, image, image, ~mask, good)
    reason = degenerate_reason(image, image, image, mask, {**good, "psnr_masked": math.inf,
                                                           "flip_masked": math.nan})
    assert reason == "masked metrics not finite: psnr_masked=inf, flip_masked=nan"
    # A faint but visible image (one 8-bit step) is not black; unmasked inf alone is not degenerate.
    faint = np.full_like(image, 1.0 / 255.0)
    assert degenerate_reason(faint, faint, image, mask, {**good, "psnr": math.inf}) == ""


@pytest.mark.parametrize("transform, fragment", [
    (lambda image: np.zeros_like(image), "method image is all black"),
    (lambda image: np.full_like(image, np.nan), "method image has no finite pixel"),
    (lambda image: np.where(np.arange(image.shape[1])[None, :, None] == 5, np.inf, image),
     "method image has 144 non-finite values"),  # one column of 48 rows × 3 channels
])
def test_degenerate_render_is_stored_flagged_and_strict(tmp_path, monkeypatch, transform, fragment):
    patch_render(monkeypatch, "vertex", transform)
    request = _request(tmp_path)
    summary = _run(request)
    assert summary.status == "degenerate" and fragment in summary.status_reason
    rows = ResultsStore(request.results_path).query()
    assert len(rows) == 1 and rows[0].status == "degenerate" and fragment in rows[0].status_reason
    frame = load(request.results_path)
    assert frame["status"].tolist() == ["degenerate"]
    # Strict JSON in the store (SQLite's own parser) and in summary.json (no NaN/Infinity tokens).
    conn = sqlite3.connect(request.results_path)
    for name in ("metrics", "config", "view_json", "scene_params"):
        assert conn.execute(f"SELECT json_valid({name}) FROM renders").fetchone() == (1,)
    masked = conn.execute("SELECT json_extract(metrics, '$.psnr_masked'), json_type(metrics, "
                          "'$.psnr_masked') FROM renders").fetchone()
    conn.close()
    # A NaN image gives NaN masked metrics, stored as null; a black one finite (bad) scores.
    assert masked[1] == ("null" if "finite" in fragment else "real")
    text = request.json_path.read_text()
    data = json.loads(text, parse_constant=_no_constant)
    assert data["status"] == "degenerate" and fragment in data["status_reason"]
    assert data["views"][0]["status"] == "degenerate"
    # The images are still written, to look at (the summary went to --json instead).
    assert (request.out_dir / "vertex" / "sphere-over-plane-diffuse" / "sky" / "view00.png").is_file()


def test_a_normal_run_is_ok(tmp_path):
    request = _request(tmp_path)
    summary = _run(request)
    assert summary.status == "ok" and summary.status_reason == ""
    row = ResultsStore(request.results_path).query()[0]
    assert row.status == "ok" and row.status_reason == "" and not row.precompute_rebuilt
    assert row.metrics["psnr_masked"] > 20  # vertex PRT on a smooth scene, as in test_cli
    # The cost model's inputs: the geometry mask's pixel count and the scene's vertex count.
    scene = prepare(request).scene
    mask = geometry_mask(scene, scene.trajectory.views[0], row.width, row.height)
    assert row.covered_pixels == int(mask.sum()) > 0 and row.scene_vertices == scene.n_vertices
    # Every submitted job has a key (what it measures), so a rerun of it can resume.
    assert row.workers == 1 and len(row.cell_key) == 64
    # The machine's load when the row was measured (the report flags busy-machine timings).
    assert row.load_average is not None and 0.0 <= row.load_average < 1e3
    assert json.loads(request.json_path.read_text(), parse_constant=_no_constant)["status"] == "ok"


# --- strict JSON ------------------------------------------------------------------------------

def test_strict_json_writes_null_for_every_non_finite_value():
    value = {"a": math.nan, "b": [math.inf, -math.inf, 1.5], "c": np.float32("nan"),
             "d": np.array([1.0, np.inf]), "e": np.int64(3), "f": (np.float64(2.0),), "g": Path("/x")}
    text = strict_json.dumps(value, sort_keys=True)
    assert json.loads(text, parse_constant=_no_constant) == {
        "a": None, "b": [None, None, 1.5], "c": None, "d": [1.0, None], "e": 3, "f": [2.0], "g": "/x"}
    assert strict_json.non_finite_keys({"x": 1.0, "y": math.inf, "z": "text", "w": None}) == ["y=inf"]


# --- schema: migration, foreign databases, auxiliary tables -----------------------------------

_V2_COLUMNS = [c for c in COLUMNS if c not in ("status", "status_reason", "precompute_rebuilt")]


def _schema_2_store(path: Path) -> None:
    """A store as prtbench wrote it before schema 3, NaN/Infinity tokens included."""
    conn = sqlite3.connect(path)
    conn.execute("PRAGMA journal_mode = WAL")
    conn.execute("CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)")
    conn.execute(f"CREATE TABLE renders (id INTEGER PRIMARY KEY AUTOINCREMENT, "
                 f"{', '.join(_V2_COLUMNS)})")
    conn.execute("INSERT INTO meta VALUES ('schema_version', '2')")
    for metrics in ('{"psnr": 30.5, "psnr_masked": 28.0}', '{"psnr": Infinity, "psnr_masked": NaN}'):
        values = {c: None for c in _V2_COLUMNS}
        values.update(method="vertex", scene="plane", profile="smoke", config="{}", view_json="{}",
                      scene_params="{}", reference_kind="path", metrics=metrics)
        conn.execute(f"INSERT INTO renders ({', '.join(values)}) VALUES ({', '.join('?' * len(values))})",
                     list(values.values()))
    conn.commit()
    conn.close()


def test_schema_2_store_is_read_as_is_then_migrated_on_append(tmp_path):
    path = tmp_path / "old.sqlite"
    _schema_2_store(path)
    before = path.read_bytes()
    rows = ResultsStore(path, readonly=True).query()  # `prtbench results`: no migration
    assert [r.status for r in rows] == ["ok", "ok"] and rows[1].metrics["psnr"] == math.inf
    assert path.read_bytes() == before
    ResultsStore(path).append([ResultRow(method="vertex", scene="plane", profile="smoke",
                                         metrics={"psnr": math.inf}, status="degenerate",
                                         status_reason="test")])
    conn = sqlite3.connect(path)
    assert conn.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone() == (str(SCHEMA_VERSION),)
    assert conn.execute("SELECT COUNT(*) FROM renders WHERE json_valid(metrics) = 0").fetchone() == (0,)
    got = conn.execute("SELECT status, status_reason, json_type(metrics, '$.psnr') FROM renders "
                       "ORDER BY id").fetchall()
    conn.close()
    assert got[0] == ("ok", "", "real")
    assert got[1][0] == "degenerate" and "psnr_masked=nan" in got[1][1] and got[1][2] == "null"
    assert got[2] == ("degenerate", "test", "null")


def test_foreign_database_and_extra_tables(tmp_path):
    foreign = tmp_path / "foreign.sqlite"
    conn = sqlite3.connect(foreign)
    conn.execute("CREATE TABLE notes (x)")
    conn.commit()
    conn.close()
    with pytest.raises(PrtbenchError, match=r"foreign.sqlite' is an SQLite file but not a prtbench"):
        ResultsStore(foreign).check()
    with pytest.raises(PrtbenchError, match="not a prtbench"):
        ResultsStore(foreign).append([ResultRow(method="vertex", scene="plane")])
    # Our store with a table another module added (an auxiliary measurement table) is fine.
    ours = tmp_path / "ours.sqlite"
    ResultsStore(ours).append([ResultRow(method="vertex", scene="plane")])
    conn = sqlite3.connect(ours)
    conn.execute("CREATE TABLE aux_measurements (name TEXT, value REAL)")
    conn.commit()
    conn.close()
    ResultsStore(ours).check()
    ResultsStore(ours).append([ResultRow(method="vertex", scene="plane")])
    assert ResultsStore(ours, readonly=True).count() == 2
    # A 'renders' table that lacks our columns is foreign too.
    partial = tmp_path / "partial.sqlite"
    conn = sqlite3.connect(partial)
    conn.execute("CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)")
    conn.execute(f"INSERT INTO meta VALUES ('schema_version', '{SCHEMA_VERSION}')")
    conn.execute("CREATE TABLE renders (id INTEGER PRIMARY KEY, method TEXT)")
    conn.commit()
    conn.close()
    with pytest.raises(PrtbenchError, match="table 'renders' lacks scene"):
        ResultsStore(partial).check()


def test_read_only_store_creates_nothing(tmp_path):
    missing = tmp_path / "no" / "such.sqlite"
    with pytest.raises(PrtbenchError, match="no results store at .*such.sqlite'; `prtbench run` fills it"):
        ResultsStore(missing, readonly=True).query()
    assert not (tmp_path / "no").exists()
    with pytest.raises(InvalidInputError, match="is a folder"):
        ResultsStore(tmp_path, readonly=True).query()
    with pytest.raises(UnknownNameError, match="result status"):
        ResultRow(method="vertex", scene="plane", status="fine")
    # Reading a WAL store leaves no -wal/-shm files behind (a plain read-only connection would).
    store = tmp_path / "r.sqlite"
    ResultsStore(store).append([ResultRow(method="vertex", scene="plane")])
    before = sorted(p.name for p in tmp_path.iterdir())
    assert len(ResultsStore(store, readonly=True).query()) == 1
    ResultsStore(store).check()
    assert sorted(p.name for p in tmp_path.iterdir()) == before == ["r.sqlite"]
    # While a writer holds the WAL open, a reader sees its committed rows.
    writer = sqlite3.connect(store)
    writer.execute("SELECT COUNT(*) FROM renders").fetchall()  # holds the WAL open
    ResultsStore(store).append([ResultRow(method="texture", scene="plane")])
    assert (tmp_path / "r.sqlite-wal").exists()
    assert [r.method for r in ResultsStore(store, readonly=True).query()] == ["vertex", "texture"]
    writer.close()


# --- output locations -------------------------------------------------------------------------

def test_output_checks(tmp_path):
    a_file = tmp_path / "file"
    a_file.write_text("x")
    with pytest.raises(InvalidInputError, match=r"^--out '.*file' is a file; accepted: a folder"):
        outputs.check_folder("--out", a_file)
    with pytest.raises(InvalidInputError, match=r"^--out '.*file/sub' is under the file"):
        outputs.check_folder("--out", a_file / "sub")
    with pytest.raises(InvalidInputError, match=r"^--json '.*' is a folder"):
        outputs.check_file("--json", tmp_path)
    outputs.check_folder("--out", tmp_path / "new" / "deeper")  # creatable: fine, not created
    outputs.check_file("--json", tmp_path / "new" / "s.json")
    assert not (tmp_path / "new").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]  # the probe left nothing


def test_full_file_system_is_caught_by_the_write_probe(tmp_path, monkeypatch):
    real_write = os.write

    def full(fd, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "write", full)
    with pytest.raises(InvalidInputError, match=r"cannot write in .*\(No space left on device\)"):
        outputs.check_folder("$PRTBENCH_CACHE", tmp_path / "cache")
    monkeypatch.setattr(os, "write", real_write)
    assert list(tmp_path.iterdir()) == []


@pytest.fixture
def read_only_mount(tmp_path):
    where = tmp_path / "ro"
    where.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(where)],
                          capture_output=True)
    if done.returncode != 0:
        pytest.skip("cannot mount a read-only tmpfs here (needs root)")
    yield where
    subprocess.run(["umount", str(where)], check=True)


def test_read_only_file_system(read_only_mount, tmp_path):
    # Root ignores permission bits, so only a read-only mount shows that the probe really writes.
    with pytest.raises(InvalidInputError, match=r"--out '.*ro/out': cannot create files .*Read-only"):
        outputs.check_folder("--out", read_only_mount / "out")
    with pytest.raises(InvalidInputError, match=r"--results '.*ro/r.sqlite': cannot create files"):
        outputs.check_results_store("--results", read_only_mount / "r.sqlite")


def test_prepare_checks_every_output_before_work(tmp_path, monkeypatch):
    a_file = tmp_path / "file"
    a_file.write_text("x")
    cache = tmp_path / "cache"
    monkeypatch.setenv("PRTBENCH_CACHE", str(cache))
    for request, fragment in [
        (_request(tmp_path, out_dir=a_file), "--out"),
        (_request(tmp_path, json_path=tmp_path), "--json"),
        (_request(tmp_path, results_path=tmp_path), "--results"),
        (_request(tmp_path, results_path=a_file), "--results"),  # not SQLite
    ]:
        with pytest.raises(PrtbenchError, match=fragment):
            prepare(request)
    monkeypatch.setenv("PRTBENCH_CACHE", str(a_file / "c"))
    with pytest.raises(InvalidInputError, match=r"\$PRTBENCH_CACHE '.*file/c' is under the file"):
        prepare(_request(tmp_path))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


# --- profiles and rebuilt artifacts -----------------------------------------------------------

def test_make_config_rejects_an_unknown_profile():
    cls = METHODS.get("vertex")
    with pytest.raises(UnknownNameError, match="unknown profile 'fast'"):
        cls.make_config(profile="fast")
    assert cls.make_config(profile="smoke") is not None


@dataclass
class _Config:
    size: int = 4


class _StubScene:
    def content_hash(self) -> str:
        return "stub-scene"


class _SlowTransferMethod:
    """A precompute whose slow sub-step (like transfer) is cached on its own."""

    name = "stub-slow-transfer"
    precompute_version = "1"
    sleep_s = 0.3

    @classmethod
    def precompute(cls, scene, config, *, progress=True):
        def slow():
            time.sleep(cls.sleep_s)
            return {"transfer": np.arange(config.size, dtype=np.float32)}

        arrays = cached_arrays("stub-transfer", "k", slow)
        return Artifact(cls.name, {"coefficients": arrays["transfer"] * 2})


def test_rebuilt_artifact_keeps_its_original_precompute_time(tmp_path, monkeypatch):
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path))
    first = load_or_precompute(_SlowTransferMethod, _StubScene(), _Config(), progress=False)
    assert first.precompute_s >= _SlowTransferMethod.sleep_s and not first.rebuilt
    (artifact,) = (tmp_path / "artifacts" / _SlowTransferMethod.name).glob("*.npz")
    artifact.write_bytes(artifact.read_bytes()[:200])  # a corrupt (truncated) cache file
    rebuilt = load_or_precompute(_SlowTransferMethod, _StubScene(), _Config(), progress=False)
    assert rebuilt.rebuilt and not rebuilt.cache_hit
    assert rebuilt.rebuild_s < _SlowTransferMethod.sleep_s  # the transfer came from the cache
    assert rebuilt.precompute_s == pytest.approx(first.precompute_s)  # the original time
    hit = load_or_precompute(_SlowTransferMethod, _StubScene(), _Config(), progress=False)
    assert hit.cache_hit and hit.precompute_s == pytest.approx(first.precompute_s)
    np.testing.assert_array_equal(hit.arrays["coefficients"], first.arrays["coefficients"])


def test_rebuild_without_a_record_counts_its_cached_parts(tmp_path, monkeypatch):
    """No build record (a cache from before records existed): the rebuild's own wall time is
    short, but its cached sub-step credits its recorded compute time, so precompute_s is still
    the cost from scratch. Without that sub-step's record too, the time is flagged unknown."""
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path))
    load_or_precompute(_SlowTransferMethod, _StubScene(), _Config(), progress=False)
    folder = tmp_path / "artifacts" / _SlowTransferMethod.name
    (record,) = folder.glob("*.json")
    record.unlink()  # a cache written before build records existed
    (artifact,) = folder.glob("*.npz")
    artifact.write_bytes(b"corrupt")
    rebuilt = load_or_precompute(_SlowTransferMethod, _StubScene(), _Config(), progress=False)
    assert rebuilt.rebuilt and rebuilt.original_time_known
    assert rebuilt.rebuild_s < _SlowTransferMethod.sleep_s <= rebuilt.precompute_s
    assert not list(folder.glob("*.json"))  # a rebuild's time is never recorded as the build's
    for time_record in tmp_path.rglob("*.time.json"):
        time_record.unlink()  # the sub-step's compute time unrecorded too (an older cache)
    (artifact,) = folder.glob("*.npz")
    artifact.write_bytes(b"corrupt")
    again = load_or_precompute(_SlowTransferMethod, _StubScene(), _Config(), progress=False)
    assert again.rebuilt and not again.original_time_known
    assert again.precompute_s == again.rebuild_s < _SlowTransferMethod.sleep_s


def test_run_row_records_the_rebuild(tmp_path, monkeypatch):
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "cache"))
    request = _request(tmp_path, out_dir=None, json_path=None)
    first = _run(request)
    (artifact,) = (tmp_path / "cache" / "artifacts" / "vertex").glob("*.npz")
    artifact.write_bytes(artifact.read_bytes()[:100])
    second = _run(request)
    assert second.precompute_rebuilt and second.precompute_s == pytest.approx(first.precompute_s)
    rows = ResultsStore(request.results_path).query()
    assert [r.precompute_rebuilt for r in rows] == [False, True]
    assert rows[1].precompute_s == pytest.approx(rows[0].precompute_s)


def test_schema_3_store_gains_the_trade_off_columns_on_append(tmp_path):
    """Schema 3 → 4: covered pixels, vertex count, workers and cell key are added; old rows
    keep their values and read back as one worker, no cell key, unknown coverage."""
    path = tmp_path / "v3.sqlite"
    ResultsStore(path).append([ResultRow(method="vertex", scene="plane", profile="smoke",
                                         metrics={"psnr": 20.0})])
    conn = sqlite3.connect(path)
    for column in ("covered_pixels", "scene_vertices", "workers", "cell_key"):
        conn.execute(f"ALTER TABLE renders DROP COLUMN {column}")
    conn.execute("UPDATE meta SET value = '3' WHERE key = 'schema_version'")
    conn.commit()
    conn.close()
    old = ResultsStore(path, readonly=True).query()
    assert old[0].workers == 1 and old[0].cell_key == "" and old[0].covered_pixels is None
    ResultsStore(path).append([ResultRow(method="vertex", scene="plane", profile="smoke",
                                         covered_pixels=1234, scene_vertices=4, workers=2,
                                         cell_key="abc")])
    rows = ResultsStore(path, readonly=True).query()
    assert [(r.covered_pixels, r.scene_vertices, r.workers, r.cell_key) for r in rows] == [
        (None, None, 1, ""), (1234, 4, 2, "abc")]
    assert rows[0].metrics["psnr"] == 20.0
    conn = sqlite3.connect(path)
    assert conn.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone() == (str(SCHEMA_VERSION),)
    conn.close()


def test_schema_4_store_gains_the_load_average_on_append(tmp_path):
    """Schema 4 → 5: the machine's load while timing is added; old rows read it as unknown."""
    path = tmp_path / "v4.sqlite"
    ResultsStore(path).append([ResultRow(method="vertex", scene="plane", profile="smoke")])
    conn = sqlite3.connect(path)
    conn.execute("ALTER TABLE renders DROP COLUMN load_average")
    conn.execute("UPDATE meta SET value = '4' WHERE key = 'schema_version'")
    conn.commit()
    conn.close()
    assert ResultsStore(path, readonly=True).query()[0].load_average is None
    ResultsStore(path).append([ResultRow(method="vertex", scene="plane", profile="smoke",
                                         load_average=0.75)])
    assert [r.load_average for r in ResultsStore(path, readonly=True).query()] == [None, 0.75]
    conn = sqlite3.connect(path)
    assert conn.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone() == (
        str(SCHEMA_VERSION),)
    conn.close()


def test_load_average_is_the_os_one_minute_figure_or_unknown(monkeypatch):
    from prtbench.bench.runner import load_average

    monkeypatch.setattr(os, "getloadavg", lambda: (3.5, 2.0, 1.0))
    assert load_average() == 3.5

    def unavailable():
        raise OSError("no load average here")

    monkeypatch.setattr(os, "getloadavg", unavailable)
    assert load_average() is None
