"""The engine of ``fliss sweep`` and ``fliss reproduce``: independent points on Dask.

:func:`cluster` gives a ``dask.distributed`` client, on a ``LocalCluster`` started for the run
or on an existing scheduler; :func:`compute` runs a set of keyed tasks on it and hands each
result over as it finishes; :func:`run_sweep` runs a :class:`~fliss.host.sweep.spec.Spec`: it
stores every point as it finishes (:class:`Store`, one JSON file per point, keyed by
:func:`~fliss.host.sweep.spec.point_key`), computes only the points not stored yet, and writes the
table (:func:`write_table`, Parquet). Nothing here prints: progress goes to a callback, failures
are exceptions, and an interruption (Ctrl-C) is part of the :class:`Outcome`.
"""

import contextlib
import json
import logging
import math
import os
import signal
import time
import uuid
from dataclasses import dataclass

from .. import interrupts
from .spec import canonical, load_model, point_key, point_seed


__all__ = ["SweepError", "Outcome", "Store", "cluster", "compute", "run_sweep", "table_rows",
           "write_table", "TABLE_NAME", "STORE_NAME"]


#: The table of a sweep, in its output directory.
TABLE_NAME = "results.parquet"
#: The folder of finished points, in a sweep's output directory.
STORE_NAME = "points"


class SweepError(Exception):
    """A sweep that cannot go on: a scheduler out of reach, a point the model refuses, a result
    that is not a flat table row, an unreadable stored point."""


@dataclass
class Outcome:
    """What :func:`run_sweep` did.

    Attributes
    ----------
    total : int
        Points of the spec.
    reused : int
        Points found finished in the output directory.
    computed : int
        Points computed by this run.
    interrupted : bool
        The run was stopped (Ctrl-C, SIGTERM) before every point finished.
    elapsed_s : float
        Time spent computing.
    table : str or None
        Path of the Parquet table, or ``None`` when no point has finished.
    """
    total: int
    reused: int
    computed: int
    interrupted: bool
    elapsed_s: float
    table: str = None

    @property
    def missing(self):
        return self.total - self.reused - self.computed


@contextlib.contextmanager
def cluster(workers=2, *, processes=True, scheduler=None, timeout_s=10.0):
    """A ``dask.distributed.Client``: on ``scheduler`` (``"tcp://HOST:PORT"``) if given, else on
    a ``LocalCluster`` of ``workers`` single-threaded workers (processes, or threads of this
    process), closed on exit, also after Ctrl-C; ``timeout_s`` bounds the wait for the
    scheduler. Dask's own log lines below errors are held back meanwhile: the scheduler's
    chatter is not this program's output. :exc:`SweepError` if the scheduler is out of reach."""
    import distributed                      # noqa: F401  (sets up its loggers when imported)

    logger = logging.getLogger("distributed")
    level = logger.level
    logger.setLevel(max(level, logging.ERROR))
    try:
        with _client(workers, processes, scheduler, timeout_s) as client:
            yield client
    finally:
        logger.setLevel(level)


@contextlib.contextmanager
def _client(workers, processes, scheduler, timeout_s):
    import dask
    from dask.distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=f"{timeout_s}s")
        except (OSError, TimeoutError, ValueError) as error:
            raise SweepError(f"cannot reach the Dask scheduler at {scheduler}: {error}") from None
        try:
            yield client
        finally:
            client.close()
        return
    if workers < 1:
        raise SweepError(f"workers must be at least 1, not {workers}")
    with _workers_ignore_sigint(), dask.config.set(_worker_environment()):
        local = LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes,
                             dashboard_address="127.0.0.1:0", silence_logs=logging.CRITICAL)
    try:
        client = Client(local)
        try:
            yield client
        finally:
            client.close()
    finally:
        local.close()


def _worker_environment():
    """Dask's environment for worker processes, less its ``MALLOC_TRIM_THRESHOLD_`` (64 KiB):
    with it, glibc hands every large temporary array back to the system and the next one is
    faulted in again: a point of the interference model took about 1.4 times the CPU time in a
    worker (1.7 times in a plain process). glibc's own default applies instead (or the user's,
    if set)."""
    import dask

    key = "distributed.nanny.pre-spawn-environ"
    environment = dict(dask.config.get(key, default={}))
    environment.pop("MALLOC_TRIM_THRESHOLD_", None)
    return {key: environment}


@contextlib.contextmanager
def _workers_ignore_sigint():
    """Worker processes started meanwhile ignore SIGINT (they inherit it): Ctrl-C at a terminal
    goes to the whole process group, and only this process should act on it, by cancelling the
    tasks and closing the cluster in order."""
    try:
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:                      # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _timed(function, *args):
    """Runs on a worker: the result and the time it took, in seconds."""
    started = time.perf_counter()
    result = function(*args)
    return result, time.perf_counter() - started


def compute(client, tasks, on_result):
    """Run ``tasks`` (``{key: (function, args)}``) on ``client``; call ``on_result(key, result,
    elapsed_s)`` in this thread as each finishes, in finishing order.

    Returns ``True`` when every task finished, ``False`` when interrupted (Ctrl-C, or SIGTERM
    turned into :exc:`KeyboardInterrupt`): the unfinished tasks are cancelled and what finished
    has been handed over. An exception of a task (or of ``on_result``) cancels the others and
    propagates.
    """
    from dask.distributed import as_completed

    token = uuid.uuid4().hex                # Dask keys of this call only, on a shared scheduler
    futures = {}
    try:
        for key, (function, args) in tasks.items():
            _stop_if_requested()
            future = client.submit(_timed, function, *args, key=f"fliss-{key}-{token}",
                                   pure=False)
            futures[future] = key
        for future in as_completed(futures):
            _stop_if_requested()
            result, elapsed_s = future.result()
            on_result(futures[future], result, elapsed_s)
        return True
    except KeyboardInterrupt:
        return False
    finally:
        unfinished = [future for future in futures if not future.done()]
        if unfinished:
            with contextlib.suppress(Exception):
                client.cancel(unfinished)


def _stop_if_requested():
    # A signal's KeyboardInterrupt can be swallowed by Dask's own hooks: its flag is not.
    if interrupts.requested.is_set():
        raise KeyboardInterrupt


class Store:
    """Finished points of a sweep: ``DIR/points/KEY.json``, each written whole (to a temporary
    name, then renamed), so that an interrupted run leaves only complete points."""

    def __init__(self, directory):
        self.directory = os.path.join(directory, STORE_NAME)

    def path(self, key):
        return os.path.join(self.directory, f"{key}.json")

    def load(self, key):
        """The stored record of ``key``, or ``None``."""
        path = self.path(key)
        try:
            with open(path) as file:
                record = json.load(file)
        except FileNotFoundError:
            return None
        except (OSError, ValueError) as error:
            raise SweepError(f"{path}: cannot read a finished point ({error}); delete the file "
                             f"to compute the point again") from None
        if not isinstance(record, dict) or not isinstance(record.get("result"), dict):
            raise SweepError(f"{path}: not a finished point; delete the file to compute the "
                             f"point again")
        return record

    def save(self, key, record):
        os.makedirs(self.directory, exist_ok=True)
        path = self.path(key)
        temporary = f"{path}.{os.getpid()}.tmp"
        with open(temporary, "w") as file:
            json.dump(record, file, allow_nan=False)    # the model's order of metrics
        os.replace(temporary, path)


def _evaluate(function, point, seed):
    """Runs on a worker: the model on one point; a refusal (ValueError) becomes a one-line
    SweepError, and so does any other exception, named (a model's bug, or a function that is no
    model)."""
    if isinstance(function, str):
        function = load_model(function)
    try:
        return function(dict(point), point_seed(seed, point))
    except ValueError as error:
        raise SweepError(f"point {canonical(point)}: {error}") from None
    except Exception as error:
        raise SweepError(f"point {canonical(point)}: the model failed: "
                         f"{type(error).__name__}: {error}") from None


def _check_result(point, result):
    if not isinstance(result, dict):
        raise SweepError(f"point {canonical(point)}: the model returned "
                         f"{type(result).__name__}, not a dict of metrics")
    clean = {}
    for name, value in result.items():
        if hasattr(value, "item") and not isinstance(value, (str, bytes)):
            value = value.item()            # numpy scalars
        if value is not None and not isinstance(value, (bool, int, float, str)):
            raise SweepError(f"point {canonical(point)}: metric {name!r} is "
                             f"{type(value).__name__}, not a number, string, boolean or None")
        if isinstance(value, float) and not math.isfinite(value):
            value = None                     # JSON and Parquet: missing
        clean[str(name)] = value
    return clean


def run_sweep(spec, out_dir, client, *, function=None, progress=None):
    """Run ``spec`` on ``client`` into ``out_dir``; returns an :class:`Outcome`.

    ``function`` replaces the spec's model (a callable, for tests); ``progress(done, total,
    computed, elapsed_s)`` is called once before any work and after every finished point.
    Points already stored in ``out_dir`` are not computed again.
    """
    store = Store(out_dir)
    points = spec.points()
    keys = [point_key(spec.model, spec.seed, point) for point in points]
    todo = {}
    reused = 0
    for key, point in zip(keys, points):
        if key in todo:
            continue
        if store.load(key) is not None:
            reused += 1
        else:
            todo[key] = point
    unique = reused + len(todo)
    model = spec.model if function is None else function
    tasks = {key: (_evaluate, (model, point, spec.seed)) for key, point in todo.items()}
    started = time.monotonic()
    done = [reused, 0]

    def finished(key, result, elapsed_s):
        point = todo[key]
        store.save(key, {"model": spec.model, "seed": spec.seed, "point": point,
                         "result": _check_result(point, result), "elapsed_s": elapsed_s})
        done[0] += 1
        done[1] += 1
        if progress:
            progress(done[0], unique, done[1], time.monotonic() - started)

    if progress:
        progress(reused, unique, 0, 0.0)
    complete = compute(client, tasks, finished) if tasks else True
    elapsed_s = time.monotonic() - started
    table = None
    if done[0]:
        table = os.path.join(out_dir, TABLE_NAME)
        write_table(table_rows(spec, store, points, keys), table)
    return Outcome(total=unique, reused=reused, computed=done[1], interrupted=not complete,
                   elapsed_s=elapsed_s, table=table)


def table_rows(spec, store, points=None, keys=None):
    """One row (parameters, then metrics) per finished point of ``spec``, in grid order. A
    metric named like a parameter is left out when it equals it in every row, and is kept as
    ``NAME_result`` otherwise."""
    points = spec.points() if points is None else points
    keys = [point_key(spec.model, spec.seed, p) for p in points] if keys is None else keys
    pairs, seen = [], set()
    for key, point in zip(keys, points):
        record = store.load(key)
        if record is not None and key not in seen:
            seen.add(key)
            pairs.append((point, record["result"]))
    clashes = {name for point, result in pairs for name in result if name in point}
    differ = {name for name in clashes
              if any(name in result and result[name] != point[name] for point, result in pairs)}
    rows = []
    for point, result in pairs:
        row = dict(point)
        for name, value in result.items():
            if name in differ:
                row[f"{name}_result"] = value
            elif name not in clashes:
                row[name] = value
        rows.append(row)
    return rows


def write_table(rows, path):
    """Write ``rows`` (dicts) as a Parquet file; a column mixing integers and floats is stored
    as floats, missing values as nulls."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    names = []
    for row in rows:
        names += [name for name in row if name not in names]
    columns = {}
    for name in names:
        values = [row.get(name) for row in rows]
        kinds = {type(value) for value in values if value is not None}
        if kinds == {int, float}:
            values = [None if value is None else float(value) for value in values]
        elif len(kinds) > 1:
            values = [None if value is None else str(value) for value in values]
        columns[name] = values
    temporary = f"{path}.{os.getpid()}.tmp"
    pq.write_table(pa.table(columns), temporary)
    os.replace(temporary, path)
