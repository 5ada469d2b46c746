"""Where the cases run: serially, on a local process pool or on a Dask cluster; Ctrl-C or
SIGTERM stops cleanly."""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterable, Iterator
from contextlib import contextmanager

from ..errors import InputError
from .execution import Failure, run_case_safely
from .sampling import CaseSpec
from .store import CaseStore, OnResult


def _worker_init(numba_threads: int) -> None:
    """Local pool worker: leave Ctrl-C to the parent, share the cores without oversubscribing."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    import numba

    numba.set_num_threads(max(1, min(numba_threads, numba.config.NUMBA_NUM_THREADS)))  # type: ignore[attr-defined]


def run_serial(specs: Iterable[CaseSpec], on_result: OnResult) -> None:
    """One worker: run the cases in this process (no pool to start)."""
    for spec in specs:
        on_result(run_case_safely(spec))


def run_local(specs: Iterable[CaseSpec], workers: int, on_result: OnResult) -> None:
    """A local process pool of ``workers`` spawned processes.

    Each worker gets ``cores // workers`` numba threads (the GA's batched
    evaluation is a parallel kernel), so workers x threads never exceeds the
    cores. On Ctrl-C the pending cases are cancelled and the running ones are
    stopped; every case finished before that is already on disk.
    """
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    threads = max(1, (os.cpu_count() or 1) // workers)
    pool = ProcessPoolExecutor(
        workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_worker_init,
        initargs=(threads,),
    )
    pending: set = set()
    queue = iter(specs)
    try:
        # keep a bounded number of cases in flight: a million-case campaign is fed lazily
        for spec in queue:
            pending.add(pool.submit(run_case_safely, spec))
            if len(pending) >= 2 * workers:
                break
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                on_result(future.result())
                following = next(queue, None)
                if following is not None:
                    pending.add(pool.submit(run_case_safely, following))
    except BaseException:
        for future in pending:
            future.cancel()
        # the executor has no public "stop running work": end the worker processes directly
        for process in list(getattr(pool, "_processes", {}).values()):
            process.terminate()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


_DASK_TASK_LOCK = threading.Lock()


def run_case_on_dask(spec: CaseSpec) -> dict | Failure:
    """A Dask task: one case at a time per worker process.

    numba's default threading layer must not run parallel kernels from two
    threads of one process at once, so a worker started with several threads
    runs its cases one after another; start Dask workers with ``--nthreads 1``
    and one process per core (``dask worker ADDRESS --nworkers N --nthreads 1``).
    """
    import numba

    with _DASK_TASK_LOCK:
        numba.set_num_threads(1)
        return run_case_safely(spec)


def connect(address: str):
    """A Dask client of the scheduler at ``address``; InputError when it cannot be reached."""
    try:
        from distributed import Client
    except ImportError:
        raise InputError(
            "--scheduler", "needs the dask[distributed] package (pip install 'dask[distributed]')"
        ) from None
    try:
        return Client(address, timeout="5s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError(
            "--scheduler",
            f"cannot reach a Dask scheduler at '{address}' "
            f"({type(exc).__name__}: {exc}); give tcp://HOST:PORT of a running "
            "scheduler",
        ) from None


def run_dask(specs: Iterable[CaseSpec], client, on_result: OnResult) -> None:
    """The same cases as tasks of a Dask cluster (``client`` from :func:`connect`)."""
    from distributed import as_completed

    futures = [
        client.submit(
            run_case_on_dask,
            spec,
            pure=False,
            key=f"emaprog-{spec.campaign_hash[:12]}-{spec.case_id}",
        )
        for spec in specs
    ]
    try:
        for future in as_completed(futures, loop=client.loop):
            on_result(future.result())
    except BaseException:
        client.cancel(futures)
        raise


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM) during a run of cases; the message says what is on disk and how to
    go on, ``exit_code`` is the shell's for the signal (130 Ctrl-C, 143 SIGTERM)."""

    exit_code = 130


class _Terminated(KeyboardInterrupt):
    """SIGTERM arrived: the run stops as on Ctrl-C."""


@contextmanager
def _terminate_as_interrupt() -> Iterator[None]:
    """SIGTERM (``kill PID``, a batch scheduler's stop) stops a run as Ctrl-C does.

    Without this, SIGTERM ends the parent alone and its spawned pool workers go
    on computing, unseen, until their queued cases are done. Ctrl-C reaches the
    whole process group; ``kill PID`` only the parent. Outside the main thread
    (where no handler can be set) nothing changes.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum, frame) -> None:
        raise _Terminated()

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def worker_count(requested: int | None, cases: int) -> int:
    """Local workers for ``cases`` cases: as asked (default all cores), never more than cases."""
    return max(1, min(requested or os.cpu_count() or 1, cases or 1))


def execute(
    specs: Iterable[CaseSpec],
    store: CaseStore,
    provenance: dict,
    count: int,
    workers: int,
    client,
    label: str,
    already: int,
    show_progress: bool = True,
) -> dict[str, int]:
    """Run ``count`` cases on the chosen back-end, storing each as it finishes.

    ``client`` (a Dask client) wins over ``workers``; one worker runs the cases
    in this process. Returns ``{"done": n, "failed": n}``; Ctrl-C or SIGTERM raises
    :class:`Interrupted` once the workers are stopped.
    """
    from .. import progress

    counts = {"done": 0, "failed": 0}
    with progress.task(label, count, show_progress) as advance:

        def on_result(result: dict | Failure) -> None:
            if isinstance(result, Failure):
                store.write_failure(result)
                counts["failed"] += 1
            else:
                store.write_case(result, {**provenance, "case_id": result["case_id"]})
                counts["done"] += 1
            advance(1, done=already + counts["done"], failed=counts["failed"])

        try:
            with _terminate_as_interrupt():
                if client is not None and count:
                    run_dask(specs, client, on_result)
                elif workers == 1 or not count:
                    run_serial(specs, on_result)
                else:
                    run_local(specs, workers, on_result)
        except KeyboardInterrupt as stop:
            terminated = isinstance(stop, _Terminated)
            interrupted = Interrupted(
                f"{'terminated (SIGTERM); ' if terminated else ''}"
                f"{already + counts['done']} cases are stored in {store.cases}; "
                "run the same command with --resume to finish"
            )
            interrupted.exit_code = 128 + signal.SIGTERM if terminated else 130
            raise interrupted from None
    return counts
