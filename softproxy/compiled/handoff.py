"""Two rates in two threads: the lock-free handoff between the servo thread and MuJoCo's.

In a real-time run with two rates (`softproxy.physics_thread`), MuJoCo steps in a thread of
its own at the physics rate (`run_physics`, nogil) and the servo thread never waits for it:

- **MuJoCo → servo.** After each mj_step1 the physics thread publishes the state the servo
  side reads (`MjArrays`: the poses, velocities and acceleration the local model carries
  forward, and what `mj_jac` and `mj_solveM` read for the implicit coupling) under a seqlock
  (`Handoff.seq`: odd while writing), stamped with the CLOCK_MONOTONIC time that state is
  current. The servo thread takes a new state at the start of a tick (`take`) into a mjData of
  its own (the mirror), and keeps the one it has when the copy was torn: it tries again next tick.
- **Servo → MuJoCo.** Each servo tick adds the fingers' wrenches into running sums
  (`Handoff.wsum`, ticks in `wcount`) under a second seqlock (`wseq`); MuJoCo's step applies
  their average over the ticks since its last step (the difference of the sums) and waits for
  nothing but the servo thread's few-hundred-nanosecond write.

The counters are read and written around full fences (`native.fence`). Units: m, s, N, ns.
"""

from __future__ import annotations

from softproxy.compiled.kernel import kernel
from softproxy.compiled.native import fence, mj_step1, mj_step2, monotonic_ns, sleep_until_ns

STOP, STEPS, LATE, COST_NS, MAX_COST_NS, SEEN, SEEN_STAMP, TAKEN, TORN = range(9)
"""Slots of `Handoff.ctl`: the physics thread's stop flag, steps taken, steps that ended after
their deadline, the last and the largest step's cost (ns); the servo side's last state taken
(its seq) and its stamp, states taken and copies found torn."""
CTL_SIZE = 9


@kernel
def copy_state(dst, src):
    """Every array of one `MjArrays` into another's (same model)."""
    dst.xpos[:, :] = src.xpos
    dst.xmat[:, :] = src.xmat
    dst.cvel[:, :] = src.cvel
    dst.xipos[:, :] = src.xipos
    dst.ximat[:, :] = src.ximat
    dst.subtree_com[:, :] = src.subtree_com
    dst.qvel[:] = src.qvel
    dst.qacc[:] = src.qacc
    dst.cdof[:, :] = src.cdof
    dst.qLD[:] = src.qLD
    dst.qLDiagInv[:] = src.qLDiagInv


@kernel
def publish(ho, state, stamp_ns):
    """The physics thread: MuJoCo's state (after mj_step1) into the published copy, current
    at `stamp_ns`."""
    ho.seq[0] += 1  # odd: being written
    fence()
    copy_state(ho.pub, state)
    ho.stamp[0] = stamp_ns
    fence()
    ho.seq[0] += 1


@kernel
def take(ho):
    """The servo thread: the newest published state into the mirror, if there is one it has
    not taken and the copy was not torn by a publish meanwhile. Returns the interval (s)
    since the state taken before (0.0 for the first), or -1.0 when nothing was taken."""
    ctl = ho.ctl
    s = ho.seq[0]
    fence()
    if s & 1 or s == ctl[SEEN]:
        return -1.0
    copy_state(ho.mirror, ho.pub)
    stamp = ho.stamp[0]
    fence()
    if ho.seq[0] != s:
        ctl[TORN] += 1
        return -1.0
    interval = 0.0 if ctl[TAKEN] == 0 else (stamp - ctl[SEEN_STAMP]) * 1e-9
    ctl[SEEN] = s
    ctl[SEEN_STAMP] = stamp
    ctl[TAKEN] += 1
    return interval


@kernel
def add_wrenches(ho, wrench, bodies_touched, counts):
    """The servo thread, at the end of a tick: this tick's wrenches (about the world origin)
    into the running sums, the tick counted; the tick's table emptied."""
    ho.wseq[0] += 1
    fence()
    for j in range(counts[0]):
        b = bodies_touched[j]
        for k in range(6):
            ho.wsum[b, k] += wrench[b, k]
            wrench[b, k] = 0.0
    ho.wcount[0] += 1
    fence()
    ho.wseq[0] += 1
    counts[0] = 0


@kernel
def _read_sums(ho, moving, out):
    """The physics thread: a consistent copy of the sums' rows of the `moving` bodies into
    out, and the tick count (retried while the servo thread is writing them)."""
    while True:
        s = ho.wseq[0]
        fence()
        if s & 1:
            continue
        for b in moving:
            for k in range(6):
                out[b, k] = ho.wsum[b, k]
        count = ho.wcount[0]
        fence()
        if ho.wseq[0] == s:
            return count


@kernel(nogil=True, entry=True)
def run_physics(m, d, state, ho, xfrc, moving, period_ns, start_ns, sums):
    """MuJoCo's thread: steps of period_ns from start_ns (CLOCK_MONOTONIC) until ctl[STOP].

    Each step: mj_step1, the state published (current at its scheduled time), a sleep to the
    step's end, the fingers' wrenches averaged over the servo ticks since the last step into
    xfrc_applied (moved to each body's centre of mass), mj_step2. A step that starts more than
    a step after it was due counts as LATE and the schedule goes on from now: a world that
    cannot keep up runs slower than real time, never in bursts. `sums` (nbody × 2 × 6):
    scratch for the sums read now and at the last step. Returns the steps taken."""
    ctl = ho.ctl
    now_sums, last_sums = sums[:, 0, :], sums[:, 1, :]
    last_count = _read_sums(ho, moving, last_sums)
    k = 0
    while ctl[STOP] == 0:
        due = start_ns + k * period_ns
        t0 = monotonic_ns()
        if t0 > due + period_ns:  # more than a step behind: go on from now, slower than real time
            ctl[LATE] += 1
            start_ns = t0 - k * period_ns
            due = t0
        mj_step1(m, d)
        publish(ho, state, due)
        cost = monotonic_ns() - t0
        end = due + period_ns
        sleep_until_ns(end)
        count = _read_sums(ho, moving, now_sums)
        n = count - last_count
        scale = 1.0 / n if n > 0 else 0.0
        for b in moving:
            fx = (now_sums[b, 0] - last_sums[b, 0]) * scale
            fy = (now_sums[b, 1] - last_sums[b, 1]) * scale
            fz = (now_sums[b, 2] - last_sums[b, 2]) * scale
            mx = (now_sums[b, 3] - last_sums[b, 3]) * scale
            my = (now_sums[b, 4] - last_sums[b, 4]) * scale
            mz = (now_sums[b, 5] - last_sums[b, 5]) * scale
            cx, cy, cz = state.xipos[b, 0], state.xipos[b, 1], state.xipos[b, 2]
            xfrc[b, 0], xfrc[b, 1], xfrc[b, 2] = fx, fy, fz
            xfrc[b, 3] = mx - (cy * fz - cz * fy)
            xfrc[b, 4] = my - (cz * fx - cx * fz)
            xfrc[b, 5] = mz - (cx * fy - cy * fx)
            for j in range(6):
                last_sums[b, j] = now_sums[b, j]
        last_count = count
        t1 = monotonic_ns()
        mj_step2(m, d)
        cost += monotonic_ns() - t1
        ctl[COST_NS] = cost
        if cost > ctl[MAX_COST_NS]:
            ctl[MAX_COST_NS] = cost
        ctl[STEPS] += 1
        k += 1
    return k
