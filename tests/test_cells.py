"""The execution seam (softproxy.cells): serial, a process pool and Ray give the same outcomes,
in cell order; a failing cell is reported with its parameters while the rest complete; each
worker loads the compiled kernels once; a bad backend flag is one line."""

import os
import sys
import time

import pytest

from softproxy.benchmarks import stability
from softproxy import cli
from softproxy.cells import Backend, BackendError, SweepStopped, cpu_count, run_cells

# A few real cells of `bench stability` (a hand-held handle against a wall) and one whose
# stiffness FingerParams refuses.
WALL = [{"kind": "wall", "device": "omega.3", "K": K, "B": B, "rate": 250.0, "duration": 0.6}
        for K in (1e3, 3e4) for B in (0.0, 2.0)]
BAD = {"kind": "wall", "device": "omega.3", "K": -1.0, "B": 0.0, "rate": 250.0, "duration": 0.6}
CELLS = WALL[:2] + [BAD] + WALL[2:]


def loads_kernels(n: int) -> tuple[int, bool]:
    """Build and run a small servo loop; (this process, whether its servo kernel was still to be
    compiled or loaded here)."""
    from softproxy.compiled import servo

    first = len(servo.begin_tick.overloads) == 0  # resolved by every loop when it is built
    stability.wall_cell("omega.3", 1e3, 2.0, 250.0, duration=0.1 + 0.01 * n)
    return os.getpid(), first


def waits(i: int, flag: str) -> int:
    """Cell 0 waits for the last cell to raise `flag`, so it ends last (up to 300 s: a guard
    against a hang, long enough for the other worker to start and run four cells on a loaded
    machine; 30 s was not, once, in CI)."""
    if i == 0:
        deadline = time.monotonic() + 300.0
        while not os.path.exists(flag) and time.monotonic() < deadline:
            time.sleep(0.01)
    elif i == 4:
        open(flag, "w").close()
    return i


def dies(i: int) -> int:
    if i == 2:
        os._exit(3)  # as a MuJoCo error inside the tick ends a process
    return i * i


def signalled(i: int, sig: int) -> int:
    """Cell 2 sends `sig` to its own process, as `timeout` or `kill` would, and waits for it."""
    if i == 2:
        os.kill(os.getpid(), sig)
        for _ in range(3000):  # the signal's handler (or its default action) ends this
            time.sleep(0.01)
    return i


def check_outcomes(outcomes):
    """The bad cell failed with a one-line error naming the stiffness; the others match a direct run."""
    assert [o.index for o in outcomes] == list(range(len(CELLS)))
    assert [o.params for o in outcomes] == CELLS
    bad = outcomes[2]
    assert not bad.ok and "stiffness" in bad.error and "\n" not in bad.error
    assert "K=-1.0" in bad.describe()
    assert all(o.ok for i, o in enumerate(outcomes) if i != 2)
    return [o.value for o in outcomes]


@pytest.fixture(scope="module")
def serial():
    return check_outcomes(run_cells(stability.cell, CELLS))


@pytest.mark.slow
def test_serial_outcomes_are_the_cells_run_directly(serial):
    """Serially, each outcome is what calling the cell gives, and a second sweep gives it again."""
    assert serial[:2] + serial[3:] == [stability.cell(**c) for c in WALL]
    assert check_outcomes(run_cells(stability.cell, CELLS)) == serial


@pytest.mark.slow
def test_pool_gives_the_serial_outcomes(serial):
    """Two worker processes: the same values, in cell order, and the failing cell reported."""
    done = []
    outcomes = run_cells(stability.cell, CELLS, Backend(workers=2), lambda d, n, o: done.append((d, n)))
    assert check_outcomes(outcomes) == serial
    assert done == [(i, len(CELLS)) for i in range(1, len(CELLS) + 1)]
    assert all(o.worker.split(":")[1] != str(os.getpid()) for o in outcomes)


@pytest.mark.slow
def test_ray_gives_the_serial_outcomes(serial):
    """Ray started on this machine: the same values, in cell order, the failing cell reported."""
    pytest.importorskip("ray")
    outcomes = run_cells(stability.cell, CELLS, Backend(ray=""))
    assert check_outcomes(outcomes) == serial


@pytest.mark.slow
@pytest.mark.parametrize("backend", [Backend(workers=2), Backend(ray="")], ids=["pool", "ray"])
def test_kernels_load_once_per_worker(backend):
    """Each worker process compiles or loads the servo kernel on its first cell only, and the
    workers persist across cells (fewer processes than cells)."""
    if backend.ray is not None:
        pytest.importorskip("ray")
    outcomes = run_cells(loads_kernels, [{"n": n} for n in range(8)], backend)
    assert all(o.ok for o in outcomes), [o.error for o in outcomes]
    by_worker = {}
    for o in outcomes:
        pid, first = o.value
        by_worker.setdefault(pid, []).append(first)
    assert len(by_worker) < len(outcomes)
    if backend.ray is None:  # fresh workers: each loads on its first cell (Ray's may have loaded earlier)
        assert all(firsts[0] and firsts.count(True) == 1 for firsts in by_worker.values()), by_worker
    assert all(firsts.count(True) <= 1 for firsts in by_worker.values()), by_worker


@pytest.mark.slow
def test_outcomes_come_in_cell_order_not_completion_order(tmp_path):
    """The first cell ends last in a pool, yet comes first; progress sees completion order."""
    seen = []
    cells = [{"i": i, "flag": str(tmp_path / "flag")} for i in range(5)]
    outcomes = run_cells(waits, cells, Backend(workers=2), lambda d, n, o: seen.append(o.index))
    assert [o.value for o in outcomes] == [0, 1, 2, 3, 4]
    assert seen[-1] == 0 and sorted(seen) == [0, 1, 2, 3, 4]


@pytest.mark.slow
def test_a_cell_that_kills_its_worker_is_reported_and_the_rest_complete():
    """os._exit in one cell breaks the pool; that cell is found (run alone, it dies again) and
    reported with its exit status, and every other cell still gives its value."""
    outcomes = run_cells(dies, [{"i": i} for i in range(6)], Backend(workers=2))
    assert [o.value for i, o in enumerate(outcomes) if i != 2] == [0, 1, 9, 16, 25]
    assert not outcomes[2].ok and "exit status 3" in outcomes[2].error and "i=2" in outcomes[2].describe()


def test_backend_flags_are_checked_in_one_line(monkeypatch):
    """--workers 0, both flags, and Ray missing: BackendError naming the flag (and the extra)."""
    with pytest.raises(BackendError, match=r"--workers must be .* >= 1, got 0"):
        Backend.from_flags(0, None, "softproxy bench")
    with pytest.raises(BackendError, match="not both"):
        Backend.from_flags(2, "", "softproxy bench")
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray now raises ImportError
    with pytest.raises(BackendError, match=r"--ray needs Ray, which is not installed: pip install 'softproxy\[cluster\]'"):
        Backend.from_flags(None, "", "softproxy bench")


@pytest.mark.parametrize("argv, says", [
    (["--workers", "0"], "--workers must be a number of worker processes >= 1"),
    (["--workers", "2", "--ray"], "not both"),
    (["--ray"], "pip install 'softproxy[cluster]'"),
])
def test_bench_backend_flag_errors(argv, says, capsys, monkeypatch, tmp_path):
    """`softproxy bench stability` with a bad backend flag: exit 2, one line on stderr, nothing run."""
    monkeypatch.setitem(sys.modules, "ray", None)
    assert cli.main(["bench", "stability", "--out", str(tmp_path), *argv]) == 2
    err = capsys.readouterr().err
    assert says in err and err.count("\n") == 1
    assert not list(tmp_path.iterdir())


def test_an_unreachable_cluster_is_one_line_and_ray_never_tries_it(monkeypatch):
    """--ray at an address where nothing listens, or where something that is not Ray answers
    (an HTTP server here; a proxy in some networks): BackendError naming it, without entering
    ray.init, which would retry for 20 s to minutes and log every try to stderr."""
    ray = pytest.importorskip("ray")
    import http.server
    import threading

    def no_init(*args, **kwargs):
        raise AssertionError("ray.init was called for an address that is not Ray")

    monkeypatch.setattr(ray, "init", no_init)
    with pytest.raises(BackendError, match=r"--ray 127.0.0.1:1: cannot reach 127.0.0.1:1"):
        run_cells(stability.cell, WALL[:1], Backend(ray="127.0.0.1:1"))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.BaseHTTPRequestHandler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    port = server.server_address[1]
    try:
        for address, what in ((f"127.0.0.1:{port}", "is not a Ray head"),
                              (f"ray://127.0.0.1:{port}", "is not a Ray client server")):
            with pytest.raises(BackendError) as err:
                run_cells(stability.cell, WALL[:1], Backend(ray=address))
            message = str(err.value)
            assert f"--ray {address}: 127.0.0.1:{port} {what}" in message and "\n" not in message
    finally:
        server.shutdown()
        server.server_close()


def test_workers_are_capped_at_the_cpu_count_unless_asked():
    """--workers 1000 starts one worker per CPU (and says so in one line); --oversubscribe lets
    it start 1000; --oversubscribe without --workers is a mistake."""
    capped = Backend.from_flags(1000, None, "softproxy bench")
    assert capped.workers == cpu_count() and capped.asked == 1000
    assert "--workers 1000 capped at the" in capped.note and "--oversubscribe" in capped.note
    assert Backend.from_flags(1000, None, "softproxy bench", oversubscribe=True).workers == 1000
    assert Backend.from_flags(1, None, "softproxy bench").note is None
    with pytest.raises(BackendError, match="--oversubscribe .* give --workers N"):
        Backend.from_flags(None, None, "softproxy bench", oversubscribe=True)


STOP_SCRIPT = """
import os, signal, sys, time
from softproxy.cells import SweepStopped, run_cells
ran = []
def cell(i):
    ran.append(i)
    if i == 1:
        os.kill(os.getpid(), signal.SIGTERM)  # as `timeout` does, mid-cell
        for _ in range(3000):
            time.sleep(0.01)
    return i
try:
    run_cells(cell, [{"i": i} for i in range(4)])
except SweepStopped as exc:
    print(exc.status, ran, exc)
"""


def test_a_signal_to_a_serial_sweep_stops_it_as_a_whole(tmp_path):
    """SIGTERM reaching a cell run in this process is no failure of that cell: the sweep stops
    there (no later cell runs), one line naming the cell and the signal, status 143."""
    import subprocess

    done = subprocess.run([sys.executable, "-c", STOP_SCRIPT], capture_output=True, text=True, timeout=120,
                          cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    status, ran, message = done.stdout.strip().split(" ", 2)
    assert status == "143" and ran == "[0," and message.startswith("1]")
    assert "cell 1 was stopped by SIGTERM; the sweep stops" in message


@pytest.mark.slow
@pytest.mark.parametrize("sig", ["SIGTERM", "SIGKILL"])
def test_a_signal_that_kills_a_pool_cell_stops_the_sweep(sig):
    """A worker process signalled mid-cell (SIGTERM turned into an orderly exit there, or
    SIGKILL): the sweep stops with 128 + the signal, instead of re-running the cell alone
    and going on as it does for a crash of the cell's own making."""
    import signal

    number = getattr(signal, sig)
    with pytest.raises(SweepStopped) as err:
        run_cells(signalled, [{"i": i, "sig": int(number)} for i in range(6)], Backend(workers=2))
    assert err.value.status == 128 + number and sig in str(err.value) and "the sweep stops" in str(err.value)


@pytest.mark.slow
def test_local_ray_is_its_own(tmp_path):
    """`--ray` without an address starts a Ray of its own: a RAY_ADDRESS pointing where nothing
    listens (as a `ray start` long gone leaves recorded) neither captures nor hangs it."""
    pytest.importorskip("ray")
    import subprocess

    script = ("from softproxy.cells import Backend, run_cells; from softproxy.benchmarks import stability; "
              f"out = run_cells(stability.cell, {WALL[:2]!r}, Backend(ray='')); "
              "print(all(o.ok for o in out))")
    env = {**os.environ, "RAY_ADDRESS": "127.0.0.1:1"}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, env=env,
                          cwd=tmp_path)
    assert done.returncode == 0 and done.stdout.strip() == "True", done.stderr[-2000:]
