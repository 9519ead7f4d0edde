"""The contract every method's bad-request test checks: ``prtbench run`` with bad ``--set``
values exits 2 with one ``prtbench: error:`` line (no traceback) matching the expected text,
and leaves no results store, no output folder and (where given) no cached file behind."""

from __future__ import annotations

import re
from pathlib import Path

from prtbench.cli import main


def assert_run_refused(argv: list[str], sets: list[str], *, match: str, tmp_path: Path,
                       capsys, cache: Path | None = None) -> str:
    """Run ``prtbench run <argv> --set …`` into ``tmp_path``; assert the refusal; its line."""
    args = ["run", *argv, "--out", str(tmp_path / "out"),
            "--results", str(tmp_path / "r.sqlite")]
    for item in sets:
        args += ["--set", item]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("prtbench: error: ") and "\n" not in err and "Traceback" not in err
    assert re.search(match, err), err
    assert not (tmp_path / "r.sqlite").exists() and not (tmp_path / "out").exists()
    if cache is not None:
        assert not cache.exists() or not any(p.is_file() for p in cache.rglob("*"))
    return err
