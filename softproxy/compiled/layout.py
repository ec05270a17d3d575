"""Where each number lives in the compiled engine's flat arrays (column indices).

The compiled tick (`softproxy.compiled`) keeps every shape and every finger as a row of a
float64 array, so that one numba call can run the fingers of a tick with no Python objects.
Shape table rows come from `softproxy.geometry` shapes; finger rows from `SoftFingerProxy`,
its `GodObject` and its `TorsionalFriction`. Poses are read straight from MuJoCo's
`geom_xpos` (ngeom × 3) and `geom_xmat` (ngeom × 9, row-major: r00 r01 r02 r10 … r22).
"""

# -- shape table: one row per Shape, in the order of World.shapes -------------------------
S_TYPE = 0       # MuJoCo geom type (mjtGeom): plane 0, sphere 2, capsule 3, ellipsoid 4, cylinder 5, box 6, mesh 7
S_GEOM = 1       # geom id (row of geom_xpos / geom_xmat)
S_BODY = 2       # body id
S_STATIC = 3     # 1.0 when the shape never moves
S_CONVEX = 4     # 1.0 for every primitive, 0.0 for a mesh
S_FLAT = 5       # 1.0 for plane and box
S_RBOUND = 6     # bounding radius (m), inf for a plane
S_A = 7          # sphere/capsule/cylinder radius, box hx, ellipsoid a (m)
S_B = 8          # capsule/cylinder half-length, box hy, ellipsoid b (m)
S_C = 9          # box hz, ellipsoid c (m)
# a mesh's row: where its triangles and its grid live in the mesh tables T and C
# (`softproxy.compiled.mesh`), the grid in the geom frame; then what its queries keep
S_T0 = 10        # its first row of T
S_NT = 11        # its number of triangles
S_CELLS = 12     # where its grid's cell starts begin in C (ncells + 1 entries)
S_LOX, S_LOY, S_LOZ = 13, 14, 15   # the grid's lower corner (m, geom frame)
S_H = 16         # cell size (m)
S_DIMX, S_DIMY, S_DIMZ = 17, 18, 19   # cells per axis
S_SIGNED = 20    # 1.0 for a watertight mesh (signed distance), 0.0 for an open one (unsigned)
S_SHADING = 21   # 1.0 for force shading (interpolated vertex normals)
S_HINT = 22      # row of T nearest the last distance query or touched last, -1 for none
S_KEY = 23       # the last two distance queries kept, newest first, KEPT_WIDTH columns each (23..36):
KEPT_WIDTH = 7   # the point (geom frame, m; NaN for none), signed distance (m), outward normal (geom frame)
S_VERTS = 37     # where its vertex records begin in C (VERTEX_WIDTH floats per vertex)
S_KEPT = 38      # the reach (m) its kept certificates were built over (`MeshShape.prepare`)
S_COLUMNS = 39

GEOM_PLANE = 0
GEOM_SPHERE = 2
GEOM_CAPSULE = 3
GEOM_ELLIPSOID = 4
GEOM_CYLINDER = 5
GEOM_BOX = 6
GEOM_MESH = 7

# -- mesh triangle table T: one row per triangle, geom frame (softproxy.compiled.mesh) -------
# the first 22 columns are `softproxy.mesh`'s triangle tuple: A, B, C, AB, AC, unit normal N,
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
T_COLUMNS = 83

# -- mesh grids C: one float64 array (indices stored as floats, exact below 2**53) ----------
C_STAMP = 0
"""C[0]: the number of the last scan; C[C_STAMPS + row of T]: the scan that last read that
triangle (a triangle is listed in every cell its bounding box overlaps, and read once per
scan); C[C_FEW:C_STAMPS]: the triangles a certificate leaves to read (scratch, one query's).
Then per mesh its cell starts (where each cell's records begin in C, ncells + 1 of them) and
its cells' records, RECORD_WIDTH floats each: the triangle's plane (nx, ny, nz, offset), its
bounding ball (centre, radius; m) and its row of T, so that a scan reads a cell's bounds in
one sequential pass and opens only the triangles they cannot rule out."""
RECORD_WIDTH = 9
C_FEW = 1
FEW_SLOTS = 16   # two faces' lists at an edge, STATIC_ABOVE (softproxy.mesh) each
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

# -- finger state: one row per finger -------------------------------------------------------
# god-object (softproxy.proxy.GodObject)
G_X, G_Y, G_Z = 0, 1, 2          # proxy centre (m, world)
G_CONTACT = 3
G_NX, G_NY, G_NZ = 4, 5, 6       # contact normal
G_SHAPE = 7                      # touched shape (row of the shape table) or -1
G_DEPTH = 8
G_STICKING = 9
G_LX, G_LY, G_LZ = 10, 11, 12    # proxy in the touched geom's frame
G_BX, G_BY, G_BZ, G_ROOM = 13, 14, 15, 16   # the broad phase's ball
G_ROUNDING = 17
G_NPLANES = 18
G_PLANES = 19                    # 3 planes × (nx, ny, nz, c, shape row): columns 19..33
PLANE_WIDTH = 5
G_RADIUS = 34
G_MU_S = 35
G_MU_D = 36
G_NNEAR = 37                     # how many shape rows `near` holds
# the finger (softproxy.finger.SoftFingerProxy)
F_PLACED = 40
F_K, F_B, F_B_TAU = 41, 42, 43
F_MAX_FORCE, F_MAX_TORQUE = 44, 45
F_OX, F_OY, F_OZ, F_SCALE = 46, 47, 48, 49
F_MAX_SPEED, F_SOFT_START, F_DT, F_RAMP = 50, 51, 52, 53
F_XD, F_YD, F_ZD = 54, 55, 56
F_SX, F_SY, F_SZ, F_STWIST = 57, 58, 59, 60
F_FX, F_FY, F_FZ = 61, 62, 63
F_TORQUE = 64
F_TX, F_TY, F_TZ = 65, 66, 67
F_PX, F_PY, F_PZ = 68, 69, 70
F_BODY = 71
F_NORMAL_FORCE = 72
F_VALID = 73
# what the device is sent this tick (clamped to the device, zero when not valid or safe)
D_FX, D_FY, D_FZ, D_TX, D_TY, D_TZ = 74, 75, 76, 77, 78, 79
F_MAX_FORCE_SEEN = 80
F_PENETRATION_MAX = 81
F_SLIDE_EVENTS = 82
F_SPIKES_REJECTED = 83
F_SPIKE_RUN = 84
F_WAS_STICKING = 85
F_HAS_TORSION = 86
# torsion (softproxy.torsion.TorsionalFriction)
T_IN_CONTACT = 87
T_ALPHA_0, T_ALPHA_P, T_ALPHA_G = 88, 89, 90
T_TORQUE, T_LIMIT = 91, 92
T_SLIPPING = 93
T_SLIP_EVENTS = 94
T_K_TAU, T_MU_S, T_MU_D, T_GAMMA = 95, 96, 97, 98
T_SATURATE, T_RATIO = 99, 100
T_MU_PRIME, T_R0, T_P_STAR = 101, 102, 103
# this tick's device sample (DeviceSample's fields), written by the engine before the tick
IN_X, IN_Y, IN_Z, IN_TWIST = 104, 105, 106, 107
IN_QW, IN_QX, IN_QY, IN_QZ = 108, 109, 110, 111
IN_VALID = 112                   # 1.0 when the read succeeded and the device marked it valid
F_COLUMNS = 113

# runs of columns written back into the Python objects: OUTPUT_AND_SENT every tick, the rest by sync
OUTPUT_AND_SENT = slice(F_FX, D_TZ + 1)   # one read for the outputs (F_FX..F_VALID) and what is sent
SENT_AT = D_FX - F_FX                     # where what is sent starts in that run
GOD_SEEN = slice(G_X, G_STICKING + 1)
DEVICE_SEEN = slice(F_XD, F_ZD + 1)
COUNTERS_SEEN = slice(F_MAX_FORCE_SEEN, F_SPIKES_REJECTED + 1)
TORSION_SEEN = slice(T_IN_CONTACT, T_SLIP_EVENTS + 1)
