"""The compiled scene: flat arrays and integer type codes.

`Model` is what the compiler produces and what every later stage reads.  It
follows MuJoCo's ``mjModel``: counts ``n<obj>``, per-object arrays
``<obj>_<field>`` with their shapes in comments, ``-1`` for "none" (ground).
Names stay here on the Python side; the numba kernels only see
`KernelModel`, a named tuple of contiguous float64 / int64 arrays.

Coordinates (Nikravesh): body ``b`` owns ``q[3b:3b+3] = (x, y, phi)`` of its
centre of mass; ground has no coordinates.  A point of a body is given in the
body frame (origin at the centre of mass).  Each ideal joint owns
``JOINT_ROWS[type]`` consecutive constraint rows, each driver one;
``joint_row`` / ``driver_row`` hold the first row.  The elements are placed in
the fill-reducing order of `planar_mbs.mechanism.ordering`, not in the order of the text.

Sign conventions shared by kernels, signals and tests:

* equations of motion ``M q'' + Cq^T lam = Qe``,
  ``Cq q'' = gamma - 2 alpha C' - beta^2 C`` (Muvengei et al. eq. 2);
* the reaction of an ideal joint is reported on its **second** body:
  ``F = -Cq[rows, body_j]^T lam`` (global frame); when the second body is
  ground, it is minus the reaction on the first body;
* a clearance joint's first body holds the bearing, the second the journal;
  its ``fx, fy`` are the contact force on the journal (Muvengei et al. eqs. 13–16).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum
from typing import NamedTuple

import numpy as np

from .. import catalog


# Ideal joints, contact laws and integrators are described once in `catalog`; the enums and
# tables below are derived from it (a new one is a formula in the kernel plus its description).
JointType = IntEnum("JointType", {s.enum: s.code for s in catalog.JOINTS}, module=__name__)
JointType.__doc__ = "Ideal joints (catalog.JOINTS: rows and equations, P = r + A s)."
JOINT_ROWS = np.array([s.rows for s in catalog.JOINTS], dtype=np.int64)
JOINT_NAMES = {JointType(s.code): s.name for s in catalog.JOINTS}

# joint_param columns: one per column name of the joint types' settings (catalog.JointSetting), in order
# of first use; a kernel formula reads its setting as km.joint_param[j, JP[name]]
JP = {name: i for i, name in enumerate(catalog.joint_param_columns())}
JP_PHI0 = JP["phi0"]  # relative angle phi_j - phi_i kept by translational and weld joints
JP_LENGTH = JP["length"]  # link length L of a revolute-revolute joint
JP_FRICTION = JP["friction"]  # joint friction (catalog.JointSpec.friction): mu_k, mu_s, pin radius, block length
JP_STATIC_FRICTION = JP["static_friction"]
JP_PIN_RADIUS = JP["pin_radius"]
JP_BLOCK_LENGTH = JP["block_length"]
N_JOINT_PARAM = len(JP)


DriverType = IntEnum("DriverType", {s.enum: s.code for s in catalog.DRIVERS}, module=__name__)
DriverType.__doc__ = "Drivers add one row g(q) - f(t) = 0 (catalog.DRIVERS)."
MotionType = IntEnum("MotionType", {s.enum: s.code for s in catalog.MOTIONS}, module=__name__)
MotionType.__doc__ = "Prescribed motions f(t) of a driver, parameters in driver_motion_param (catalog.MOTIONS)."
N_MOTION_PARAM = catalog.N_MOTION_PARAM


ContactLaw = IntEnum("ContactLaw", {s.enum: s.code for s in catalog.LAWS}, module=__name__)
ContactLaw.__doc__ = "Normal contact-force laws of a clearance joint (catalog.LAWS, contact.md)."
FrictionModel = IntEnum("FrictionModel", {s.enum: s.code for s in catalog.FRICTION_MODELS}, module=__name__)
FrictionModel.__doc__ = "Friction models of the contact elements (catalog.FRICTION_MODELS, contact.md)."
CONTACT_LAW_NAMES = {ContactLaw(s.code): s.name for s in catalog.LAWS}

# clearance_param columns
CP_CLEARANCE = 0  # radial clearance c = R_B - R_J  [m]
CP_R_BEARING = 1  # R_B [m]
CP_R_JOURNAL = 2  # R_J [m]
CP_LENGTH = 3  # bearing length L [m]
CP_STIFFNESS = 4  # K of F = K d^n [N/m^n]  (Muvengei et al. eq. 18 unless given)
CP_EXPONENT = 5  # n (1.5 for metals)
CP_RESTITUTION = 6  # c_e
CP_SIGMA_SUM = 7  # sigma_1 + sigma_2, sigma = (1 - nu^2)/E  [1/Pa]
CP_FRICTION = 8  # Coulomb coefficient mu (0 = frictionless)
CP_FRICTION_V0 = 9  # slip speed below which friction is off (Ambrosio's v0) [m/s]
CP_FRICTION_V1 = 10  # slip speed from which full Coulomb friction acts (Ambrosio's v1) [m/s]
CP_KIND = 11  # contact geometry, a PairKind code (catalog.PAIRS)
CP_NX = 12  # outward normal (nx, ny) of the first body's line, in its frame (CIRCLE_ON_LINE)
CP_NY = 13
CP_VISCOSITY = 14  # dynamic viscosity mu of the lubricant [Pa s] (LUBRICATED)
CP_BREAKDOWN = 15  # eccentricity ratio where the film breaks down and dry contact begins (LUBRICATED)
CP_DAMPING = 16  # c of the Kelvin-Voigt law F = K d + c d' [N s/m] (given, or from a restitution)
# the friction model (catalog.FRICTION_MODELS; CP_FRICTION is mu_k, CP_FRICTION_V0/V1 Ambrosio's ramp)
CP_FRICTION_MODEL = 17  # a FrictionModel code
CP_STATIC_FRICTION = 18  # mu_s >= mu_k of the stick models
CP_STICK_STIFFNESS = 19  # k_t of a stuck contact / the normal law's dF/dd
CP_STICK_DAMPING = 20  # damping ratio of a stuck contact's spring-damper
CP_STRIBECK_VELOCITY = 21  # v_s [m/s]
CP_STRIBECK_EXPONENT = 22  # exponent of the Stribeck curve
CP_VISCOUS_FRICTION = 23  # sigma_2 [N s/m]
CP_BRISTLE_STIFFNESS = 24  # LuGre's sigma_0 per unit normal force [1/m]
CP_BRISTLE_DAMPING = 25  # LuGre's sigma_1 per unit normal force [s/m]
CP_STATE = 26  # 1 + index j of the element's own state (LuGre's sigma_0 z at y[2n + j]); 0: none (`Model.nstate`)
N_CLEARANCE_PARAM = 27
# contact geometries of the clearance elements (catalog.PAIRS); R_i = CP_R_BEARING, R_j = CP_R_JOURNAL
PairKind = IntEnum("PairKind", {s.enum: s.code for s in catalog.PAIRS}, module=__name__)
PairKind.__doc__ = "Contact geometries of the clearance and contact elements (catalog.PAIRS)."

# ContactLaw groups (catalog.LAW_GROUPS, contact.md): dissipative laws F = K d^n (1 + chi(ce) d'/d'(-))
# need the impact velocity; the cylindrical laws are implicit in F and use sigma, L and the radii
DISSIPATIVE_LAWS = frozenset(ContactLaw(s.code) for s in catalog.LAWS if s.dissipative)
CYLINDRICAL_LAWS = frozenset(ContactLaw(s.code) for s in catalog.LAWS if s.cylindrical)


ForceType = IntEnum("ForceType", {s.enum: s.code for s in catalog.FORCES}, module=__name__)
ForceType.__doc__ = "Force elements (catalog.FORCES: force_param columns by name, `ForceSpec.param_columns`)."


class ExprOp(IntEnum):
    """Opcodes of the expression programs (`kernel.expressions`): one instruction per row of
    ``expr_code (ninstr, 4) = (op, a, b, c)``; its result is register ``reg[row]`` of the run's
    workspace (`Workspace.xreg`: one register per instruction, written in order: no stack).  a, b, c are earlier rows unless noted."""

    CONST = 0  # expr_const[a]
    TIME = 1  # t
    BODY = 2  # quantity b (BQ_*) of body a
    ADD = 3
    SUB = 4
    MUL = 5
    DIV = 6
    NEG = 7  # -a
    POW = 8  # a ^ expr_const[b] (a constant exponent)
    SIN = 9
    COS = 10
    EXP = 11
    SQRT = 12
    ABS = 13
    ATAN2 = 14  # atan2(a, b)
    LT = 15  # 1.0 if a < b else 0.0; switching function a - b
    LE = 16
    IF = 17  # b if a != 0 else c
    TABLE = 18  # table b at x = a (piecewise cubic, table_info / table_seg)
    LOG = 19
    TAN = 20


BQ_X, BQ_Y, BQ_PHI, BQ_VX, BQ_VY, BQ_OMEGA = range(6)  # ExprOp.BODY quantities


N_FORCE_PARAM = catalog.N_FORCE_PARAM


Integrator = IntEnum("Integrator", {s.enum: s.code for s in catalog.INTEGRATORS}, module=__name__)
Integrator.__doc__ = "Time integrators (catalog.INTEGRATORS)."
INTEGRATOR_NAMES = {Integrator(s.code): s.name for s in catalog.INTEGRATORS}


# cfg: float64 settings array handed to the time loop
CFG_METHOD = 0  # Integrator code
CFG_RTOL = 1
CFG_ATOL = 2
CFG_STEP = 3  # fixed step of RK4; first trial step of adaptive methods (0 = automatic)
CFG_HMIN = 4  # smallest step before STEP_UNDERFLOW
CFG_HMAX = 5  # largest step (0 = output_step)
CFG_OUTPUT_STEP = 6
CFG_ALPHA = 7  # Baumgarte alpha (velocity feedback 2 alpha C')
CFG_BETA = 8  # Baumgarte beta (position feedback beta^2 C)
CFG_PROJECT = 9  # 1 = project q, q' onto the constraints after each accepted step; 0 = never;
# 2 = auto: from the first regularised factor on (a singular position or redundant joints: PROJECT_*)
CFG_MAX_STEPS = 10
CFG_SKIP = 11  # groups of the observation row no stored signal needs (OBS_SKIP_* bits; 0 = the whole row)
CFG_SIZE = 12  # the mechanism's size (m, `Model.size`): the bounds of the constraint check scale with it
CFG_LOST = 13  # relative bound of that check (`lost_bound`): residual / size, velocity residual / speed
N_CFG = 14
PROJECT_OFF, PROJECT_ON, PROJECT_AUTO = 0.0, 1.0, 2.0
# OBS_SKIP_* bits of cfg[CFG_SKIP]: the time loop's `observe` leaves those columns NaN and skips their work.
# Accelerations, joint reactions and driver efforts/powers take a full `accelerations` per row (its Schur
# solve); the constraint errors need the constraint rows; the rest is cheap.  `signals.skip_bits` sets them.
OBS_SKIP_DYNAMICS = 1  # q'' block, joint reactions, driver efforts and powers
OBS_SKIP_CLEARANCE = 2  # the clearance joints' block
OBS_SKIP_ENERGY = 4  # system kinetic and potential energy
OBS_SKIP_ERRORS = 8  # system position and velocity errors
OBS_SKIP_LOADS = 16  # the force elements' values and powers, gravity's power (their works are always kept)


class Status(IntEnum):
    """Integer status codes returned by the time loop; `simulate` turns them into messages."""

    DONE = 0  # reached t_stop
    BUFFER_FULL = 1  # output buffer full: write it out and call again
    STEP_UNDERFLOW = 2
    NONFINITE = 3  # NaN or infinity in the state or its derivative
    SINGULAR = 4  # constraint matrix Cq M^-1 Cq^T not positive definite
    MAX_STEPS = 5
    CONTACT_SOLVE = 6  # an implicit contact law found no force
    BAD_INPUT = 7
    DRIFT = 8  # fixed-step RK4 left the constraints (residual above the documented bound)
    CONSTRAINTS_LOST = 9  # an adaptive run left its constraints beyond the bound scaled to the mechanism
    PASSAGE = 10  # a fixed RK4 step across a singular position that step halving does not confirm
    ABSURD = 11  # an accepted step left every physical bound (ABSURD_STATE); y is that state
    JOINT_FRICTION = 12  # the friction of the ideal joints found no torques (stats[ST_INFO]: the friction joint)


# beyond it (m, m/s, rad/s) no planar mechanism is being simulated (light: 3e8 m/s); angles are not bounded
ABSURD_STATE = 1e9


# contact state of the clearance joints, `contact` (nclearance + njfriction, N_CONTACT_STATE) float64, kept across calls
CT_MODE = 0  # contact mode, an integer code (FREE / TOUCHING) read through kernel.contact.contact_mode
CT_IMPACT_VELOCITY = 1  # delta'(-) of the current contact
CT_LAST_FORCE = 2  # unused (once the warm start of the implicit laws)
# friction of a stick model (catalog.FrictionSpec.stick): its mode, slip direction and stick anchor
CT_FRICTION = 3  # NO_FRICTION_MODE, STICK or SLIP
CT_SLIP_DIRECTION = 4  # sign (+1 / -1) of the slip velocity v_T while slipping
CT_ANCHOR = 5  # 5, 6: the slip coordinates where it stuck (kernel.contact.slip_coordinates)
N_CONTACT_STATE = 7
# a worn bearing (`kernel.wear`): columns past N_CONTACT_STATE, present only in a run that wears
CT_WEAR_NODES = N_CONTACT_STATE  # N, the nodes of the worn profile (0: the circle)
CT_WEAR_TABLE = N_CONTACT_STATE + 1  # N node depths, then N second derivatives of the periodic spline
NO_FRICTION_MODE, STICK, SLIP = 0, 1, 2
# the friction joints' memory (`KernelModel.joint_friction`) follows as rows nclearance + f of `contact`:
# CT_FRICTION its mode (NO_FRICTION_MODE: frictionless), CT_SLIP_DIRECTION, CT_ANCHOR its slip coordinate
# (relative angle or sliding distance) where it stuck
FREE = 0  # free flight: no contact force even if delta > 0
TOUCHING = 1  # in contact: the law's force while delta > 0


# stats: int64 counters kept across calls of the time loop
ST_STEPS = 0
ST_REJECTED = 1
ST_RHS = 2
ST_CONTACT_EVENTS = 3
ST_OUTPUTS = 4
ST_INFO = 5  # status detail: constraint row, clearance joint or body index involved
N_STATS = 8

BP_LENGTH, BP_EA, BP_EI, BP_ETA, BP_RHO_A = range(5)  # beam_param columns (element length)
N_BEAM_PARAM = 5


# ---- the observation row: one definition, written by kernel.loop.observe, read by signals.signal_table.
# Blocks in order (`observation_layout` gives their first columns): q, q', q'' (3 nbody each), joint
# reactions (N_JOINT_SIGNALS per ideal joint), driver efforts, driver powers (one per driver),
# clearance signals (N_CLEARANCE_SIGNALS per clearance joint), force elements (N_FORCE_SIGNALS each),
# driver works (one per driver), friction joints (N_JFRICTION_SIGNALS each), system signals (N_SYSTEM_SIGNALS:
# last, its energies and errors at the end).
JS_FX, JS_FY, JS_MOMENT = 0, 1, 2  # reaction on the joint's second body (moment about its joint point)
N_JOINT_SIGNALS = 3
CS_EX, CS_EY, CS_E, CS_PENETRATION, CS_FN, CS_FX, CS_FY = 0, 1, 2, 3, 4, 5, 6
CS_IN_CONTACT, CS_IMPACT_VELOCITY, CS_FRICTION, CS_SLIP = 7, 8, 9, 10
CS_POINT_X, CS_POINT_Y, CS_FILM_PRESSURE = 11, 12, 13
CS_WORK, CS_DISSIPATED = 14, 15
CS_STICK, CS_FRICTION_POWER = 16, 17  # 1 while stuck (a stick model); F_T v_T
CS_BRISTLE = 18  # LuGre's bristle deflection z (0 for the other models)
# CS_FRICTION: friction force on the journal along t = perp(n) (signed); CS_SLIP: slip velocity v_T;
# CS_POINT_*: the contact point on the second body (global); CS_FILM_PRESSURE: peak film pressure (LUBRICATED);
# CS_WORK: work of the element's contact (and film) forces on both bodies since the start; CS_DISSIPATED:
# the energy it took out, -(CS_WORK + its elastic energy now - at the start)
N_CLEARANCE_SIGNALS = 19
SYS_GRAVITY_POWER, SYS_GRAVITY_WORK, SYS_INPUT_WORK, SYS_DISSIPATED, SYS_BALANCE = 0, 1, 2, 3, 4
SYS_KINETIC, SYS_POTENTIAL, SYS_POSITION_ERROR, SYS_VELOCITY_ERROR = 5, 6, 7, 8
# SYS_INPUT_WORK: work of the loads and drivers less what their potentials store (damping, actuators,
# expressions, drivers); SYS_DISSIPATED: the clearance elements' CS_DISSIPATED summed; SYS_BALANCE:
# T + V - (T + V at the start) - SYS_INPUT_WORK + SYS_DISSIPATED, zero but for the integration's error
N_SYSTEM_SIGNALS = 9
FS_VALUE, FS_POWER, FS_WORK = 0, 3, 4  # a force element's values (catalog.ForceSpec.signals), power, work
N_FORCE_SIGNALS = 5
# a friction joint's block (after the driver works): its friction torque or force on the second body along
# its slip coordinate, the slip rate, the friction power (<= 0), 1 while stuck, the work since the start
JF_FRICTION, JF_RATE, JF_POWER, JF_STICK, JF_WORK = 0, 1, 2, 3, 4
N_JFRICTION_SIGNALS = 5
# indices into `observation_layout`'s tuple
(OB_Q, OB_QD, OB_QDD, OB_JOINT, OB_EFFORT, OB_POWER, OB_CLEARANCE, OB_FORCE, OB_DRIVER_WORK, OB_JFRICTION,
 OB_SYSTEM, OB_SIZE) = range(12)


def observation_layout(nbody, njoint, ndriver, nclearance, nforce, njfriction=0):
    """First column of each block of the observation row, and the row size, as a tuple indexed
    by OB_*.  Plain integer arithmetic: the kernels compile this same function (`kernel.loop`)."""
    q = 0
    qd = q + 3 * nbody
    qdd = qd + 3 * nbody
    joint = qdd + 3 * nbody
    effort = joint + N_JOINT_SIGNALS * njoint
    power = effort + ndriver
    clearance = power + ndriver
    force = clearance + N_CLEARANCE_SIGNALS * nclearance
    dwork = force + N_FORCE_SIGNALS * nforce
    jfriction = dwork + ndriver
    system = jfriction + N_JFRICTION_SIGNALS * njfriction
    return q, qd, qdd, joint, effort, power, clearance, force, dwork, jfriction, system, system + N_SYSTEM_SIGNALS


# ---- work channels: the powers whose integrals the time loop keeps (`kernel.work`), one per force element,
# then gravity, one per driver, one per clearance element, one per friction joint, one per beam (its material
# damping); `work_layout` gives their first indices.
WL_FORCE, WL_GRAVITY, WL_DRIVER, WL_CLEARANCE, WL_JFRICTION, WL_BEAM, WL_SIZE = range(7)


def work_layout(nforce, ndriver, nclearance, njfriction=0, nbeam=0):
    """First work channel of each group, and their count, as a tuple indexed by WL_* (compiled too)."""
    gravity = nforce
    driver = gravity + 1
    clearance = driver + ndriver
    jfriction = clearance + nclearance
    beam = jfriction + njfriction
    return 0, gravity, driver, clearance, jfriction, beam, beam + nbeam


class KernelModel(NamedTuple):
    """Everything the numba kernels read, as contiguous arrays (shapes in comments).  The expression
    and table arrays default to none (a model without `expression` loads or motions)."""

    body_mass: np.ndarray  # (nbody,)
    body_inertia: np.ndarray  # (nbody,)
    minv: np.ndarray  # (3 nbody,) inverse of the diagonal mass matrix
    gravity: np.ndarray  # (2,)
    joint_type: np.ndarray  # (njoint,) JointType
    joint_body: np.ndarray  # (njoint, 2) body ids, -1 = ground
    joint_point: np.ndarray  # (njoint, 2, 2) points in body frames
    joint_axis: np.ndarray  # (njoint, 2) unit axis in the first body's frame
    joint_param: np.ndarray  # (njoint, N_JOINT_PARAM)
    joint_row: np.ndarray  # (njoint,) first constraint row
    driver_type: np.ndarray  # (ndriver,) DriverType
    driver_body: np.ndarray  # (ndriver, 2)  (reference body i, driven body j)
    driver_point: np.ndarray  # (ndriver, 2, 2)
    driver_axis: np.ndarray  # (ndriver, 2) unit axis in body i's frame (POSITION)
    driver_motion: np.ndarray  # (ndriver,) MotionType
    driver_motion_param: np.ndarray  # (ndriver, N_MOTION_PARAM)
    driver_row: np.ndarray  # (ndriver,)
    clearance_body: np.ndarray  # (nclearance, 2) (bearing body i, journal body j)
    clearance_point: np.ndarray  # (nclearance, 2, 2) bearing / journal centres in body frames
    clearance_law: np.ndarray  # (nclearance,) ContactLaw
    clearance_param: np.ndarray  # (nclearance, N_CLEARANCE_PARAM)
    force_type: np.ndarray  # (nforce,) ForceType
    force_body: np.ndarray  # (nforce, 2)
    force_point: np.ndarray  # (nforce, 2, 2)
    force_param: np.ndarray  # (nforce, N_FORCE_PARAM)
    expr_code: np.ndarray = np.zeros((0, 4), dtype=np.int64)  # (ninstr, 4) int: (ExprOp, a, b, c), every program's instructions in turn
    expr_const: np.ndarray = np.zeros(0)  # (nconst,) constants of the programs (SI)
    expr_prog: np.ndarray = np.zeros((0, 2), dtype=np.int64)  # (nprog, 2) int: first and end row of each program (result: row end - 1)
    expr_loads: np.ndarray = np.zeros(2, dtype=np.int64)  # first and end row of the loads' programs (together)
    expr_switch: np.ndarray = np.zeros((0, 2), dtype=np.int64)  # (nswitch, 2) int: comparison row, its program
    table_info: np.ndarray = np.zeros((0, 2), dtype=np.int64)  # (ntable, 2) int: first row in table_seg and the number of knots
    table_period: np.ndarray = np.zeros(0)  # (ntable,) period of a periodic table (0: held at its end values outside)
    table_seg: np.ndarray = np.zeros((0, 5))  # (nknot, 5) knot x_k and y = c0 + c1 d + c2 d^2 + c3 d^3, d = x - x_k
    joint_friction: np.ndarray = np.zeros(0, dtype=np.int64)  # (njfriction,) int: the joints with friction, in order
    # beams (kernel/beam.py): node k of a beam is two massless bodies, its position and its slope (first + 2 k,
    # first + 2 k + 1); none by default
    # (3 nbody,) the inverse mass of the same bodies at the heaviest one's mass, each keeping its radius of gyration
    # (`compile.heaviest_metric`): the geometry's own metric, which tells a mechanism near a loss of rank from one
    # whose masses only make S badly scaled, and regularises S in the geometry's directions (`dynamics.schur_factor`)
    unit_minv: np.ndarray = np.zeros(0)
    beam_info: np.ndarray = np.zeros((0, 4), dtype=np.int64)  # (nbeam, 4) int: first node body, elements, offset in beam_mass and beam_minv, offset in beam_weight
    beam_param: np.ndarray = np.zeros((0, 5))  # (nbeam, BP_*): element length, EA, EI, damping time eta, rho A
    beam_mass: np.ndarray = np.zeros(0)  # every beam's constant mass matrix (nb x nb, nb = 4 (elements + 1)), row by row
    beam_minv: np.ndarray = np.zeros(0)  # its inverse, the same layout
    beam_band: np.ndarray = np.zeros(0)  # the Cholesky factor of its scalar mass (kernel/beam.py BAND per scalar coordinate, offset 2 beam_info[:, 3])
    beam_weight: np.ndarray = np.zeros(0)  # every beam's constant generalised weight (nb each)
    body_beam: np.ndarray = np.zeros(0, dtype=np.int64)  # (nbody,) int: the beam of a node body, -1 for a rigid body (empty without beams)


def read_only(arr: np.ndarray) -> np.ndarray:
    """A view of `arr` that cannot be written (its owner still can)."""
    view = arr.view()
    view.flags.writeable = False
    return view


def frozen(km: KernelModel) -> KernelModel:
    """`km` with every array read-only: a kernel that writes into the model fails to compile (numba
    types such arrays as read-only), and Python writes raise.  Every model a run reads is frozen."""
    return KernelModel(*(read_only(np.asarray(a)) for a in km))


def observation_size(nbody: int, njoint: int, ndriver: int, nclearance: int, nforce: int,
                     njfriction: int = 0) -> int:
    """Columns of one observation row (`observation_layout`)."""
    return observation_layout(nbody, njoint, ndriver, nclearance, nforce, njfriction)[OB_SIZE]


@dataclass(frozen=True)
class SourceRef:
    """Where an element was written, to point back at the user's line."""

    file: str
    line: int
    column: int


def projection_code(value) -> float:
    """cfg[CFG_PROJECT] of a `projection` setting: "on", "off", "auto" (True / False as on / off)."""
    if value is True or value is False:
        return PROJECT_ON if value else PROJECT_OFF
    return {"on": PROJECT_ON, "off": PROJECT_OFF, "auto": PROJECT_AUTO}[str(value)]


LOST_FLOOR = 1e-9  # the constraint check's relative bound is never below this ...
LOST_PER_RTOL = 10.0  # ... and is this many rtol: every shipped model at rtol 1e-3, its own and 1e-8 passes the
# check even at 1 rtol (a run keeps its residuals well below rtol); beyond, the constraints gave way


def lost_bound(rtol: float) -> float:
    """Relative bound of the adaptive methods' constraint check (`kernel.loop.lost_check`): a residual
    beyond it times the mechanism's size (its velocity: times its speed) stops the run."""
    return max(LOST_FLOOR, LOST_PER_RTOL * rtol)


@dataclass
class Settings:
    """The `simulate` block, resolved to SI."""

    t_end: float = 0.1
    integrator: Integrator = Integrator.DOPRI5
    rtol: float = 1e-6
    atol: float = 1e-9
    step: float = 1e-6  # RK4 fixed step; first trial step for adaptive methods
    h_min: float = 1e-14
    h_max: float = 0.0  # 0 = no limit (outputs come from the dense output)
    output_step: float = 1e-4
    alpha: float = 5.0
    beta: float = 5.0
    projection: str = "auto"  # "on", "off" (unchecked: may cross a singular position onto another branch), "auto"
    max_steps: int = 100_000_000

    def cfg(self, size: float = 1.0) -> np.ndarray:
        """The time loop's settings array; `size` is the mechanism's (`Model.size`)."""
        c = np.zeros(N_CFG)
        c[CFG_SIZE] = size
        c[CFG_METHOD] = int(self.integrator)
        c[CFG_RTOL] = self.rtol
        c[CFG_ATOL] = self.atol
        c[CFG_STEP] = self.step
        c[CFG_HMIN] = self.h_min
        c[CFG_HMAX] = self.h_max
        c[CFG_OUTPUT_STEP] = self.output_step
        c[CFG_ALPHA] = self.alpha
        c[CFG_BETA] = self.beta
        c[CFG_PROJECT] = projection_code(self.projection)
        c[CFG_LOST] = lost_bound(self.rtol)
        c[CFG_MAX_STEPS] = self.max_steps
        return c


@dataclass
class Model:
    """The compiled, immutable scene plus the names that map arrays back to signals."""

    kernel: KernelModel
    settings: Settings
    q0: np.ndarray  # (3 nbody,) user's approximate initial pose
    qd0: np.ndarray  # (3 nbody,) user's initial velocities
    body_names: list[str]
    joint_names: list[str]
    driver_names: list[str]
    clearance_names: list[str]
    force_names: list[str]
    body_geometry: list[dict] = field(default_factory=list)  # drawing hints per body
    body_source: list[SourceRef] = field(default_factory=list)
    joint_source: list[SourceRef] = field(default_factory=list)
    driver_source: list[SourceRef] = field(default_factory=list)
    clearance_source: list[SourceRef] = field(default_factory=list)
    parameters: dict[str, str] = field(default_factory=dict)  # resolved params, as text with units
    source_text: str = ""
    source_path: str = ""
    source_key: str = ""  # absolute path of the model file (symlinks kept): the base of source_includes
    source_includes: dict[str, str] = field(default_factory=dict)  # absolute path -> text, every include
    source_tables: dict[str, bytes] = field(default_factory=dict)  # path -> bytes of every table file read
    source_files: list = field(default_factory=list)  # resolved paths of the model file and its includes
    # (nclearance, 4) initial state of each clearance joint as written: journal offset (x, y) and
    # relative velocity (x, y) in the bearing's frame; NaN where not given (kinematics.assemble)
    clearance_start: np.ndarray | None = None
    # per clearance element: how the assembly of the initial pose treats it: ("revolute",) the journal
    # centred (or at its offset) when it closes a loop; ("translational", bi, bj, pi, pj, axis, phi0, name,
    # (offset, tilt, relative_velocity, tilt_rate), NaN where not given) on the first pair of a translational
    # clearance joint (kinematics.slide_joints); ("none",) no rows
    clearance_assembly: list = field(default_factory=list)
    # per revolute clearance joint that wears (`wear = archard(...)`): its wear run's settings in SI,
    # {"model", "coefficient" (k_d = k / H, 1/Pa), "update" (s), "factor", "updates", "nodes"} (run/wear.py)
    clearance_wear: dict = field(default_factory=dict)
    # what the compiler took but warns about (a number without a unit taken in SI), each rendered as
    # `file:line:col: warning: ...` with its line and hint; `mbs check` and `mbs run` print them
    warnings: list = field(default_factory=list)
    beam_names: list = field(default_factory=list)  # the beams (`body NAME = beam`), their node bodies after the rigid ones

    @property
    def nbody(self) -> int:
        return len(self.body_names)

    @property
    def njoint(self) -> int:
        return len(self.joint_names)

    @property
    def ndriver(self) -> int:
        return len(self.driver_names)

    @property
    def nclearance(self) -> int:
        return len(self.clearance_names)

    @property
    def nforce(self) -> int:
        return len(self.force_names)

    @property
    def nstate(self) -> int:
        """States of the contact elements' own (LuGre's bristles, sigma_0 z), after (q, q') in the
        integrated state y = (q, q', z): one per element whose friction model has one."""
        return int(np.count_nonzero(np.asarray(self.kernel.clearance_param)[:, CP_STATE] > 0))

    @property
    def njfriction(self) -> int:
        """Ideal joints with friction (`KernelModel.joint_friction`)."""
        return len(self.kernel.joint_friction)

    @property
    def jfriction_names(self) -> list[str]:
        return [self.joint_names[int(j)] for j in self.kernel.joint_friction]

    @property
    def contact_rows(self) -> int:
        """Rows of a run's contact memory: the clearance elements', then the friction joints'."""
        return self.nclearance + self.njfriction

    @property
    def ncoord(self) -> int:
        """The coordinates: 3 per rigid body, 4 per node of a beam (its two bodies' third slots unused)."""
        return 3 * self.nbody - int(np.sum(np.asarray(self.kernel.body_beam) >= 0))

    @property
    def size(self) -> float:
        """The mechanism's size (m): twice the longest distance from a body's centre of mass to one of
        its joint, driver, clearance or force points (a link's length), else the extent of the initial
        pose.  The bounds of the constraint check scale with it."""
        k = self.kernel
        r = 0.0
        for pts, bodies in ((k.joint_point, k.joint_body), (k.driver_point, k.driver_body),
                            (k.clearance_point, k.clearance_body), (k.force_point, k.force_body)):
            pts = np.asarray(pts, dtype=float).reshape(-1, 2, 2)
            on_body = np.asarray(bodies).reshape(-1, 2) >= 0
            if pts.size and on_body.any():
                r = max(r, 2.0 * float(np.hypot(pts[..., 0], pts[..., 1])[on_body].max()))
        if not r > 0.0 and self.nbody:
            xy = np.asarray(self.q0, dtype=float).reshape(-1, 3)[:, :2]
            r = float(np.hypot(*(xy.max(axis=0) - xy.min(axis=0))))
        return r if r > 0.0 else 1.0

    @property
    def nconstraint(self) -> int:
        k = self.kernel
        return int(JOINT_ROWS[k.joint_type].sum()) + self.ndriver

    @property
    def dof(self) -> int:
        return self.ncoord - self.nconstraint
