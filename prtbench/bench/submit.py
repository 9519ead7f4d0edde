"""The one submit path: validate every job, skip what is stored, run the rest, store the rows.

:func:`submit` is what every driver calls (``prtbench run``, the paper tables and figures,
``sweep``, ``advise``, ``regress``, the stability matrix):

1. every job is prepared (:func:`prtbench.bench.runner.prepare`) before any work, so one bad
   job is a one-line error and nothing is written; its key (:func:`job_key`) names what it
   measures (method, full config, scene, parameters, light, views, resolution, profile,
   reference, code version) and duplicate jobs run once;
2. with ``resume``, jobs whose key already has measured rows in the store are skipped;
3. the rest run on an executor (:mod:`prtbench.bench.executors`), each through
   :func:`measure` (the ordinary runner; it never raises: a failing job is reported with its
   one-line error and never aborts the others);
4. only this process (the client) writes the store, each finished job's rows in one
   transaction, so a killed client or worker loses only the jobs in flight and a rerun with
   ``resume`` completes the set.

A progress bar counts done / running / failed / skipped jobs.
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from prtbench.api import config as config_mod
from prtbench.api.cache_size import enforce_cap
from prtbench.api.errors import PrtbenchError
from prtbench.bench.cluster import one_line
from prtbench.bench.executors import Executor, Lost, SerialExecutor, bind
from prtbench.bench.job import NO_OUTPUTS, Job, Outputs
from prtbench.bench.outputs import check_results_store
from prtbench.bench.runner import PreparedRun, execute, prepare, summary_rows
from prtbench.store.results import ResultsStore, default_path, git_sha

#: Statuses of stored rows that count as measured (failed jobs store nothing).
MEASURED = ("ok", "degenerate")


@dataclass
class JobResult:
    """What became of one job.

    Attributes
    ----------
    job : Job
    key : str
        :func:`job_key`.
    status : str
        ``done`` (measured now), ``skipped`` (already in the store) or ``failed``.
    error : str
        The one-line error of a failed job.
    rows : list
        Its result rows (:func:`prtbench.bench.runner.summary_rows`), stored unless the submit
        said otherwise.
    summary : RunSummary, optional
        The run's summary (per-view metrics, frame times, files written).
    seconds : float
        Wall time of the job on its worker (0 when skipped).
    exception : BaseException, optional
        The original exception of a job that failed in this process (re-raised for the CLI).
    scene : Scene, optional
        The prepared scene (views selected) of a job run in this process (figures draw on it).
    """

    job: Job
    key: str
    status: str
    error: str = ""
    rows: list = field(default_factory=list)
    summary: Any = None
    seconds: float = 0.0
    exception: BaseException | None = None
    scene: Any = None


@dataclass
class Submission:
    """The results of one :func:`submit`.

    ``results`` holds one per distinct job (duplicates, same :func:`job_key`, run once), in the
    order given; ``per_job`` one per job given (a duplicate shares its first's result).
    """

    results: list[JobResult]
    #: Workers that ran concurrently (1: serial; 0: nothing ran).
    workers: int
    wall_s: float
    executor: str = ""
    per_job: list[JobResult] = field(default_factory=list)

    def count(self, status: str) -> int:
        return sum(1 for r in self.results if r.status == status)

    @property
    def failed(self) -> list[JobResult]:
        return [r for r in self.results if r.status == "failed"]


def code_version() -> str:
    """The code version in job keys: the full :func:`prtbench.store.results.git_sha`,
    ``+dirty`` included, so results of a modified tree never pass for a clean commit's."""
    return git_sha()


def job_key(prepared: PreparedRun, *, code: str) -> str:
    """SHA-256 of everything a job's measurement depends on (its label excluded)."""
    identity = {
        "method": prepared.method_cls.name, "config": config_mod.to_dict(prepared.config),
        "scene": prepared.scene.name, "variant": prepared.scene.variant,
        "scene_params": dict(prepared.scene.params), "light": prepared.light.name,
        "views": len(prepared.scene.trajectory), "resolution": [prepared.width, prepared.height],
        "profile": prepared.profile.name, "reference": prepared.job.reference, "code": code}
    if prepared.job.reference_bounces is not None:  # absent: the keys of older stores hold
        identity["reference_bounces"] = int(prepared.job.reference_bounces)
    text = json.dumps(identity, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def measure(task: tuple[Job, str, Outputs], *, workers: int = 1, progress: bool = False,
            echo: bool = False, local: bool = False) -> JobResult:
    """Run one job through the ordinary runner; never raises.

    ``task`` is ``(job, key, outputs)``; the job is prepared again here, where it runs (a Dask
    worker or a spawned process builds its own scene, GL context and Mitsuba variant).
    ``local``: it runs in the submitting process, so the result keeps the exception of a
    failure and the prepared scene (neither travels between processes).
    """
    job, key, outputs = task
    start = time.perf_counter()
    try:
        prepared = prepare(job, outputs=outputs, store=False)
        summary = execute(prepared, progress=progress, echo=echo)
        rows = summary_rows(summary, prepared.scene, workers=workers, cell_key=key)
    except Exception as exc:  # noqa: BLE001 - a failing job is reported, never fatal
        return JobResult(job, key, "failed", one_line(exc), seconds=time.perf_counter() - start,
                         exception=exc if local else None)
    return JobResult(job, key, "done", rows=rows, summary=summary,
                     seconds=time.perf_counter() - start, scene=prepared.scene if local else None)


def stored_keys(results_path: Path | None, profile: str | None = None) -> dict[str, set[int]]:
    """Job key → the ``workers`` values of its measured rows in the store."""
    path = Path(results_path) if results_path is not None else default_path()
    if not path.exists():
        return {}
    out: dict[str, set[int]] = {}
    for row in ResultsStore(path, readonly=True).query(profile=profile):
        if row.cell_key and row.status in MEASURED:
            out.setdefault(row.cell_key, set()).add(int(row.workers or 1))
    return out


class _Progress:
    """tqdm over jobs with done / running / failed / skipped counts."""

    def __init__(self, total: int, skipped: int, *, enabled: bool, desc: str):
        self.bar = tqdm(total=total, initial=skipped, unit="job", desc=desc,
                        disable=not enabled, file=sys.stderr, dynamic_ncols=True)
        self.done = self.failed = 0
        self.skipped, self.running = skipped, 0

    def update(self, *, running: int, finished: str | None = None) -> None:
        if finished == "done":
            self.done += 1
        elif finished == "failed":
            self.failed += 1
        self.running = running
        self.bar.set_postfix(done=self.done, running=self.running, failed=self.failed,
                             skipped=self.skipped, refresh=False)
        self.bar.update(1 if finished else 0)

    def close(self) -> None:
        self.bar.close()


def validate(jobs: Sequence[Job], *, profile: str, outputs: Sequence[Outputs] | None = None,
             results_path: Path | None = None, store: bool = True
             ) -> tuple[list[tuple[Job, str, Outputs]], list[int]]:
    """The distinct tasks ``(job, key, outputs)`` and, per job given, its task's index; every
    job is prepared first, and nothing is written.

    Raises
    ------
    PrtbenchError
        The first invalid job (its one-line error), or an unusable output location.
    """
    if store:
        check_results_store("--results", Path(results_path) if results_path else default_path())
    code = code_version()
    outs = list(outputs) if outputs is not None else [NO_OUTPUTS] * len(jobs)
    if len(outs) != len(jobs):
        raise ValueError(f"{len(outs)} outputs for {len(jobs)} jobs")
    index_of: dict[str, int] = {}
    tasks, owners = [], []
    for job, out in zip(jobs, outs):
        job = job.in_profile(profile)
        prepared = prepare(job, outputs=out, results_path=results_path, store=store)
        key = job_key(prepared, code=code)
        if key not in index_of or out.writes_files:  # a job that writes files runs itself
            index_of[key] = len(tasks)
            tasks.append((job, key, out))
        owners.append(index_of[key])
    return tasks, owners


def submit(jobs: Sequence[Job], *, profile: str = "quick", executor: Executor | None = None,
           outputs: Sequence[Outputs] | None = None, results_path: Path | None = None,
           store: bool = True, resume: bool = False, progress: bool = True, echo: bool = False,
           run_progress: bool = False, desc: str = "jobs", raise_errors: bool = False,
           on_result: Callable[[JobResult], None] | None = None) -> Submission:
    """Run ``jobs`` (see the module docstring) and return what became of each.

    Parameters
    ----------
    jobs : sequence of Job
        A job without a profile runs in ``profile``.
    executor : Executor, optional
        Where they run (default: a :class:`SerialExecutor`). The caller closes an executor
        it passes (one Dask cluster can serve many submits).
    outputs : sequence of Outputs, optional
        Per job: where its images and JSON summary go (default: nowhere).
    results_path : Path, optional
        The results store (default :func:`prtbench.store.results.default_path`).
    store : bool
        Append the rows to the store (screening runs of ``advise`` do not).
    resume : bool
        Skip jobs whose key has measured rows in the store.
    progress : bool
        A progress bar over jobs.
    echo, run_progress : bool
        The runner's per-view lines and its precompute / reference progress bars (jobs run
        in this process only).
    raise_errors : bool
        Re-raise the error of a failed job run in this process (``prtbench run``: a refusal
        found while running is still a one-line error, exit 2).
    on_result : callable, optional
        Called with each finished :class:`JobResult` (after its rows are stored).
    """
    owned = executor is None
    executor = executor or SerialExecutor()
    start = time.perf_counter()
    try:
        tasks, owners = validate(jobs, profile=profile, outputs=outputs,
                                 results_path=results_path, store=store)
        stored = stored_keys(results_path) if resume else {}
        results: dict[int, JobResult] = {
            i: JobResult(job, key, "skipped") for i, (job, key, _) in enumerate(tasks)
            if key in stored}
        todo = [i for i in range(len(tasks)) if i not in results]
        if todo:  # the jobs are valid: bring the cache under $PRTBENCH_CACHE_MAX (LRU) first
            enforce_cap()
        writer = ResultsStore(results_path) if store and todo else None
        bar = _Progress(len(tasks), len(results), enabled=progress, desc=desc)
        ran = 0
        try:
            if todo:
                in_process = isinstance(executor, SerialExecutor)
                workers = executor.start()
                task = bind(measure, workers=max(1, workers),
                            progress=run_progress and in_process, echo=echo and in_process,
                            local=in_process)
                bar.update(running=min(max(1, workers), len(todo)))
                pending = len(todo)
                for position, result in executor.map(task, [tasks[i] for i in todo]):
                    index = todo[position]
                    job, key, _ = tasks[index]
                    if isinstance(result, Lost):
                        result = JobResult(job, key, "failed", result.error, seconds=result.seconds)
                    if result.status == "done" and writer is not None:
                        writer.append(result.rows)  # one transaction: all its views or none
                    results[index] = result
                    pending -= 1
                    ran = max(1, workers)
                    bar.update(running=min(ran, pending), finished=result.status)
                    if on_result is not None:
                        on_result(result)
                    if raise_errors and result.exception is not None:
                        raise result.exception
        finally:
            bar.close()
    finally:
        if owned:
            executor.close()
    return Submission([results[i] for i in range(len(tasks))], ran if todo else 0,
                      time.perf_counter() - start, executor.kind,
                      per_job=[results[i] for i in owners])


class JobPool:
    """Jobs submitted one at a time and collected as they finish, on one executor.

    The incremental form of :func:`submit` for drivers that decide what to run next from what
    came back (the advisor's search keeps every worker busy with it): each job is prepared
    here first (a refusal comes back at once as a failed result), then measured on the
    executor; with ``store`` its rows are appended here, by the client.

    Parameters
    ----------
    executor : Executor
        Where the jobs run (the caller closes it).
    results_path : Path, optional
    store : bool
    """

    def __init__(self, executor: Executor, *, results_path: Path | None = None,
                 store: bool = False):
        self.executor, self.results_path, self.store = executor, results_path, store
        self._code = code_version()
        self._ready: list[tuple[Any, JobResult]] = []
        self._tokens: dict[int, tuple[Any, Job, str]] = {}
        self._writer = ResultsStore(results_path) if store else None
        self._task = None

    def submit(self, job: Job, *, profile: str, token: Any) -> None:
        """Start ``job`` in ``profile``; :meth:`next_finished` gives back ``token`` with it."""
        job = job.in_profile(profile)
        try:
            prepared = prepare(job, results_path=self.results_path, store=self.store)
        except PrtbenchError as exc:
            self._ready.append((token, JobResult(job, "", "failed", one_line(exc))))
            return
        key = job_key(prepared, code=self._code)
        if self._task is None:  # the first job: bring the cache under its cap first
            enforce_cap()
            in_process = isinstance(self.executor, SerialExecutor)
            self._task = bind(measure, workers=max(1, self.executor.start()), local=in_process)
        handle = self.executor.submit(self._task, (job, key, NO_OUTPUTS))
        self._tokens[id(handle)] = (token, job, key)

    @property
    def pending(self) -> int:
        return len(self._ready) + len(self._tokens)

    def next_finished(self) -> tuple[Any, JobResult]:
        """``(token, JobResult)`` of the next job to finish."""
        if self._ready:
            return self._ready.pop(0)
        handle, result = self.executor.next_finished()
        token, job, key = self._tokens.pop(id(handle))
        if isinstance(result, Lost):
            result = JobResult(job, key, "failed", result.error, seconds=result.seconds)
        if result.status == "done" and self._writer is not None:
            self._writer.append(result.rows)
        return token, result


def run(job: Job, *, profile: str = "quick", outputs: Outputs = NO_OUTPUTS,
        results_path: Path | None = None, store: bool = True, progress: bool = True,
        echo: bool = True) -> JobResult:
    """One job in this process (``prtbench run``): its errors raise, as one-line errors."""
    submission = submit([job], profile=profile, outputs=[outputs], results_path=results_path,
                        store=store, progress=False, run_progress=progress, echo=echo,
                        raise_errors=True, desc="run")
    return submission.results[0]


def rows_as_dicts(rows: Sequence[Any]) -> list[Mapping[str, Any]]:
    """Result rows as plain dicts (the advisor's view of them)."""
    return [asdict(r) if hasattr(r, "__dataclass_fields__") else dict(r) for r in rows]
