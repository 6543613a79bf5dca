"""A campaign of seeded picks: run in local worker processes or as Ray tasks.

Every finished pick's record is appended at once to a JSON-lines file (one record per line, flushed), so a
campaign that is stopped keeps what it finished: `resume` skips the trials whose records are there (a last
line cut off mid-write is ignored and that trial runs again). A progress bar (tqdm) shows picks per minute
and the running success rate with its 95 % Wilson interval.

The trials are the same whichever runs them: each builds its own diagram from its scenario and seed
(diagrams/evaluation.py) in a worker process set up alike (SINGLE_THREADED), so the same seeds give the same
records (wall-clock times aside) with one worker, N, or Ray.
"""

import contextlib
import importlib.util
import json
import logging
import os
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import get_context
from pathlib import Path

from tqdm import tqdm

from diagrams.evaluation import Trial, crashed_record, record_key, run_trial_in_worker, trial_key, wilson_interval

# Every pick runs in a worker process with single-threaded numerics (torch, BLAS, OpenMP), one pick per CPU:
# threaded reductions round differently, and a pick in a multi-threaded process lifted its can 12 um higher
# than the same seed on Ray.
SINGLE_THREADED = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
RAY_MISSING = "--ray needs Ray, an optional dependency: pip install -e '.[cluster]'"


def read_records(path: Path) -> list[dict]:
    """The records of a JSON-lines file; a line that does not parse (a campaign killed mid-write) is left out."""
    records = []
    if not path.exists():
        return records
    for number, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip():
            continue
        try:
            records.append(json.loads(line))
        except json.JSONDecodeError:
            logging.warning("%s:%d: an unfinished record, left out (its trial runs again)", path, number)
    return records


def _cut_unfinished_line(path: Path):
    """A campaign killed mid-write leaves a last line without its newline: cut it off before appending."""
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        with path.open("r+b") as file:
            file.truncate(data.rfind(b"\n") + 1)


def _append(path: Path, record: dict):
    with path.open("a") as file:
        file.write(json.dumps(record) + "\n")
        file.flush()
        os.fsync(file.fileno())


@contextlib.contextmanager
def _single_threaded_children() -> Iterator[None]:
    """SINGLE_THREADED in this process's environment while processes spawned in it inherit it; the environment as it
    was afterwards (a process the caller starts later, e.g. scripts/pick.py from a test, keeps the caller's threads)."""
    saved = {name: os.environ.get(name) for name in SINGLE_THREADED}
    os.environ.update(SINGLE_THREADED)
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _in_pool(function, items: list, jobs: int, on_crash) -> Iterator[tuple[int, object]]:
    """(n, function(items[n])) as each finishes in `jobs` workers. A worker that dies (the simulator's C++ aborts
    its process: a simulation blown up to NaN) breaks the whole pool: the items it left unfinished run again one at
    a time, each in a pool of its own, and one that dies alone too gives on_crash(item, why)."""
    left = dict(enumerate(items))
    try:
        for n, result in _pooled(function, left, jobs):
            del left[n]
            yield n, result
    except BrokenProcessPool as error:
        logging.warning("a worker process died (%s): its %d unfinished items run again one by one", error, len(left))
    for n, item in list(left.items()):
        try:
            ((_, result),) = _pooled(function, {n: item}, 1)
        except BrokenProcessPool as error:
            result = on_crash(item, str(error) or type(error).__name__)
        yield n, result


def _pooled(function, items: dict, jobs: int) -> Iterator[tuple[int, object]]:
    """(n, function(item)) for each of items {n: item}, as each finishes in `jobs` spawned worker processes."""
    with _single_threaded_children(), ProcessPoolExecutor(jobs, mp_context=get_context("spawn")) as pool:
        futures = {pool.submit(function, item): n for n, item in items.items()}
        for future in as_completed(futures):
            yield futures[future], future.result()


def _reraise(item, why: str):
    raise RuntimeError(f"a worker process died on {item!r}: {why}")


def _on_ray(function, items: list, address: str, jobs: int) -> Iterator[tuple[int, object]]:
    import ray

    started_here = not ray.is_initialized()
    if started_here:
        options = {"address": address} if address else {"num_cpus": jobs}
        ray.init(**options, include_dashboard=False, log_to_driver=False, runtime_env={"env_vars": SINGLE_THREADED})
    try:
        task = ray.remote(num_cpus=1)(function)
        pending = {task.remote(item): n for n, item in enumerate(items)}
        while pending:
            (ready,), _ = ray.wait(list(pending), num_returns=1)
            yield pending.pop(ready), ray.get(ready)
    finally:
        if started_here:
            ray.shutdown()


def fan_out(
    function, items: list, jobs: int = 1, ray_address: str | None = None, on_crash=_reraise
) -> Iterator[tuple[int, object]]:
    """(item number, function(item)) as each finishes, computed in `jobs` single-threaded worker processes, or as
    Ray tasks of one CPU when ray_address is not None ("" starts a local Ray with `jobs` CPUs).

    `function` must be importable by the workers (a module-level function of the installed packages). An item
    whose worker process dies gives on_crash(item, why) (local workers; default: a RuntimeError).
    """
    if ray_address is not None and importlib.util.find_spec("ray") is None:
        raise RuntimeError(RAY_MISSING)
    if ray_address is not None:
        return _on_ray(function, items, ray_address, jobs)
    return _in_pool(function, items, jobs, on_crash)


def run_campaign(
    trials: list[Trial],
    jobs: int = 1,
    ray_address: str | None = None,
    records_path: Path | None = None,
    resume: bool = False,
    describe=lambda record: "",
) -> list[dict]:
    """Runs the trials in `jobs` worker processes, or as Ray tasks when ray_address is not None ("" for a local
    Ray with `jobs` CPUs); returns their records in the trials' order.

    Args:
        records_path: a JSON-lines file each finished record is appended to.
        resume: keep the records already in records_path and run only the trials they lack.
        describe: a record -> a line printed above the bar.
    """
    done = {}
    if resume:
        if records_path is None:
            raise ValueError("resuming needs a records file")
        wanted = {trial_key(trial) for trial in trials}
        done = {key: r for r in read_records(records_path) if (key := record_key(r)) in wanted}
        if records_path.exists():
            _cut_unfinished_line(records_path)
    elif records_path is not None and records_path.exists() and records_path.stat().st_size:
        raise FileExistsError(f"{records_path} holds records already: resume it (--resume) or name another file")
    todo = [trial for trial in trials if trial_key(trial) not in done]
    if done:
        print(f"resuming: {len(done)} of {len(trials)} picks already in {records_path}, {len(todo)} to run")
    finished = fan_out(run_trial_in_worker, todo, jobs, ray_address, on_crash=crashed_record)
    successes = sum(r["success"] for r in done.values())
    bar = tqdm(total=len(trials), initial=len(done), unit="pick", dynamic_ncols=True)
    start = time.perf_counter()
    for count, (n, record) in enumerate(finished, 1):
        done[trial_key(todo[n])] = record
        if records_path is not None:
            _append(records_path, record)
        successes += record["success"]
        low, high = wilson_interval(successes, len(done))
        per_minute = count / (time.perf_counter() - start) * 60
        bar.set_postfix_str(
            f"{per_minute:.1f} picks/min, success {successes}/{len(done)} (95 % CI {100 * low:.0f}-{100 * high:.0f} %)"
        )
        bar.write(describe(record))
        bar.update()
    bar.close()
    return [done[trial_key(trial)] for trial in trials]
