"""The state block shared between the servo loop and the viewer: layout, seqlock, command slot.

No GL here: the servo process imports this module only.

Memory layout of the `multiprocessing.shared_memory` block::

    int64 header[32]    SEQ (seqlock counter), MAGIC, NGEOM, NFINGER, CLOSED (run over),
                        VIEWER_STATUS, VIEWER_FRAMES, VIEWER_PID, REQUEST[16] (command slot),
                        VIEWER_BEAT (heartbeat), SERVO_PID (the publisher's process)
    float64 state[...]  scalars (time, ticks, rates, tick p50/p99, faults, misses),
                        geom_xpos (ngeom x 3), geom_xmat (ngeom x 9), fingers (nfinger x 32)

Every header field has exactly one writer; `state` is written by the publisher only,
under a seqlock: it makes SEQ odd, writes, makes SEQ even. A reader copies `state` and
keeps the copy only if SEQ was even and unchanged across the copy; otherwise it retries.
The writer never waits for a reader, whatever the reader does (a frozen or killed viewer
included): there are no locks and no pipes. (Loads are not reordered with loads, nor
stores with stores, on x86-64; that is what this relies on.)

The command slot: REQUEST[i] is the contact mode the viewer asks for finger i
(-1 no request, 0 soft, 1 point). It is level-triggered, so there is nothing to
acknowledge and nothing to lose: the publisher polls it when it publishes (outside the
timed tick) and switches a finger whose mode differs; the mode a finger really has is
published back in its state record.

The heartbeat: the viewer adds one to VIEWER_BEAT at every turn of its display loop (drawn,
paused or waiting alike), so the servo side can tell a viewer that stopped responding
(frozen, stopped, starved) from one waiting for its user, and never waits on the former.
SERVO_PID is the publisher's process: a viewer started on its own watches it and closes
when it is gone.
"""

from __future__ import annotations

import os
import time

import numpy as np
from multiprocessing import shared_memory

from softproxy.fingertip import MODELS
from softproxy.fingertip import model as fingertip_model

MAGIC = 0x5350_5648_4D45_4D31  # "SPVHMEM1"
HEADER_SLOTS = 32
HEADER_BYTES = HEADER_SLOTS * 8
MAX_FINGERS = 16

# header slots (int64)
SEQ, H_MAGIC, H_NGEOM, H_NFINGER, H_CLOSED, H_VIEWER_STATUS, H_VIEWER_FRAMES = range(7)
H_REQUEST = 8  # .. 8 + MAX_FINGERS (slot 7 is free)
H_VIEWER_BEAT = H_REQUEST + MAX_FINGERS  # the viewer's heartbeat: +1 per display-loop turn
H_SERVO_PID = H_VIEWER_BEAT + 1          # the publisher's process id

# viewer status values
VIEWER_STARTING, VIEWER_RUNNING, VIEWER_FAILED, VIEWER_CLOSED = 0, 1, 2, 3
# contact modes
SOFT, POINT = 0, 1

# state scalars (float64)
S_T, S_TICKS, S_RATE_NOMINAL, S_RATE, S_P50_US, S_P99_US, S_FAULTS, S_MISSES, S_WALL, S_REALTIME, S_PUBLISHES = range(11)
N_SCALARS = 16

# per-finger record (float64)
F_PROXY = 0        # 0..2 proxy (god-object) centre, m
F_DEVICE = 3       # 3..5 device position in the world, m
F_FORCE = 6        # 6..8 force on the finger, N
F_POINT = 9        # 9..11 contact point, m
F_NORMAL = 12      # 12..14 contact normal (out of the object)
F_CONTACT = 15     # proxy touches something
F_VALID = 16       # last device sample usable
F_MODE = 17        # SOFT (torsion present) or POINT
F_TORSION_CONTACT = 18
F_ALPHA_P = 19     # proxy twist, rad
F_ALPHA_G = 20     # goal twist (device), rad
F_ALPHA_0 = 21     # twist where contact began, rad
F_SLIPPING = 22
F_LIMIT = 23       # static torsional limit mu'|P|^gamma, N·m
F_K_TAU = 24       # torsional stiffness, N·m/rad
F_TORQUE = 25      # M about n, N·m
F_NORMAL_FORCE = 26  # P, N
F_RADIUS = 27      # proxy radius, m
F_BODY = 28        # touched body id or -1
F_SLIPS = 29       # slip events
F_MODEL = 30       # index of the finger's fingertip model in softproxy.fingertip.MODELS (-1 unknown)
F_ENERGY = 31      # the passivity observer E, J (< 0: energy the coupling owes; softproxy.compiled.passivity)
N_FINGER_FIELDS = 32

TICK_WINDOW = 1000  # tick p50/p99 over the most recent ticks
MODEL_NAMES = list(MODELS)
_MODEL_INDEX = {name: i for i, name in enumerate(MODEL_NAMES)}


class Layout:
    """Sizes and offsets of the state array for a model with `ngeom` geoms and `nfinger` fingers."""

    def __init__(self, ngeom: int, nfinger: int) -> None:
        if not 0 <= nfinger <= MAX_FINGERS:
            raise ValueError(f"the viewer shows at most {MAX_FINGERS} fingers, got {nfinger}")
        self.ngeom = int(ngeom)
        self.nfinger = int(nfinger)
        self.xpos = N_SCALARS
        self.xmat = self.xpos + 3 * self.ngeom
        self.fingers = self.xmat + 9 * self.ngeom
        self.size = self.fingers + N_FINGER_FIELDS * self.nfinger
        self.nbytes = HEADER_BYTES + 8 * self.size

    def __eq__(self, other) -> bool:
        return isinstance(other, Layout) and (self.ngeom, self.nfinger) == (other.ngeom, other.nfinger)

    def empty(self) -> np.ndarray:
        return np.zeros(self.size)


class Frame:
    """A consistent copy of the state (numpy views into one float64 array)."""

    def __init__(self, layout: Layout, data: np.ndarray) -> None:
        self.layout = layout
        self.data = data
        self.geom_xpos = data[layout.xpos:layout.xmat].reshape(layout.ngeom, 3)
        self.geom_xmat = data[layout.xmat:layout.fingers].reshape(layout.ngeom, 3, 3)
        self.fingers = data[layout.fingers:layout.size].reshape(layout.nfinger, N_FINGER_FIELDS)

    def copy(self) -> "Frame":
        return Frame(self.layout, self.data.copy())

    @property
    def t(self) -> float:
        return float(self.data[S_T])

    @property
    def ticks(self) -> int:
        return int(self.data[S_TICKS])

    def scalar(self, index: int) -> float:
        return float(self.data[index])


def pack_state(loop, out: np.ndarray, layout: Layout, rate: float = 0.0, p50_us: float = 0.0,
               p99_us: float = 0.0, publishes: int = 0) -> None:
    """Write the loop's current state into `out` (a float64 array of `layout.size`)."""
    data = loop.world.data
    out[S_T] = loop.t
    out[S_TICKS] = loop.ticks
    out[S_RATE_NOMINAL] = loop.rate_hz
    out[S_RATE] = rate
    out[S_P50_US] = p50_us
    out[S_P99_US] = p99_us
    out[S_FAULTS] = sum(loop.faults.values())
    out[S_MISSES] = loop.stats.misses
    out[S_WALL] = time.time()
    out[S_REALTIME] = 1.0 if loop.paced else 0.0
    out[S_PUBLISHES] = publishes
    ng = layout.ngeom
    out[layout.xpos:layout.xmat] = data.geom_xpos.reshape(-1)[:3 * ng]
    out[layout.xmat:layout.fingers] = data.geom_xmat.reshape(-1)[:9 * ng]
    o = layout.fingers
    for f in loop.fingers[:layout.nfinger]:
        god = f.god
        tors = f.torsion
        if tors is not None:
            t = (SOFT, 1.0 if tors.in_contact else 0.0, tors.alpha_p, tors.alpha_g, tors.alpha_0,
                 1.0 if tors.slipping else 0.0, tors.limit, tors.k_tau)
        else:
            t = (POINT, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        out[o:o + 32] = (god.x, god.y, god.z, f.xd, f.yd, f.zd, f.fx, f.fy, f.fz, f.px, f.py, f.pz,
                         god.nx, god.ny, god.nz, 1.0 if god.contact else 0.0, 1.0 if f.valid else 0.0,
                         *t, f.torque, f.normal_force, f.params.radius, f.body, f.slip_events,
                         _MODEL_INDEX.get(f.model.name, -1), f.energy)
        o += N_FINGER_FIELDS


def tick_percentiles_us(stats, window: int = TICK_WINDOW) -> tuple[float, float]:
    """Tick duration p50 and p99 (µs) over the most recent `window` ticks (0, 0 before any)."""
    n = stats.count
    if n == 0:
        return 0.0, 0.0
    cap = stats.capacity
    k = min(n, window, cap)
    i = n % cap
    d = stats.duration
    w = d[i - k:i] if i >= k else np.concatenate((d[cap - (k - i):], d[:i]))
    i50, i99 = (k - 1) // 2, (99 * (k - 1)) // 100  # nearest rank: np.partition is ~15x cheaper than percentile
    part = np.partition(w, (i50, i99))
    return float(part[i50]) * 1e6, float(part[i99]) * 1e6


# ---------------------------------------------------------------------------------------
# Soft <-> point contact, switched from the publisher (between ticks, never inside one)
# ---------------------------------------------------------------------------------------
def contact_mode(finger) -> int:
    return SOFT if finger.torsion is not None else POINT


def set_contact_mode(finger, mode: int, saved_slips: dict | None = None) -> bool:
    """Make `finger` a soft finger (torsion) or a point contact (no torsion). True if it changed.

    Point: the torsion goes and the torque it was rendering is zeroed. Soft: a torsion law
    from `finger.params`, with the finger's own fingertip model or, if that model has no
    torsion (a run with `--finger-model point`), the model its params name, else CH; it
    starts out of contact, so the torque starts at zero at the next tick
    (`SoftFingerProxy.use_torsion`). `saved_slips` (by finger id) keeps the torsional slip
    count across switches. Call it between ticks only (the publisher does).
    """
    if mode == contact_mode(finger):
        return False
    if mode == POINT:
        if saved_slips is not None:
            saved_slips[id(finger)] = finger.torsion.slip_events
        finger.use_torsion(None)
        return True
    soft = finger.model
    if not soft.has_torsion:
        try:
            soft = fingertip_model(finger.params.model)
        except (KeyError, ValueError):
            soft = None
        if soft is None or not soft.has_torsion:
            soft = fingertip_model("CH")
    finger.use_torsion(soft)
    if saved_slips is not None:
        finger.torsion.slip_events = saved_slips.get(id(finger), 0)
    return True


_CREATED: set[str] = set()  # blocks this process created (and its resource tracker unlinks)


def _start_resource_tracker() -> None:
    """Start multiprocessing's resource tracker (it unlinks our blocks should this process die)
    without it running the user's files: it is started as `python -c ...` in the working
    directory, which would put that directory first on its sys.path (a `select.py` there runs).
    PYTHONSAFEPATH=1 (Python >= 3.11) keeps the directory out; it is set only while the tracker
    starts. Nothing happens if the tracker already runs."""
    if os.name != "posix":
        return
    from multiprocessing import resource_tracker

    before = os.environ.get("PYTHONSAFEPATH")
    os.environ["PYTHONSAFEPATH"] = "1"
    try:
        resource_tracker.ensure_running()
    finally:
        if before is None:
            del os.environ["PYTHONSAFEPATH"]
        else:
            os.environ["PYTHONSAFEPATH"] = before


def _attach(name: str) -> shared_memory.SharedMemory:
    """Attach to an existing block without letting this process's resource tracker unlink it."""
    try:
        return shared_memory.SharedMemory(name=name, track=False)  # Python >= 3.13
    except TypeError:
        shm = shared_memory.SharedMemory(name=name)
        if shm.name in _CREATED:  # same process as the publisher: its registration stays
            return shm
        try:
            from multiprocessing import resource_tracker

            resource_tracker.unregister(shm._name, "shared_memory")  # noqa: SLF001 (3.11/3.12 workaround)
        except Exception:
            pass
        return shm


class _Block:
    """A mapped block: header and state views; `close()` releases the views before the mapping."""

    def __init__(self, shm: shared_memory.SharedMemory, layout: Layout) -> None:
        self.shm = shm
        self.layout = layout
        self.header = np.ndarray((HEADER_SLOTS,), np.int64, buffer=shm.buf)
        self.state = np.ndarray((layout.size,), np.float64, buffer=shm.buf, offset=HEADER_BYTES)

    @property
    def name(self) -> str:
        return self.shm.name

    def _release(self) -> None:
        self.header = self.state = None
        try:
            self.shm.close()
        except Exception:
            pass


class StatePublisher(_Block):
    """Servo side: an `on_tick(loop)` callable publishing every `every` ticks. Never blocks.

    Creates the shared-memory block (`name` is chosen by the system unless given). Each
    publish polls the command slot, then writes the state under the seqlock: a few
    dozen µs, outside the timed part of the tick.
    """

    def __init__(self, layout: Layout, every: int = 17, name: str | None = None) -> None:
        if every < 1:
            raise ValueError(f"every must be >= 1 tick, got {every!r}")
        _start_resource_tracker()
        shm = shared_memory.SharedMemory(create=True, size=layout.nbytes, name=name)
        _CREATED.add(shm.name)
        super().__init__(shm, layout)
        self.header[:] = 0
        self.header[H_MAGIC] = MAGIC
        self.header[H_NGEOM] = layout.ngeom
        self.header[H_NFINGER] = layout.nfinger
        self.header[H_REQUEST:H_REQUEST + MAX_FINGERS] = -1
        self.header[H_SERVO_PID] = os.getpid()
        self.every = int(every)
        self.publishes = 0
        self.switches = 0
        self._seq = 0
        self._next_tick = 0
        self._last_wall = None
        self._last_ticks = 0
        self._rate = 0.0
        self._slips: dict = {}
        self._unlinked = False

    @classmethod
    def for_loop(cls, loop, display_hz: float = 60.0, name: str | None = None) -> "StatePublisher":
        """A publisher sized for `loop`'s world and fingers, publishing at about `display_hz`."""
        layout = Layout(loop.world.model.ngeom, len(loop.fingers))
        return cls(layout, every=max(1, int(round(loop.rate_hz / display_hz))), name=name)

    def __call__(self, loop) -> None:
        if loop.ticks < self._next_tick:
            return
        self._next_tick = loop.ticks + self.every
        self.poll_commands(loop)
        self.publish(loop)

    def poll_commands(self, loop) -> None:
        """Apply the contact modes the viewer asked for (between ticks)."""
        header = self.header
        for i, f in enumerate(loop.fingers[:self.layout.nfinger]):
            want = int(header[H_REQUEST + i])
            if want in (SOFT, POINT) and want != contact_mode(f):
                if set_contact_mode(f, want, self._slips):
                    self.switches += 1

    def publish(self, loop) -> None:
        """Write the loop's state under the seqlock."""
        now = time.perf_counter()
        if self._last_wall is not None and now > self._last_wall:
            rate = (loop.ticks - self._last_ticks) / (now - self._last_wall)
            self._rate = rate if self._rate == 0.0 else 0.8 * self._rate + 0.2 * rate
        self._last_wall, self._last_ticks = now, loop.ticks
        p50, p99 = tick_percentiles_us(loop.stats)
        self.publishes += 1
        header = self.header
        self._seq += 1
        header[SEQ] = self._seq  # odd: writing
        pack_state(loop, self.state, self.layout, self._rate, p50, p99, self.publishes)
        self._seq += 1
        header[SEQ] = self._seq  # even: consistent

    def write(self, data: np.ndarray) -> None:
        """Copy a whole state array (`layout.size` floats) in under the seqlock."""
        header = self.header
        self._seq += 1
        header[SEQ] = self._seq
        self.state[:] = data
        self._seq += 1
        header[SEQ] = self._seq

    def finish(self, loop=None) -> None:
        """Publish the final state (if given the loop) and tell the viewer the run is over."""
        if self.header is None:
            return
        if loop is not None:
            self.poll_commands(loop)
            self.publish(loop)
        self.header[H_CLOSED] = 1

    @property
    def viewer_status(self) -> int:
        return int(self.header[H_VIEWER_STATUS]) if self.header is not None else VIEWER_CLOSED

    @property
    def viewer_frames(self) -> int:
        return int(self.header[H_VIEWER_FRAMES]) if self.header is not None else 0

    @property
    def viewer_beat(self) -> int:
        """The viewer's heartbeat counter (it changes while the viewer's display loop turns)."""
        return int(self.header[H_VIEWER_BEAT]) if self.header is not None else 0

    def close(self) -> None:
        """Unmap and unlink the block (a viewer still attached keeps its own mapping)."""
        if self.header is not None:
            self.header[H_CLOSED] = 1
        self._release()
        if not self._unlinked:
            self._unlinked = True
            try:
                self.shm.unlink()
            except FileNotFoundError:
                pass
            _CREATED.discard(self.shm.name)


class StateReader(_Block):
    """Viewer side: attach to the block by name, read consistent frames, write the command slot."""

    def __init__(self, name: str) -> None:
        shm = _attach(name)
        header = np.ndarray((HEADER_SLOTS,), np.int64, buffer=shm.buf)
        if shm.size < HEADER_BYTES or int(header[H_MAGIC]) != MAGIC:
            del header
            shm.close()
            raise ValueError(f"shared memory {name!r} is not a softproxy viewer block")
        layout = Layout(int(header[H_NGEOM]), int(header[H_NFINGER]))
        del header
        super().__init__(shm, layout)
        self.frame = Frame(layout, layout.empty())
        self.retries = 0

    def read(self, tries: int = 1000) -> Frame | None:
        """The latest consistent frame (a fresh copy), or None if none was published yet
        or the writer kept it busy for `tries` attempts (the caller keeps its last frame)."""
        header, state = self.header, self.state
        buf = self.layout.empty()
        for _ in range(tries):
            s1 = int(header[SEQ])
            if s1 == 0:
                return None
            if s1 & 1:
                self.retries += 1
                time.sleep(0)
                continue
            np.copyto(buf, state)
            if int(header[SEQ]) == s1:
                return Frame(self.layout, buf)
            self.retries += 1
        return None

    @property
    def closed(self) -> bool:
        """The run is over (the publisher finished or closed)."""
        return bool(self.header[H_CLOSED])

    def request_mode(self, finger: int, mode: int) -> None:
        """Ask the servo side to make finger `finger` SOFT or POINT (applied at its next publish)."""
        if not 0 <= finger < self.layout.nfinger:
            raise IndexError(f"no finger {finger}")
        if mode not in (SOFT, POINT):
            raise ValueError(f"mode must be SOFT (0) or POINT (1), got {mode!r}")
        self.header[H_REQUEST + finger] = mode

    def set_status(self, status: int) -> None:
        self.header[H_VIEWER_STATUS] = status

    def count_frame(self) -> None:
        self.header[H_VIEWER_FRAMES] += 1

    def beat(self) -> None:
        """One turn of the display loop: the servo side sees the viewer is responsive."""
        self.header[H_VIEWER_BEAT] += 1

    @property
    def servo_pid(self) -> int:
        """The publisher's process id (0: unknown)."""
        return int(self.header[H_SERVO_PID])

    def close(self) -> None:
        self._release()


def frame_of(loop, layout: Layout | None = None) -> Frame:
    """A frame of the loop's state now, without shared memory (snapshots, video)."""
    layout = layout or Layout(loop.world.model.ngeom, len(loop.fingers))
    data = layout.empty()
    p50, p99 = tick_percentiles_us(loop.stats)
    pack_state(loop, data, layout, 0.0, p50, p99)
    return Frame(layout, data)
