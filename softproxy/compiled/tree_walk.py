"""The one walk of a box tree: which nodes a query reads, in what order, and when it stops.

Every box tree of the engine has one shape: node 1 the root, node j's children 2j and 2j + 1,
node j a leaf when j >= size (its leaf number j - size; a leaf holds LEAF items). The run-time
queries on a mesh's tree (in the float table C, `softproxy.compiled.box_tree`) walk it here,
one walk written once, twice over:

- `depth_first`: a stack, the children's bounds taken when their parent is read and the
  nearer child read first (the distance and sweep queries of `softproxy.compiled.mesh`);
- `best_first`: a heap of the nodes waiting, the least bound read first, so the walk may
  end at the first node beyond what it needs (a patch's gathering in `patch`).

A query is its parts, small @njit functions of (q, s, ...): q the query's constants (a
namedtuple of the arrays and scalars it reads, never reassigned during the walk), s its state
(a tuple of scalars, the best found so far and counters, which `visit` returns anew):
- `bound(q, s, node)`: a lower bound on what the node holds (a squared gap, a sweep's
  entry): nodes are read least first; a node whose bound exceeds `limit(q, s)`, or is
  infinite (an empty node, one the query rules out by another test), is left out;
- `visit(q, s, leaf)`: read leaf number `leaf`, returning the new state;
- `limit(q, s)`: the bound past which nothing can matter (`best_so_far`, the state's first
  entry: it shrinks as the walk finds better; infinite by default);
- `opened(q, s, node)`: a test made when a node is taken up, on the state of that moment
  (a sweep's cull plane); every node by default;
- `done(q, s)`: the walk stops (a patch given up); never by default;
- and per walk: `ties_left` (depth first: on equal bounds the child 2j first, else
  2j + 1), `rebound` (depth first: a node taken up after the limit has shrunk since its
  bound was taken is bounded again: a sweep's entry depends on how far the sweep still
  reaches), `overflow(q, s, bound)` (best first: the state when a node finds the heap full).

Why so. numba folds what it knows when it compiles, and inlines a @njit function it calls
by name; so `depth_first(...)` and `best_first(...)` build, once per query at import, a
@njit walk whose parts are free variables of the closure: compile-time constants, called
directly and inlined into the loop, as if the walk were written out for that query. Two other
ways were measured (a nearest-leaf query over a 65,536-leaf tree, 200k queries): the parts
passed as first-class function arguments to one @njit walk ran 2× slower than the walk written
out, and numba cannot cache a kernel that passes them (a function's address is a dynamic
global); the closure ran as fast as the walk written out (within the machine's noise) and the
kernels calling it are cached. A code constant switching between the queries' parts inside
one walk would make the tree module import every query's module, above it. The walks
themselves are compiled with the kernels that call them and not cached on their own: numba
keys a closure's cache on its cells, and a dispatcher pickles with an id of its process, so
such an entry would never be read again.

The parts are inlined at numba's IR level (inline="always"): every call of a function taking a
tuple of arrays counts a reference to each array (an atomic add, and a subtract after),
which LLVM removes only where both lie in one branch-free stretch. For the same reason the
walks that build the certificates at load (`certificate.face_lists`, `vertex_tables`,
`ball.ball_lists`) stay written out, with this module's LEAF, STACK and heap: their queries
read some twenty arrays, and as parts of these walks they paid ~40 atomic counts a leaf
visit; a chunk of 4096 faces of the 100k-triangle sliver mesh took 0.21 s for its face lists
(0.05 s written out) and 0.55 s for its vertex tables (0.19 s). The run-time queries read
two arrays (T and C) and a few scalars.

Each walk keeps the order the walks written out kept, ties included, so every query finds
the same triangles in the same order as before they were one. `patch._cut` is not a walk:
it takes the tree level by level down to the deepest that CUT_NODES nodes cover.
"""

from __future__ import annotations

import math

import numpy as np

from softproxy.compiled.kernel import kernel


LEAF = 8
"""Items (triangles or vertices) per leaf of a box tree."""
STACK = 256
"""Depth of a depth-first walk's stack (two entries per level: far more than any tree has)."""
FROM_ROOT = np.zeros(0)
"""The `cut` of a walk that starts at the root."""


@kernel(inline="always")
def unlimited(q, s):
    """No limit: every node whose bound is finite is read."""
    return math.inf


@kernel(inline="always")
def best_so_far(q, s):
    """The limit is the state's first entry: the best found so far."""
    return s[0]


@kernel(inline="always")
def always(q, s, node):
    """Every node taken up is opened."""
    return True


@kernel(inline="always")
def never(q, s):
    """The walk runs until no node waits."""
    return False


@kernel(inline="always")
def left_out(q, s, bound):
    """A node with no room in the heap is left out (the state unchanged)."""
    return s


@kernel
def depth_scratch():
    """The scratch of a depth-first walk: node numbers, their bounds, and the limit when each
    bound was taken (STACK each)."""
    return np.empty(STACK, dtype=np.int64), np.empty(STACK), np.empty(STACK)


@kernel
def best_scratch(room):
    """The scratch of a best-first walk: a heap of room nodes (minus their bounds, numbers)."""
    return np.empty(room), np.empty(room, dtype=np.int64)


@kernel
def push_ordered(nodes, keys, top, node, key):
    """Push `node` with `key` onto a walk's stack nodes[:top], keys[:top] kept in descending
    key order, so the least (the nearest, the earliest entered) is read first; returns the
    new top."""
    j = top
    while j > 0 and keys[j - 1] < key:
        nodes[j], keys[j] = nodes[j - 1], keys[j - 1]
        j -= 1
    nodes[j], keys[j] = node, key
    return top + 1


@kernel
def heap_offer(hs, hw, m, keep, s, w):
    """Offer (s, w) to the max-heap (by hs) of hs[:m], hw[:m] of at most `keep` entries: added
    while there is room, else in place of the top when s is below it; returns the new m."""
    if m < keep:
        c = m
        hs[c], hw[c] = s, w
        m += 1
        while c > 0:  # sift up
            parent = (c - 1) // 2
            if hs[parent] >= hs[c]:
                break
            hs[parent], hs[c] = hs[c], hs[parent]
            hw[parent], hw[c] = hw[c], hw[parent]
            c = parent
    elif s < hs[0]:
        hs[0], hw[0] = s, w
        _sift_down(hs, hw, m)
    return m


@kernel
def heap_pop(hs, hw, m):
    """Take the top (the largest hs) off the max-heap hs[:m], hw[:m]: (its hs, its hw, new m)."""
    s, w = hs[0], hw[0]
    m -= 1
    if m > 0:
        hs[0], hw[0] = hs[m], hw[m]
        _sift_down(hs, hw, m)
    return s, w, m


@kernel
def _sift_down(hs, hw, m):
    """Restore the max-heap (by hs) of hs[:m], hw[:m] after its top was replaced."""
    j = 0
    while True:
        c = 2 * j + 1
        if c >= m:
            return
        if c + 1 < m and hs[c + 1] > hs[c]:
            c += 1
        if hs[c] <= hs[j]:
            return
        hs[j], hs[c] = hs[c], hs[j]
        hw[j], hw[c] = hw[c], hw[j]
        j = c


def depth_first(bound, visit, limit=unlimited, opened=always, done=never, ties_left=True, rebound=False):
    """A depth-first walk of a box tree for the query of these parts (module docstring):
    `walk(size, cut, q, s, stack) -> (s, waiting)`, from the nodes of `cut` (C's format: how
    many, then their numbers; FROM_ROOT or any empty array: the root), the nearest on top,
    with a `depth_scratch` stack; `waiting`: how many nodes were left on the stack (0 unless
    `done` stopped it)."""

    @kernel(cache=False)
    def walk(size, cut, q, s, stack):
        nodes, keys, asked = stack
        lim = limit(q, s)
        top = 0
        if len(cut) == 0:
            k = bound(q, s, 1)
            if k <= lim and k < math.inf:
                nodes[0], keys[0] = 1, k
                top = 1
        else:
            for i in range(int(cut[0])):
                node = int(cut[1 + i])
                k = bound(q, s, node)
                if k <= lim and k < math.inf:
                    top = push_ordered(nodes, keys, top, node, k)
        if rebound:
            asked[:top] = lim
        while top > 0:
            if done(q, s):
                break
            top -= 1
            node, key = nodes[top], keys[top]
            lim = limit(q, s)
            if key > lim:
                continue
            if rebound and lim < asked[top] and bound(q, s, node) > lim:
                continue  # the limit shrank since: bounded again, it lies beyond
            if not opened(q, s, node):
                continue
            if node >= size:
                s = visit(q, s, node - size)
                continue
            k0 = bound(q, s, 2 * node)
            k1 = bound(q, s, 2 * node + 1)
            # the nearer child on top of the stack, read first
            if (k0 <= k1) if ties_left else (k0 < k1):
                if k1 <= lim and k1 < math.inf:
                    nodes[top], keys[top] = 2 * node + 1, k1
                    if rebound:
                        asked[top] = lim
                    top += 1
                if k0 <= lim and k0 < math.inf:
                    nodes[top], keys[top] = 2 * node, k0
                    if rebound:
                        asked[top] = lim
                    top += 1
            else:
                if k0 <= lim and k0 < math.inf:
                    nodes[top], keys[top] = 2 * node, k0
                    if rebound:
                        asked[top] = lim
                    top += 1
                if k1 <= lim and k1 < math.inf:
                    nodes[top], keys[top] = 2 * node + 1, k1
                    if rebound:
                        asked[top] = lim
                    top += 1
        return s, top

    return walk


def best_first(bound, visit, limit=unlimited, opened=always, done=never, overflow=left_out):
    """A best-first walk of a box tree for the query of these parts (module docstring):
    `walk(size, cut, q, s, heap) -> (s, waiting)`, from the nodes of `cut` (C's format;
    FROM_ROOT or any empty array: the root), the least bound read first, with a
    `best_scratch(room)` heap of room nodes; it ends at the first node whose bound exceeds
    the limit (every node waiting lies as far). `waiting`: how many nodes were left in the
    heap (0 unless `done` stopped it or it ended at that node)."""

    @kernel(cache=False)
    def walk(size, cut, q, s, heap):
        hs, hw = heap
        room = len(hs)
        lim = limit(q, s)
        w = 0
        if len(cut) == 0:
            k = bound(q, s, 1)
            if k <= lim and k < math.inf:
                w = heap_offer(hs, hw, w, room, -k, 1)
        else:
            for i in range(int(cut[0])):
                node = int(cut[1 + i])
                k = bound(q, s, node)
                if k <= lim and k < math.inf:
                    w = heap_offer(hs, hw, w, room, -k, node)
        while w > 0:
            if done(q, s):
                break
            key, node, w = heap_pop(hs, hw, w)
            if -key > limit(q, s):
                break
            if not opened(q, s, node):
                continue
            if node >= size:
                s = visit(q, s, node - size)
                continue
            for child in range(2 * node, 2 * node + 2):
                k = bound(q, s, child)
                if not (k <= limit(q, s) and k < math.inf):
                    continue
                if w == room:
                    s = overflow(q, s, k)
                    continue
                w = heap_offer(hs, hw, w, room, -k, child)
        return s, w

    return walk
