"""Running a grid of independent cells — one function, one dict of keyword arguments per cell —
serially, in a pool of worker processes, or as Ray tasks, with the results in cell order.

`run_cells(fn, cells, backend)` is the one seam every sweep goes through (`bench stability`,
`bench tradeoff`, `softproxy replay-batch`). A backend never changes a result: each cell is a
lockstep run that depends only on its parameters, and the outcomes are ordered by cell,
never by completion, so the same cells give the same values bit for bit whichever backend
ran them (timings aside).

- **serial** (`Backend()`): the cells run in this process, one after the other. A cell that
  ends the process (a MuJoCo error inside the tick exits with status 3) ends the sweep;
  `--workers 1` isolates the cells in a worker process instead.
- **pool** (`Backend(workers=N)`): N worker processes, started fresh (`spawn`: nothing
  inherited from the parent's threads) and kept for the whole sweep, so each one compiles or
  loads numba's kernels once, on its first cell, and reuses them for every later cell. A
  worker that dies takes no other cell with it: the cells it may have been running are run
  again alone, each in a process of its own, and a cell that kills its process there too is
  reported as failed (with the exit status); the rest of the sweep goes on in a new pool.
- **Ray** (`Backend(ray="")`: a new Ray of its own on this machine, whatever RAY_ADDRESS
  says; `Backend(ray="ADDRESS")`: an existing cluster, e.g. `auto` on a cluster node (or
  with RAY_ADDRESS set) or `ray://HEAD:10001` from a laptop): one task per cell, on Ray's
  long-lived worker processes (again: kernels loaded once per worker). Ray is the optional
  extra `softproxy[cluster]`, imported only here and only when asked for. A local Ray's
  workers get this process's import path, as a pool's do.

A cell that raises is caught where it runs and comes back as an `Outcome` whose `error` is one
line (exception, message, where) with its parameters; the other cells are not disturbed.

A signal is not a cell's failure: it is someone stopping the work. A termination signal
(SIGTERM from `timeout` or a service stop, SIGHUP, SIGQUIT, ...) that reaches a cell, in this
process or in a pool worker, or a worker killed by SIGKILL or one of those signals, stops
the whole sweep: `SweepStopped` (one line naming the cell and the signal; `status` is the
shell's 128 + signal number), the pool's workers ended, Ray's tasks cancelled. The same
signals sent to this process while it waits on a pool or Ray end the sweep the same way
(`softproxy.termination` turns them into an orderly exit while a sweep runs, as it does
while a servo loop runs). A crash of the cell's own making (SIGSEGV, SIGABRT, an exit
status) is that cell's failure, as above.

`--workers N` is capped at the CPUs this process may run on (`cpu_count()`): more processes
than cores only make every cell slower and the machine unresponsive. `--oversubscribe` lifts
the cap for whoever knows better (cells that mostly wait).
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
import socket
import sys
import time
import traceback
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Callable, Iterator, Sequence

from softproxy import termination

CLUSTER_EXTRA = "pip install 'softproxy[cluster]'"
"""How to get Ray (the `cluster` extra of pyproject.toml)."""
RAY_RETRIES = 1
"""Times Ray runs a cell again whose worker died: once covers a lost node; a cell that kills its
worker every time is reported as failed, not run four times (Ray's default)."""
RAY_WAIT_S = 1.0
"""Longest wait for a Ray result before looking again (s): how late Ctrl-C may be seen."""
RAY_CONNECT_S = 3.0
"""How long a cluster address may take to accept a connection (s) before --ray gives up on it."""
WORKER_STOP_S = 2.0
"""How long a pool's workers get to end after SIGTERM when a sweep stops (s), before SIGKILL."""
STOPPING = frozenset(termination.HANDLED) - {signal.SIGINT} | {signal.SIGKILL}
"""Signals that, ending a cell's process or reaching a cell, stop the whole sweep (someone
stopping the work, not the cell failing). SIGINT (Ctrl-C) stops it too, as KeyboardInterrupt."""


class BackendError(ValueError):
    """A backend that cannot be used (bad flag, Ray missing or unreachable); one line naming the flag."""


class SweepStopped(RuntimeError):
    """A signal stopped a cell or the sweep: the sweep ends as a whole. One line; `status` is the
    exit status a shell gives for the signal (128 + its number)."""

    def __init__(self, message: str, sig: int) -> None:
        super().__init__(message)
        self.signal = sig
        self.status = 128 + sig


def cpu_count() -> int:
    """The CPUs this process may run on (its affinity mask where the platform has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def signal_of(exc: BaseException) -> int | None:
    """The signal number behind a SystemExit that `softproxy.termination` raised for a signal,
    else None (a cell's own sys.exit is not a signal, whatever its code)."""
    if not isinstance(exc, SystemExit):
        return None
    tb = exc.__traceback__
    while tb is not None:
        if tb.tb_frame.f_code is termination._raise.__code__:
            return exc.code - 128 if isinstance(exc.code, int) else None
        tb = tb.tb_next
    return None


def _signal_name(sig: int) -> str:
    try:
        return signal.Signals(sig).name
    except ValueError:
        return f"signal {sig}"


@dataclass(frozen=True)
class Backend:
    """Where cells run: `workers` 0 = serially in this process, N >= 1 = a pool of N worker
    processes; `ray` None = no Ray, "" = Ray started on this machine, "ADDRESS" = an existing
    Ray cluster (then `workers` is 0: the cluster decides its parallelism)."""

    workers: int = 0
    ray: str | None = None
    asked: int | None = None  # --workers as given, when the CPU count capped it

    @classmethod
    def from_flags(cls, workers: int | None = None, ray: str | None = None, command: str = "softproxy",
                   oversubscribe: bool = False) -> "Backend":
        """The backend of `--workers N` / `--ray [ADDRESS]`; BackendError (one line naming the
        flag and the fix) for a bad count, both flags together, or Ray not installed. N is
        capped at `cpu_count()` unless `oversubscribe` (`--oversubscribe`); `note` says so."""
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
            raise BackendError(f"{command}: --workers must be a number of worker processes >= 1, got {workers!r}")
        if workers is not None and ray is not None:
            raise BackendError(f"{command}: give --workers N (a local pool) or --ray [ADDRESS] (Ray decides its "
                               f"own parallelism), not both")
        if oversubscribe and workers is None:
            raise BackendError(f"{command}: --oversubscribe lets --workers N exceed the CPU count; give --workers N")
        if ray is not None:
            ray = ray.strip()
            _import_ray(f"{command}: --ray")
        asked = None
        if workers is not None and not oversubscribe and workers > cpu_count():
            asked, workers = workers, cpu_count()
        return cls(workers=workers or 0, ray=ray, asked=asked)

    @property
    def note(self) -> str | None:
        """One line saying that --workers was capped (None if it was not)."""
        if self.asked is None:
            return None
        return (f"--workers {self.asked} capped at the {self.workers} CPU(s) this process may use; "
                f"add --oversubscribe to start {self.asked} worker processes anyway")

    def describe(self) -> str:
        """One phrase for reports: "serial", "a pool of 2 worker processes", "Ray (this machine)"."""
        if self.ray is not None:
            return f"Ray ({self.ray or 'started on this machine'})"
        if self.workers:
            return f"a pool of {self.workers} worker process{'es' if self.workers > 1 else ''}"
        return "serial (this process)"


@dataclass
class Outcome:
    """What one cell gave: `value` (what fn returned) or `error` (one line: exception, message,
    where; None if the cell ran), `trace` (the full traceback, for a log), `seconds` (the
    cell's own wall time where it ran, s) and `worker` ("host:pid" that ran it)."""

    index: int
    params: dict
    value: object = None
    error: str | None = None
    trace: str | None = None
    seconds: float = 0.0
    worker: str = ""

    @property
    def ok(self) -> bool:
        return self.error is None

    def describe(self) -> str:
        """One line naming the cell by its parameters and what went wrong."""
        params = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        return f"cell {self.index} ({params}): {self.error}"


def _where(exc: BaseException) -> str:
    """"file:line in function" of the innermost frame of an exception's traceback."""
    frames = traceback.extract_tb(exc.__traceback__)
    if not frames:
        return ""
    f = frames[-1]
    return f" ({os.path.basename(f.filename)}:{f.lineno} in {f.name})"


def _worker_name() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def run_cell(fn: Callable, index: int, params: dict) -> Outcome:
    """Run one cell where this is called, catching what it raises (SystemExit included: a cell
    must not end its worker); KeyboardInterrupt, and the SystemExit of a termination signal
    (`signal_of`), still stop the sweep."""
    start = time.perf_counter()
    try:
        value = fn(**params)
    except (Exception, SystemExit) as exc:
        if signal_of(exc) is not None:
            raise
        message = " ".join(str(exc).split()) or "(no message)"
        return Outcome(index, params, error=f"{type(exc).__name__}: {message}{_where(exc)}",
                       trace="".join(traceback.format_exception(exc)), seconds=time.perf_counter() - start,
                       worker=_worker_name())
    return Outcome(index, params, value=value, seconds=time.perf_counter() - start, worker=_worker_name())


def run_cells(fn: Callable, cells: Sequence[dict], backend: Backend = Backend(),
              progress: Callable[[int, int, Outcome], None] | None = None) -> list[Outcome]:
    """Run `fn(**cell)` for every cell on `backend`; the outcomes in cell order.

    `fn` must be importable by name (a module-level function) for the pool and Ray, and its
    parameters and result picklable. `progress(done, total, outcome)` is called here as each
    cell ends (in completion order)."""
    found: list[Outcome | None] = [None] * len(cells)
    for outcome in each_outcome(fn, cells, backend, progress):
        found[outcome.index] = outcome
    return found  # type: ignore[return-value]


def each_outcome(fn: Callable, cells: Sequence[dict], backend: Backend = Backend(),
                 progress: Callable[[int, int, Outcome], None] | None = None) -> Iterator[Outcome]:
    """The outcomes of `run_cells` as the cells end (completion order; `Outcome.index` says
    which cell), so a caller can fold them in and let them go as they come."""
    cells = [dict(c) for c in cells]
    if backend.ray is not None:
        source = _ray_outcomes(fn, cells, backend.ray)
    elif backend.workers:
        source = _pool_outcomes(fn, cells, backend.workers)
    else:
        source = _serial_outcomes(fn, cells)
    installed = termination.install()  # a signal to this process: an orderly stop (workers ended)
    try:
        for done, outcome in enumerate(source, 1):
            if progress is not None:
                progress(done, len(cells), outcome)
            yield outcome
    except SystemExit as exc:
        sig = signal_of(exc)
        if sig is None:
            raise
        source.close()  # the pool's workers ended, Ray's tasks cancelled, before the line is said
        raise SweepStopped(f"stopped by {_signal_name(sig)}", sig) from None
    finally:
        source.close()
        if installed:
            termination.uninstall()


def _serial_outcomes(fn: Callable, cells: list[dict]) -> Iterator[Outcome]:
    for i, params in enumerate(cells):
        try:
            outcome = run_cell(fn, i, params)
        except SystemExit as exc:
            sig = signal_of(exc)
            if sig is None:
                raise
            raise SweepStopped(f"cell {i} was stopped by {_signal_name(sig)}; the sweep stops", sig) from None
        yield outcome


# ---------------------------------------------------------------------------------------------
# a pool of worker processes

_started = None  # in a pool worker: the shared flags, one per cell, set when the cell starts


def _init_worker(started) -> None:
    global _started
    _started = started
    termination.install()  # kept for the worker's life: a signal to it reaches the cell as SystemExit


def _stopped(index: int, sig: int, how: str) -> SweepStopped:
    return SweepStopped(f"cell {index}'s worker process {how} {_signal_name(sig)}; the sweep stops", sig)


def _pool_cell(fn: Callable, index: int, params: dict) -> Outcome:
    _started[index] = 1  # so a crash can be pinned on the cells that were running
    return run_cell(fn, index, params)


def _alone(fn: Callable, index: int, params: dict, conn) -> None:
    """A cell in a process of its own (a suspect after a worker died): its outcome down `conn`."""
    termination.install()
    conn.send(run_cell(fn, index, params))
    conn.close()


def _run_alone(context, fn: Callable, index: int, params: dict) -> Outcome:
    """Run one cell in a fresh process; if the process dies, an Outcome saying so."""
    reader, writer = context.Pipe(duplex=False)
    process = context.Process(target=_alone, args=(fn, index, params, writer), daemon=True)
    process.start()
    writer.close()
    try:
        outcome = reader.recv()
    except EOFError:  # the process ended without sending: it died running the cell
        outcome = None
    finally:
        if sys.exc_info()[0] is not None:  # this process is being stopped: so is the cell's
            process.terminate()
        process.join()
        reader.close()
    code = process.exitcode
    for sig in STOPPING:
        if code in (-sig, 128 + sig):
            raise _stopped(index, sig, "was ended by" if code < 0 else "stopped on")
    if outcome is None:
        outcome = Outcome(index, params, error=f"its worker process died running it (exit status "
                                               f"{process.exitcode}: a crash, or the process ended itself)",
                          worker=f"{socket.gethostname()}:{process.pid}")
    return outcome


def _end(processes: list, timeout: float = WORKER_STOP_S) -> None:
    """Make sure the pool's worker processes are gone: those left `timeout` s after SIGTERM get SIGKILL."""
    deadline = time.monotonic() + timeout
    for process in processes:
        process.join(max(0.0, deadline - time.monotonic()))
    for process in processes:
        if process.is_alive():
            process.kill()
            process.join(timeout)


def _pool_outcomes(fn: Callable, cells: list[dict], workers: int) -> Iterator[Outcome]:
    context = multiprocessing.get_context("spawn")
    left = set(range(len(cells)))
    suspects: list[int] = []
    while left:
        for i in suspects:  # each alone: only the one that kills its process is blamed
            yield _run_alone(context, fn, i, cells[i])
            left.discard(i)
        if not left:
            break
        started = context.Array("b", len(cells), lock=False)
        pool = ProcessPoolExecutor(max_workers=min(workers, len(left)), mp_context=context,
                                   initializer=_init_worker, initargs=(started,))
        broken = finished = False
        processes: list = []
        try:
            futures = {pool.submit(_pool_cell, fn, i, cells[i]): i for i in sorted(left)}
            processes = list(getattr(pool, "_processes", {}).values())  # to learn how a dead one ended
            pending = set(futures)
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    try:
                        outcome = future.result()
                    except BrokenProcessPool:
                        broken = True
                        continue
                    except SystemExit as exc:  # a signal reached the cell in its worker
                        sig = signal_of(exc) or (exc.code - 128 if isinstance(exc.code, int) else signal.SIGTERM)
                        raise _stopped(futures[future], sig, "was stopped by") from None
                    left.discard(outcome.index)
                    yield outcome
            finished = True
        finally:
            if not finished:  # stopped (a signal, an error, the caller gave up): end the workers now
                for process in processes:
                    process.terminate()
            pool.shutdown(wait=not broken and finished, cancel_futures=True)
            if broken or not finished:  # a worker the pool ended mid-cell may hang sending its result
                _end(processes)
                pool.shutdown(wait=True)  # its workers gone: its queues and their semaphores freed
        # The pool ends the workers left when one dies with SIGTERM: a SIGKILL is from outside.
        killed = [p for p in processes if p.exitcode == -signal.SIGKILL]
        if broken and killed:
            index = min((i for i in left if started[i]), default=min(left))
            raise _stopped(index, signal.SIGKILL, "was ended by")
        suspects = sorted(i for i in left if started[i])
        if broken and not suspects:  # died before any cell began (an import failing, say): blame them all
            suspects = sorted(left)


# ---------------------------------------------------------------------------------------------
# Ray

def _import_ray(flag: str):
    try:
        import ray
    except ImportError:
        raise BackendError(f"{flag} needs Ray, which is not installed: {CLUSTER_EXTRA}") from None
    return ray


def _probe(address: str) -> None:
    """BackendError unless `address` (`HOST:PORT` of a Ray head's GCS, or `ray://HOST:PORT` of
    its client server) accepts a connection and answers as Ray within RAY_CONNECT_S each. Ray
    itself retries an address that is down, or that something else answers, for 20 s to
    minutes, logging each try to stderr; this asks once, quietly."""
    client = address.startswith("ray://")
    target = address.removeprefix("ray://")
    host, colon, port = target.rpartition(":")
    if not colon or not port.isdigit():
        return  # "auto", or a form Ray resolves itself
    fix = "give the address of a running cluster (ray start --head prints it)"
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=RAY_CONNECT_S).close()
    except OSError as exc:
        raise BackendError(f"--ray {address}: cannot reach {host}:{port} ({exc.strerror or exc}); {fix}") from None
    import grpc  # Ray's own dependency, and its stubs: one call, with a deadline
    from ray.core.generated import gcs_service_pb2, gcs_service_pb2_grpc, ray_client_pb2, ray_client_pb2_grpc

    channel = grpc.insecure_channel(target)
    try:
        if client:
            ray_client_pb2_grpc.RayletDriverStub(channel).ClusterInfo(
                ray_client_pb2.ClusterInfoRequest(type=ray_client_pb2.ClusterInfoType.PING), timeout=RAY_CONNECT_S)
        else:
            gcs_service_pb2_grpc.NodeInfoGcsServiceStub(channel).GetClusterId(
                gcs_service_pb2.GetClusterIdRequest(), timeout=RAY_CONNECT_S)
    except grpc.RpcError as exc:
        what = "a Ray client server" if client else "a Ray head (its GCS)"
        said = " ".join(str(exc.details() or exc.code()).split())[:120]
        raise BackendError(f"--ray {address}: {host}:{port} is not {what} ({exc.code().name}: {said}); "
                           f"{fix}{'' if client else '; a Ray client address is ray://HEAD:10001'}") from None
    finally:
        channel.close()


_ray_address: str | None = None  # the address this module connected Ray to ("" = started here)


def start_ray(address: str = ""):
    """The ray module, connected: to `address`, or to a Ray started here (address ""), whose
    workers get this process's import path. Left connected for the next sweep; a Ray the
    application initialised itself is used as it is."""
    global _ray_address
    ray = _import_ray("--ray")
    if ray.is_initialized():
        if _ray_address is None or _ray_address == address:  # the application's own Ray, or ours
            return ray
        ray.shutdown()  # ours, but another address is asked for now
        _ray_address = None
    quiet = {"logging_level": logging.ERROR, "log_to_driver": False}
    try:
        if address:
            _probe(address)
            ray.init(address=address, **quiet)
        else:
            path = os.pathsep.join(p for p in sys.path if p and os.path.isdir(p))
            before = os.environ.get("PYTHONPATH")
            os.environ["PYTHONPATH"] = path  # inherited by the raylet this starts, and so by its workers
            try:
                # "local": a new Ray of our own, never a cluster that RAY_ADDRESS or a
                # `ray start` (even one long gone) left recorded in /tmp/ray
                ray.init(address="local", include_dashboard=False, **quiet)
            finally:
                if before is None:
                    os.environ.pop("PYTHONPATH", None)
                else:
                    os.environ["PYTHONPATH"] = before
    except BackendError:
        raise
    except Exception as exc:  # ConnectionError, RuntimeError, ValueError: Ray's own words, on one line
        what = f"--ray {address}" if address else "--ray"
        message = " ".join(str(exc).split())[:300]
        fix = ("give the address of a running cluster (ray start --head prints it; e.g. --ray auto on a node, "
               "--ray ray://HEAD:10001 from elsewhere)" if address else "check that Ray can start on this machine")
        raise BackendError(f"{what}: cannot start or reach Ray ({type(exc).__name__}: {message}); {fix}") from None
    _ray_address = address
    return ray


def stop_ray() -> None:
    """Shut down the Ray this module started or connected to (a no-op otherwise); the next
    Ray sweep starts or connects again."""
    global _ray_address
    if _ray_address is None:
        return
    import ray

    ray.shutdown()
    _ray_address = None


def _ray_outcomes(fn: Callable, cells: list[dict], address: str) -> Iterator[Outcome]:
    ray = start_ray(address)
    task = ray.remote(num_cpus=1, max_retries=RAY_RETRIES)(run_cell)
    refs = {task.remote(fn, i, params): i for i, params in enumerate(cells)}
    pending = list(refs)
    try:
        while pending:
            ready, pending = ray.wait(pending, num_returns=min(len(pending), 64), timeout=RAY_WAIT_S)
            for ref in ready:
                i = refs.pop(ref)
                try:
                    outcome = ray.get(ref)
                except Exception as exc:  # the task never returned: its worker or node died, or it could not load
                    message = " ".join(str(exc).split())[:300]
                    outcome = Outcome(i, cells[i], error=f"{type(exc).__name__}: {message}")
                yield outcome
    finally:
        for ref in pending:  # a sweep stopped early (Ctrl-C, the caller gave up) leaves no work behind
            ray.cancel(ref, force=True)
