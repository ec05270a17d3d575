"""Where each number of the engine lives: record dtypes for shapes and fingers, columns of the mesh tables.

The engine keeps every shape and every finger as records of numpy arrays (named, typed
fields; a vector is a sub-array, `("pos", f8, 3)`), so that one compiled call runs the
fingers of a tick with no Python objects, and the Python classes users see
(`SoftFingerProxy`, `GodObject`, `TorsionalFriction`, the shapes) are views onto those
records: nothing to copy back and forth. As MuJoCo keeps mjModel apart from mjData, a
finger is two records: its model (`FINGER_MODEL`, what a run holds constant: radius,
friction, stiffness, clamps, the torsion law) and its data (`FINGER_DATA`, what a tick
changes); the kernels name them `fm` and `fd`. Poses are read straight from
MuJoCo's `geom_xpos` (ngeom × 3) and `geom_xmat` (ngeom × 9, row-major: r00 r01 r02 r10 … r22).
A mesh's triangles and grid are flat float tables (T, C) with named column offsets.
"""

from collections import namedtuple

import numpy as np

# -- what the kernels take: five bundles of arrays, built once per loop (or per shape set) ----
MjViews = namedtuple("MjViews", "m d qvel qacc xfrc xipos mass")
"""MuJoCo as the tick's coupling reads and writes it: the mjModel and mjData addresses (for
mj_step1/2 and the body response) and views of mjData: qvel, qacc, xfrc_applied (nbody × 6,
N and N·m), xipos (nbody × 3, m); and its mass matrix by tree (`MassMatrix`). Every array a
kernel takes costs a reference count in and out of each call, so the tick's bundles hold
few: the local model of two rates (`Carried`) is an argument of its own, None with one rate."""
MassMatrix = namedtuple("MassMatrix", "qLD qLDiagInv rownnz rowadr colind dof_index")
"""M's factorisation (the addresses of an mjData's qLD, qLDiagInv) and sparsity (of an
mjModel's M_rownnz, M_rowadr, M_colind), and the address of 0..nv-1 as int32 (the dofs a
solve over one tree lists): `body_response.response_in_tree`. Addresses only, no array (each
body's tree's dofs are in the coupling's workspace, `coupling.workspace`): `MjViews` goes
down every call of the tick."""
Carried = namedtuple("Carried", "d_xpos d_xmat d_cvel d_qvel d_qacc xipos ximat subtree_com body_rootid moving "
                                "mover_geom mover_body mover_rbound "
                                "geom_xpos geom_xmat cvel snap_xpos snap_xmat body_com body_xmat body_vel body_err "
                                "body_off body_spin body_bound body_near touched qvel0 qvel dqvel qacc_free scratch handoff")
"""The local model the haptic ticks render against between MuJoCo's steps (two rates;
`softproxy.compiled.carry`): views of mjData (geom_xpos, geom_xmat, cvel, qvel, qacc, xipos,
ximat, subtree_com) and mjModel (body_rootid); the bodies that can move, and the shapes
(their geom, body and bounding radius, m); the carried
geom_xpos (ngeom × 3, m), geom_xmat (ngeom × 9) and cvel (nbody × 6) the haptic side's
`Shapes` read; the poses of MuJoCo's last state (snap_xpos, snap_xmat; per body its centre of
mass, orientation, velocity (ω, v at the centre of mass), the offset fading over the step,
the fingers' carried change (integral, rate), how far it may get within the fade (m, rad),
whether a shape of it was carried and whether a finger touched it); the local
generalised velocity (qvel0 at the last state, qvel now, dqvel the fingers' part, nv) and
the acceleration held over the step (qacc_free); 9 floats of scratch; the `Handoff` to a
MuJoCo thread (two rates in a real-time run)."""
MjArrays = namedtuple("MjArrays", "xpos xmat cvel xipos ximat subtree_com qvel qacc cdof qLD qLDiagInv")
"""The part of an mjData the servo side reads of MuJoCo's state with two rates in two threads:
geom_xpos, geom_xmat, cvel, xipos, ximat, subtree_com, qvel, qacc (for the local model), cdof,
qLD, qLDiagInv (what mj_jac and mj_solveM read, for the implicit coupling)."""
Handoff = namedtuple("Handoff", "seq stamp pub mirror wseq wsum wcount ctl")
"""MuJoCo's thread and the servo thread (`softproxy.compiled.handoff`): the published state's
seqlock counter and stamp (CLOCK_MONOTONIC ns), the published `MjArrays` and the servo side's
mirror of them (views of its own mjData), the wrench sums' seqlock, sums (nbody × 6, about the
world origin) and tick count, and the control slots (`handoff.STOP`…)."""
Shapes = namedtuple("Shapes", "S T C xpos xmat cvel")
"""The shapes as every query reads them (`sh` in the kernels): their SHAPE records, the mesh
triangle table T and the mesh grids C (None in a world without meshes), and their poses,
views of mjData: geom_xpos (ngeom × 3, m), geom_xmat (ngeom × 9), cvel (nbody × 6: the
touched body's spin drags the torsion). `softproxy.geometry.ShapeSet.tables` holds one."""
Fingers = namedtuple("Fingers", "model data near scratch")
"""A table of fingers as the kernels take it (`fg`): their FINGER_MODEL and FINGER_DATA records,
each one's near shapes (rows of the shape table) and the god-object's scratch.
`softproxy.finger_rows.FingerRows.tables` holds one."""
FingerTables = namedtuple("FingerTables", "rows device_of wrench bodies counts ws")
"""The fingers as a loop's tick takes them: their table (`rows`, a `Fingers`), the device sample
row each reads, the body wrenches with their body lists and counts, and the implicit
coupling's workspace (`softproxy.compiled.coupling`)."""
DeviceIO = namedtuple("DeviceIO", "io samples samples_at limits")
"""A compiled device: the address of its state, its SAMPLE rows (and their address), its
[max_force (N), max_torque (N·m)], read every tick."""
StatRings = namedtuple("StatRings", "durations periods counters")
"""The tick statistics' ring buffers (s) and counters [count, misses] (`softproxy.servo.TickStats`)."""

GEOM_PLANE = 0
GEOM_SPHERE = 2
GEOM_CAPSULE = 3
GEOM_ELLIPSOID = 4
GEOM_CYLINDER = 5
GEOM_BOX = 6
GEOM_MESH = 7
"""MuJoCo's geom types (mjtGeom) a shape can have."""

KEPT_POINT, KEPT_DISTANCE, KEPT_NORMAL, KEPT_ROW = 0, 3, 4, 7
KEPT_WIDTH = 8
"""Columns of a kept query: the point (3, from KEPT_POINT), the distance, the normal (3, from
KEPT_NORMAL), the row of T of its nearest point."""
HINT_SLOTS = 16
"""Hint slots per mesh shape in SHAPE["key"]: the queries of each finger on one mesh keep to
their own (`softproxy.compiled.mesh._slot`), two a finger (its proxy's and its frictionless
proxy's)."""
SLOT_HINT, SLOT_AGE, SLOT_KEPT = 3, 4, 5
"""A slot's columns: the point of its last query (3, m, geom frame), the row of T that query
ended on, when it was used (a count), then its last two kept queries (KEPT_WIDTH each)."""
SLOT_WIDTH = SLOT_KEPT + 2 * KEPT_WIDTH

# -- shape table: one record per Shape, in the order of World.shapes --------------------------
SHAPE = np.dtype([
    ("type", np.int64),       # MuJoCo geom type (mjtGeom): plane 0, sphere 2, capsule 3, ellipsoid 4, cylinder 5, box 6, mesh 7
    ("geom", np.int64),       # geom id (row of geom_xpos / geom_xmat)
    ("body", np.int64),       # body id
    ("static", np.bool_),     # the shape never moves
    ("convex", np.bool_),     # every primitive; not a mesh
    ("planar", np.bool_),     # plane and box: every face flat
    ("rbound", np.float64),   # bounding radius (m), inf for a plane
    ("geom_size", np.float64, 3),  # MuJoCo's geom_size row (m): sphere radius; capsule and cylinder radius,
                                   # half-length; box half-sizes; ellipsoid semi-axes
    # a mesh: where its triangles and its box tree live in the mesh tables T and C
    # (`softproxy.compiled.mesh`), the tree in the geom frame; then what its queries keep
    ("t0", np.int64),         # its first row of T
    ("nt", np.int64),         # its number of triangles
    ("tree", np.int64),       # where its box tree begins in C (TREE_SIZE, TREE_RECORDS, then the nodes)
    ("signed", np.bool_),     # watertight: signed distance; open: unsigned
    ("shading", np.bool_),    # force shading (interpolated vertex normals)
    ("hint", np.int64),       # row of T nearest the last distance query or touched last, -1 for none
    ("feature", np.int64),    # row of T of the last answer: a distance's nearest point, a sweep's touch (-1: none)
    # its hint slots: per slot the last query's point and hint and the last two distance
    # queries kept, newest first: the point (geom frame, m; NaN for none), signed distance
    # (m), outward normal (geom frame), the row of T of the nearest point
    ("key", np.float64, (HINT_SLOTS, SLOT_WIDTH)),
    ("verts", np.int64),      # where its vertex records begin in C (VERTEX_WIDTH floats per vertex)
    ("patch", np.int64),      # where its patches begin in C: one per hint slot, PATCH_WIDTH floats each (-1: none)
    ("kept", np.float64),     # the reach (m) its kept certificates were built over (`MeshShape.prepare`)
    ("ball", np.float64),     # the radius (m) of its ball certificates' resting ball (0: none)
    # its material (`softproxy.material`; `softproxy.compiled.material` renders it): what a
    # finger feels on it beyond the finger's own coupling and friction
    ("material", np.bool_),   # anything below differs from the finger's own (False: none read)
    ("stiffness", np.float64),  # the surface's spring (N/m; inf: the finger's); the softer one renders
    ("damping", np.float64),  # the surface's damper (N·s/m; inf: the finger's); the lesser one renders
    ("friction", np.float64, 2),  # the pair's static and dynamic coefficients (NaN: the finger's × friction_scale)
    ("friction_scale", np.float64),  # the geom's MJCF friction: the finger's coefficients times it
    ("torsion", np.float64),  # the torsional limit's factor over the finger's law scaled with friction (1)
    ("viscosity", np.float64),  # a damper on the finger's motion relative to the surface, in contact (N·s/m)
    ("vibration", np.float64, 2),  # frequency (Hz) and amplitude (N) along the normal, in contact
    ("magnet", np.float64, 2),  # the pull at the surface (N) and the distance it reaches (m)
    ("stick_slip", np.float64, 2),  # the anchor spring's break force (N) and stiffness (N/m), in contact
    ("texture", np.float64, 6),  # a grating in the geom frame: unit axis (3), period (m), height (m),
                                 # friction modulation (the cone's μ × (1 + m sin))
    ("popthrough", np.float64),  # a finger pressing harder than this (N) passes through (0: never)
], align=True)
"""A shape's record; `shape_tables` fills one per shape. Poses are read from MuJoCo."""

FACE = 0
EDGE_AB, EDGE_BC, EDGE_CA = 1, 2, 3
VERTEX_A, VERTEX_B, VERTEX_C = 4, 5, 6
"""A triangle's features, the codes a nearest point or a touch reports: its face, its edges
(edge e = EDGE_AB + e, e = 0, 1, 2) and its vertices (vertex v = VERTEX_A + v); the order of
its pseudo-normals in T (T_PSEUDO + 3 × feature)."""

PLANE_NORMAL, PLANE_OFFSET, PLANE_SHAPE, PLANE_ROW = 0, 3, 4, 5
PLANE_WIDTH = 6
"""A constraint plane, a row of a finger's `planes`: unit normal (nx, ny, nz from
PLANE_NORMAL), offset c (m; the plane is n·x = c), the shape row it belongs to (PLANE_SHAPE),
and on a mesh the row of T of the triangle it came from (PLANE_ROW; -1: none or not known).
`softproxy.compiled.godobject` reads and writes them through `plane`, `normal`, `along` and
`set_plane`."""

# -- mesh triangle table T: one row per triangle, geom frame (softproxy.compiled.mesh) -------
# the first 22 columns are the triangle as `softproxy.mesh.MeshShape` builds it: A, B, C, AB, AC, unit normal N,
# AB·AB, AB·AC, AC·AC, 1 / (AB·AB AC·AC - (AB·AC)²)
T_A, T_B, T_C, T_AB, T_AC, T_N = 0, 3, 6, 9, 12, 15
T_AA, T_ABAC, T_CC, T_INV = 18, 19, 20, 21
T_EDGES = 22     # edges AB, BC, CA: 3 × (start, unit direction, length), columns 22..42
EDGE_WIDTH = 7
T_PSEUDO = 43    # pseudo-normals of the features: face, edges AB BC CA, vertices A B C (3 each), 43..63
T_VN = 64        # vertex normals at A, B, C for force shading, 64..72
# the kept certificates' per-triangle part (softproxy.compiled.certificate)
T_ADJ = 73       # the rows across edges AB, BC, CA (-1: an open edge), 73..75
T_TV = 76        # its vertices A, B, C (vertex ids of its mesh), 76..78
T_CLEAR = 79     # per side (front, back): where its list of triangles rising above its plane
                 # starts in C and how many (-1: a concave patch, no certificate), 79..82
T_BALL = 83      # per side (front, back): where its ball list starts in C and how many (-1: none;
                 # softproxy.mesh_balls: the plane list where that holds), 83..86
T_COLUMNS = 87

# -- mesh grids C: one float64 array (indices stored as floats, exact below 2**53) ----------
C_STAMP = 0
"""C[0]: the number of the last scan; C[C_STAMPS + row of T]: the scan that last read that
triangle (a sweep's scan reads the hint first and skips it in the tree);
C[C_FEW:C_STAMPS]: the triangles a certificate leaves to read (scratch, one query's).
Then per mesh its box tree (`softproxy.compiled.mesh`): from C[S.tree] the number of leaves
(a power of two, TREE_SIZE) and where its records begin (TREE_RECORDS), then its nodes,
NODE_WIDTH floats each (node j of 1 .. 2 size - 1 at TREE_NODES + NODE_WIDTH (j - 1); node
j's children 2j and 2j + 1, leaf j node size + j holding the records of the LEAF
(`softproxy.compiled.certificate`) triangles from j LEAF on), then its records, RECORD_WIDTH floats per triangle in
the tree's order: the triangle's plane (nx, ny, nz, offset), the rectangle in that plane
that holds it (centre, unit axis along its longest edge, half-length along that axis and
half-width across it; m) and its row of T, so that a leaf's bounds are read in one
sequential pass and only the triangles they cannot rule out are opened. A rectangle, not a
ball: a CAD sliver 7 mm long and 50 µm wide is as wide as its ball only along itself."""
RECORD_WIDTH = 13
R_CENTRE, R_ROW = 4, 12  # the rectangle (centre, axis, half-length, half-width) from 4; the row
TREE_SIZE, TREE_RECORDS, TREE_NODES = 0, 1, 2
# a node: its axis-aligned box (lower, upper corner; m), the three axes of its oriented box
# (the first triangle's normal, its longest edge, their cross product) and its extents
# along each (lower, upper; m); an empty node's boxes are inverted (+inf..-inf)
N_LO, N_HI, N_AXES, N_EXT = 0, 3, 6, 15
NODE_WIDTH = 21
C_FEW = 1
FEW_SLOTS = 16   # two faces' lists at an edge, STATIC_ABOVE (softproxy.compiled.certificate) each
C_STAMPS = C_FEW + FEW_SLOTS
# a mesh's vertex records in C (softproxy.compiled.certificate), from C[S_VERTS]:
V_X = 0          # the vertex (m, geom frame), 0..2
V_AXIS = 3       # its cone: axis (unit), cosine (2.0: no cone), 3..6
V_COS = 6
V_RING = 7       # where its ring starts in C and how many: per edge leaving it (vector (m), a row of T on it)
V_FAN = 9        # where its fan starts and how many: the rows of T around it
V_SINES = 11     # where its sin β table starts and how many: (sin β ascending, vertex id)
V_THRESHOLD = 13  # 1 - (least sin β - margin)² (2.0: nothing certified by angle alone)
VERTEX_WIDTH = 14

# a patch (one per hint slot of a mesh shape, from C[S.patch + PATCH_WIDTH slot]): a capsule
# (its segment's ends (2 × 3, geom frame), radius; m) and how many records it holds; a
# capsule found too full (ends, radius, and the shortest segment and least radius of the
# queries found too full in it; m; and 1 once a patch for a finger held still in it was
# found too full too), where the box tree serves the queries, and the cut of
# the tree the walks inside it start from (how many nodes, then their numbers); then a
# lower bound on each record's distance from the first capsule's segment (m², ascending)
# and copies of the tree records of every triangle within that capsule, nearest first, so a
# query inside it reads those that may lie within its own capsule in one pass
P_END, P_RADIUS, P_COUNT, P_FULL, P_CUT = 3, 6, 7, 8, 18
CUT_NODES = 32
P_KEYS = P_CUT + 1 + CUT_NODES
PATCH_RECORDS = 128
P_RECORDS = P_KEYS + PATCH_RECORDS
PATCH_WIDTH = P_RECORDS + PATCH_RECORDS * RECORD_WIDTH

# -- a finger: its model (what a run holds constant) and its data (what a tick changes) ------
FINGER_MODEL = np.dtype([
    ("radius", np.float64),                 # proxy radius (m)
    ("mu_s", np.float64), ("mu_d", np.float64),  # the god-object's friction cone, static and dynamic
    ("slide_restick", np.float64),          # a slide re-sticks after this long still (s); 0: per tick
    ("stiffness", np.float64),              # k, the coupling spring (N/m)
    ("damping", np.float64),                # b, the coupling damper (N·s/m)
    ("max_force", np.float64), ("max_torque", np.float64),  # the finger's clamps (N, N·m)
    ("origin", np.float64, 3),              # device to world: world = origin + scale × device (m)
    ("scale", np.float64),
    ("max_speed", np.float64),              # the spike filter's speed (m/s)
    ("soft_start", np.float64),             # s for the clamps to ramp up after placement
    ("magnets", np.bool_),                  # a shape of its world pulls it (a material's magnet)
    # torsion (`softproxy.torsion.TorsionalFriction`): the fingertip law, eqs 26-27 and 38-40
    ("has_torsion", np.bool_),              # a soft finger; False: a point contact
    ("torsion_stiffness", np.float64),      # k_τ (N·m/rad)
    ("torsion_damping", np.float64),        # b_τ (N·m·s/rad)
    ("torsion_mu_s", np.float64), ("torsion_mu_d", np.float64), ("gamma", np.float64),
    ("saturate", np.bool_),                 # the limit follows eq 26 above P*
    ("ratio", np.float64),                  # μ_d / μ_s
    ("mu_prime", np.float64), ("r0", np.float64), ("p_star", np.float64),  # the model's law (eqs 26-27)
    ("torsion_restick", np.float64),        # a twist slip re-sticks after this long still (s); 0: per tick
], align=True)
"""A finger's model: its parameters, set when it is built (`SoftFingerProxy`, `GodObject`,
`TorsionalFriction`) and read by every tick. `fm` in the kernels."""

FINGER_DATA = np.dtype([
    # the god-object (`softproxy.proxy.GodObject` is its view)
    ("pos", np.float64, 3),                 # proxy centre (m, world)
    ("contact", np.bool_),
    ("normal", np.float64, 3),              # contact normal, unit, out of the object
    ("touched", np.int64),                  # touched shape (row of the shape table) or -1
    ("depth", np.float64),                  # how far the device is inside the constraint (m)
    ("sticking", np.bool_),
    ("local", np.float64, 3),               # the proxy in the touched geom's frame (m)
    ("ball", np.float64, 3), ("ball_room", np.float64),  # the broad phase's ball: centre, room (m)
    ("rounding", np.bool_),                 # the last solve followed a surface round
    ("nplanes", np.int64),
    ("planes", np.float64, (3, PLANE_WIDTH)),  # constraint planes (PLANE_NORMAL, PLANE_OFFSET, …)
    ("free_pos", np.float64, 3),            # last tick's frictionless proxy (m)
    ("nfree", np.int64),
    ("free_planes", np.float64, (3, PLANE_WIDTH)),  # the planes it rested on
    # the friction cone's slip state (sticking False while in contact: slipping, dynamic cone)
    ("slide_dir", np.float64, 3),           # unit offset of the last slide
    ("slide_idle", np.float64),             # s since it last slid RESTICK_TRAVEL of its offset
    ("slide_travel", np.float64),           # m slid since then
    ("nnear", np.int64),                    # how many shape rows `near` holds
    ("squeezed", np.bool_),                 # caught between a moving and a static shape
    ("squeeze_ticks", np.int64),            # ticks it was
    # the coupling (`softproxy.finger.SoftFingerProxy`)
    ("placed", np.bool_),
    ("dt", np.float64),                     # the last tick's period (s)
    ("ramp", np.float64),                   # soft start: fraction of the clamps in force
    ("device_pos", np.float64, 3),          # the device (m, world)
    ("twist_prev", np.float64),             # last tick's device twist (rad), for the damper
    ("body_turn", np.float64),              # the touched body's turn about n this tick (rad)
    ("force", np.float64, 3),               # F on the finger (N, world)
    ("torque_n", np.float64),               # M about n (N·m)
    ("torque", np.float64, 3),              # M·n (N·m, world)
    ("contact_pos", np.float64, 3),         # contact point on the object (m)
    ("body", np.int64),                     # touched body or -1
    ("push_body", np.int64),                # the body it pushed last tick, or -1
    ("normal_force", np.float64),           # P = F·n (N)
    ("valid", np.bool_),                    # this tick's sample was used
    # what the device is sent this tick (clamped to the device, zero when not valid or safe)
    ("sent_force", np.float64, 3), ("sent_torque", np.float64, 3),  # N, N·m
    ("max_force_seen", np.float64), ("penetration_max", np.float64),
    # the coupling's passivity (`softproxy.compiled.passivity`)
    ("rel_move", np.float64, 3),            # Δx_b - Δx_d over the last tick (m)
    ("rel_turn", np.float64),               # Δθ_b - Δα_s over the last tick (rad)
    ("energy", np.float64),                 # the observer E (J; < 0: energy owed)
    ("energy_in", np.float64), ("energy_min", np.float64),  # all the coupling took in; E's lowest (J)
    ("pc_energy", np.float64), ("pc_ticks", np.int64),  # the controller: planned dissipation (J), ticks
    ("slide_events", np.int64), ("spikes_rejected", np.int64), ("spike_run", np.int64),
    ("was_sticking", np.bool_),
    # torsion (`softproxy.torsion.TorsionalFriction` is its view)
    ("in_contact", np.bool_),
    ("alpha_0", np.float64), ("alpha_p", np.float64), ("alpha_g", np.float64),  # rad
    ("spring_torque", np.float64),          # k_τ(α_p - α_g) (N·m)
    ("limit", np.float64),                  # the static limit this tick (N·m)
    ("slipping", np.bool_),
    ("slip_dir", np.float64),               # sign of α_p - α_g while slipping
    ("slip_idle", np.float64),              # s since it last slid RESTICK_TRAVEL of its offset
    ("slip_travel", np.float64),            # rad slid since then
    ("slip_events", np.int64),
    # this tick's device sample (DeviceSample's fields), written by the engine before the tick
    ("in_pos", np.float64, 3), ("in_twist", np.float64),  # device frame (m, rad)
    ("in_quat", np.float64, 4),             # w, x, y, z
    ("in_valid", np.bool_),
    # the touched shape's material as this contact renders it (`softproxy.compiled.material`)
    ("contact_stiffness", np.float64),      # k (N/m): the finger's, or the surface's where softer
    ("contact_damping", np.float64),        # b (N·s/m)
    ("contact_viscosity", np.float64),      # η (N·s/m): the surface's viscosity, a damper in every direction
    ("contact_friction", np.float64, 2),    # μ_s, μ_d of the friction cone
    ("contact_torsion", np.float64),        # the torsional limit's factor over the finger's law
    ("texture_force", np.float64, 3),       # a texture's lateral force this tick (N, world): the hand's alone
    ("texture_sent", np.float64, 3),        # the part of the last sent force the body did not get (N, world)
    ("surface_move", np.float64, 3),        # the touched surface's move under the proxy over the last tick (m)
    ("vibration_phase", np.float64),        # rad, while in contact with a vibrating surface
    ("anchor", np.float64, 3),              # the stick-slip anchor (m, the touched geom's frame)
    ("anchored", np.bool_),
    ("effect_force", np.float64, 3),        # the magnets' pull this tick (N, world)
    ("popped", np.int64),                   # the shape row it popped through and is still inside (-1: none)
    ("field_energy", np.float64),           # what the magnets' fields gave the hand to get here, and take back leaving (J)
], align=True)
"""A finger's data: its god-object, coupling, torsion, counters and this tick's sample, which
every tick reads and writes. `fd` in the kernels."""
