"""Physics of the gravity compensator for an RP arm (Demian and Klimchik 2022).

Pure model, standard library only: no FMI and no I/O. It is shared by the FMU slave
`PrismaticCompensator`, the harness and the tests. Conventions of docs/conventions.md: q1 is
the angle of link 1 from the horizontal, counter-clockwise positive, u = (cos q1, sin q1);
q2 is the travel of the prismatic joint along the link; gravity along -y; pivot O at the origin.

Potential energy, with lc2 = ls0 + q2, e = b + q* = b + rho q2 and S = max(sin q1, 0):

    E_grav = (m1 lc1 + m2 lc2) g sin q1
    E_k1 = 1/2 k1 (r S)^2                        pin-slot spring, stretch s = r sin q1 (eq. 3.4)
    E_k2 = 1/2 k2 (l2 - L0)^2,  l2 = |D - C|, l2^2 = c^2 + d^2 - 2 c d sin q1
    E_k3 = 1/2 k3 (l3 - L0)^2,  l3 = |B - A|, l3^2 = a^2 + e^2 - 2 a e sin q1

L0 is the free length of springs k2 and k3: 0 (the paper's) makes them zero-free-length, so
that their energies are quadratic in the anchor coordinates and the design equations
compensate exactly; a real spring (L0 > 0) scales each one's force by 1 - L0 / l.

The k1 wire cannot push: below the horizontal (sin q1 < 0) it is slack, T = 0.

Force paths (the worms are ideal: rigid, frictionless, not back-drivable):
- q1: every spring acts through its energy, -dE/dq1; this includes the reaction
  k1 r^2 S cos q1 of the pin-slot spring, which the paper's Section 3 design ignores.
- q2, spring k1: the idle pulley on the slider pushes it outward with 2T, T = k1 r S. The
  spring's stretch does not change with q2 because the winding pulley, geared to the slider
  through a self-locking worm, pays out twice the slider travel (eq. 2.5); the worm holds the
  pulley torque. So 2T acts on q2 although E_k1 does not depend on q2: the worm supplies the
  work 2T dq2.
- q2, spring k3: its anchor B moves with q2 through a belt. `self_locking` true: that belt is
  driven through a self-locking worm, which holds dE_k3/dq2, so k3 exerts no force on q2 and
  the worm supplies the work dE_k3/dq2 dq2. false: the belt is back-drivable and -dE_k3/dq2
  acts on q2.
The worms' force on q2 beyond the spring energies is f2_worm = 2T + [self_locking] dE_k3/dq2,
and W_worm = integral of f2_worm q2' dt is the work they do on the arm, so that
E_grav + E_springs + E_kin - W_drive - W_worm + E_loss is constant (see below).

Static residuals, the efforts a drive must supply to hold the arm at rest (positive along
+q1 and +q2; gravity effort minus spring compensation):

    tau1_gravity_residual = dV/dq1,  f2_gravity_residual = dV/dq2 - f2_worm,  V = E_grav + E_springs

Lagrange equations, J1 = I1 + m1 lc1^2, inputs tau1 and f2:

    (J1 + J_drive1 + m2 lc2^2) q1'' + 2 m2 lc2 q1' q2' + tau1_gravity_residual = tau1 - d1 q1'
    (m2 + m_drive2) q2'' - m2 lc2 q1'^2 + f2_gravity_residual = f2 - d2 q2'

J_drive1 and m_drive2 are the drives' rotor inertias reflected to the joints (J_rotor N^2 of a
gearbox [kg m^2] and of a lead screw [kg]; 0 by default), set by whoever couples the drives:
each rotor spins with its own joint only, so it adds to that joint's inertia and its kinetic
energy 1/2 J_drive1 q1'^2 + 1/2 m_drive2 q2'^2 is part of E_kin (the rotors' gyroscopic
coupling with the arm's rotation is neglected, as in a reflected-inertia model).

The prismatic joint's stroke is limited by end stops q2_min <= q2 <= q2_max (default: m2
between the pivot and the end of the 1 m link). The stops are inelastic: a slider that hits
one stops there (the stop's impulse acts along the link, so q1_dot does not change) and its
kinetic energy goes to E_loss; it stays until the net force pulls it away.

Energy ledger (docs/energy_ledger.md): E_grav + E_springs + E_kin + E_loss - W_drive - W_worm
- E_added is constant, with E_loss = E_friction + end-stop impacts and E_added = 0 (no mass
joins or leaves this arm).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial
from typing import NamedTuple

from fmu_src.integration import (
    first_substeps,
    integrate_substeps,
    ledger_accuracy,
    ledger_controlled,
)
from fmu_src.mechanism import (
    input_variables,
    no_input_events,
    no_mode,
    output_variables,
    state_variables,
    variable,
    variable_named,
)
from fmu_src.memo import derive, unless_rejected
from fmu_src.parameters import check_ranges, parameter


@dataclass(frozen=True)
class Parameters:
    """Parameters of the arm and compensator: Table 1 of the paper as read in README.md.

    Ours, not the paper's: r = 0.15 m (follows from Table 1's k1 by eq. 3.6), I1 = m1 l1^2/12
    (uniform rod l1 = 1 m about its centre, for m1 = 1 kg), no friction by default (d1 = d2 = 0
    as in the paper's model). With design_springs (default) k1, k2, k3 and rho come from the
    design equations with this g, so compensation is exact; otherwise the given values are
    used (their defaults are Table 1's, designed for g = 9.8).
    """

    m1: float = parameter(1.0, "kg", "Mass of link 1", min=0.0)
    lc1: float = parameter(0.5, "m", "Distance from O to the centre of mass of link 1", min=0.0)
    I1: float = parameter(1.0 / 12.0, "kg.m2", "Moment of inertia of link 1 about its centre "
                          "of mass (uniform rod, l1 = 1 m, m1 = 1 kg)", min=0.0)
    m2: float = parameter(0.5, "kg", "Mass moved by the prismatic joint", min=0.0,
                          min_exclusive=True)
    ls0: float = parameter(0.25, "m", "Distance from O to m2 at q2 = 0 (eq. 3.2)", min=0.0,
                           min_exclusive=True)
    a: float = parameter(0.4, "m", "Height of the frame anchor A of spring k3", min=0.0,
                         min_exclusive=True)
    b: float = parameter(0.125, "m", "Distance from O to the anchor B of spring k3 at q2 = 0",
                         min=0.0, min_exclusive=True)
    c: float = parameter(0.4, "m", "Height of the frame anchor C of spring k2", min=0.0,
                         min_exclusive=True)
    d: float = parameter(0.5, "m", "Distance from O to the link anchor D of spring k2", min=0.0,
                         min_exclusive=True)
    r: float = parameter(0.15, "m", "Pin distance of the pin-slot mechanism (eq. 3.4)", min=0.0,
                         min_exclusive=True)
    design_springs: bool = parameter(
        True, None, "k1, k2, k3 and rho from the design equations 3.6, 3.13, 3.15, 3.17 with "
        "this g (the given values are ignored)")
    k1: float = parameter(16.33, "N/m", "Stiffness of the pin-slot spring (used unless "
                          "design_springs)", min=0.0)
    k2: float = parameter(24.5, "N/m", "Stiffness of spring CD (used unless design_springs)",
                          min=0.0)
    k3: float = parameter(24.5, "N/m", "Stiffness of spring AB (used unless design_springs)",
                          min=0.0)
    rho: float = parameter(0.5, "1", "Belt ratio q*/q2 moving anchor B (used unless "
                           "design_springs)", min=0.0)
    compensated: bool = parameter(True, None, "Compensator fitted (false removes all springs)")
    self_locking: bool = parameter(
        True, None, "The belt moving anchor B is driven through a self-locking worm (spring k3 "
        "exerts no force on q2); false: back-drivable")
    L0: float = parameter(0.0, "m", "Free length of springs k2 and k3 (0: ideal "
                          "zero-free-length springs, as the design equations assume)", min=0.0)
    d1: float = parameter(0.0, "N.m.s/rad", "Viscous friction of the revolute joint", min=0.0)
    d2: float = parameter(0.0, "N.s/m", "Viscous friction of the prismatic joint", min=0.0)
    g: float = parameter(9.81, "m/s2", "Gravitational acceleration", min=0.0)
    q1_0: float = parameter(0.0, "rad", "Initial angle of link 1 from the horizontal")
    q2_0: float = parameter(0.0, "m", "Initial prismatic joint travel")
    q1_dot_0: float = parameter(0.0, "rad/s", "Initial revolute joint speed")
    q2_dot_0: float = parameter(0.0, "m/s", "Initial prismatic joint speed")
    J_drive1: float = parameter(0.0, "kg.m2", "Drive inertia reflected to the revolute joint "
                                "(J_rotor N^2)", min=0.0)
    m_drive2: float = parameter(0.0, "kg", "Drive inertia reflected to the prismatic joint "
                                "(J_rotor N^2 of a lead screw, N = 2 pi / lead)", min=0.0)
    q2_min: float = parameter(-0.25, "m", "Inner end stop of the prismatic joint (default: m2 "
                              "at the pivot, -ls0)")
    q2_max: float = parameter(0.75, "m", "Outer end stop of the prismatic joint (default: m2 "
                              "at the end of the 1 m link, 1 m - ls0)")
    ledger_accuracy: float = ledger_accuracy()

    def __post_init__(self) -> None:
        # the derived constants (fmu_src.memo): J1 = I1 + m1 lc1^2, the inertia of link 1
        # about O [kg m^2]; mass_2 = m2 + m_drive2, the inertia of the prismatic joint [kg];
        # the stiffnesses [N/m] and belt ratio q*/q2 [1] in use: with design_springs k1 =
        # m2 g / (2 r) (eq. 3.6), k2 = lc1 m1 g / (c d) (eq. 3.13), k3 = m2 g ls0 / (a b)
        # (eqs. 3.15, 3.17), rho = b / ls0 (eq. 3.17), else the given k1, k2, k3 and rho
        design = self.design_springs
        derive(self, J1=unless_rejected(lambda: self.I1 + self.m1 * self.lc1 ** 2),
               mass_2=self.m2 + self.m_drive2,
               k1_used=unless_rejected(lambda: self.m2 * self.g / (2.0 * self.r)) if design
               else self.k1,
               k2_used=unless_rejected(lambda: self.lc1 * self.m1 * self.g / (self.c * self.d))
               if design else self.k2,
               k3_used=unless_rejected(lambda: self.m2 * self.g * self.ls0 / (self.a * self.b))
               if design else self.k3,
               rho_used=unless_rejected(lambda: self.b / self.ls0) if design else self.rho)

    def inertia_1(self, q2: float) -> float:
        """Inertia of the revolute joint at travel q2, J1 + J_drive1 + m2 (ls0 + q2)^2 [kg m^2]."""
        lc2 = self.ls0 + q2
        return self.J1 + self.J_drive1 + self.m2 * lc2 * lc2


def validate(params: Parameters) -> None:
    """Raise ValueError naming the first parameter that is NaN or outside its physical range."""
    check_ranges(params)
    if not params.J1 > 0.0:
        raise ValueError(f"I1 = {params.I1} kg.m2 with m1 lc1^2 = {params.m1 * params.lc1 ** 2} "
                         "kg.m2 gives J1 = I1 + m1 lc1^2 outside (0, inf)")
    if not params.q2_min < params.q2_max:
        raise ValueError(f"q2_min = {params.q2_min} m must be below q2_max = {params.q2_max} m")
    if not params.q2_min <= params.q2_0 <= params.q2_max:
        raise ValueError(f"q2_0 = {params.q2_0} m is outside [q2_min, q2_max] = "
                         f"[{params.q2_min}, {params.q2_max}] m")


class Inputs(NamedTuple):
    """Drive efforts held constant over a communication step."""

    tau1: float = 0.0   # N m, drive torque on the revolute joint
    f2: float = 0.0     # N, drive force on the prismatic joint, outward positive


# the FMU's input variables, one per Inputs field
INPUT_VARIABLES = input_variables(
    Inputs,
    tau1=variable("N.m", "Drive torque on the revolute joint"),
    f2=variable("N", "Drive force on the prismatic joint, outward positive"),
)


# no input changes the state at a communication point: the efforts are no events
EVENT_INPUTS: tuple[str, ...] = ()


class State(NamedTuple):
    """Joint positions and speeds, and the cumulative energies integrated with them [J]."""

    q1: float
    q1_dot: float
    q2: float
    q2_dot: float
    W_drive: float = 0.0     # work of tau1 and f2 on the arm
    W_worm: float = 0.0      # work of the worms' forces on the arm
    E_friction: float = 0.0  # energy dissipated by d1 and d2
    E_impact: float = 0.0    # energy dissipated by the end stops of q2


def initial_state(p: Parameters) -> State:
    """State at t = 0 from q1_0, q2_0, q1_dot_0, q2_dot_0."""
    return State(p.q1_0, p.q1_dot_0, p.q2_0, p.q2_dot_0)


class Efforts(NamedTuple):
    """Static efforts at a configuration (drive side, positive along +q1 and +q2)."""

    tau1_gravity: float           # N m, eq. 3.1
    f2_gravity: float             # N, eq. 3.3
    tau1_gravity_residual: float  # N m, dV/dq1
    f2_gravity_residual: float    # N, dV/dq2 - f2_worm
    T_wire: float                 # N, tension of the k1 wire
    f2_worm: float                # N, force of the worms on q2 beyond the spring energies


def efforts(p: Parameters, q1: float, q2: float) -> Efforts:
    """Gravity efforts, their residuals after compensation and the worm force at (q1, q2).

    Built by tuple.__new__ (Efforts(...) is a Python call): this runs at every RK4 stage."""
    sin_q, cos_q = math.sin(q1), math.cos(q1)
    tau1_gravity = (p.lc1 * p.m1 + (p.ls0 + q2) * p.m2) * p.g * cos_q
    f2_gravity = p.m2 * p.g * sin_q
    if not p.compensated:
        return tuple.__new__(Efforts, (tau1_gravity, f2_gravity, tau1_gravity, f2_gravity,
                                       0.0, 0.0))
    k1, k2, k3, rho = p.k1_used, p.k2_used, p.k3_used, p.rho_used
    e = p.b + rho * q2
    stretch = p.r * max(sin_q, 0.0)
    T = k1 * stretch
    if p.L0:  # a real spring's force: k (l - L0) along it, k (1 - L0 / l) per unit length
        k2 *= _free_length_factor(p, p.c * p.c + p.d * p.d - 2.0 * p.c * p.d * sin_q)
        k3 *= _free_length_factor(p, p.a * p.a + e * e - 2.0 * p.a * e * sin_q)
    dV_dq1 = tau1_gravity + (T * p.r - p.c * p.d * k2 - p.a * e * k3) * cos_q
    dE3_dq2 = k3 * rho * (e - p.a * sin_q)
    f2_worm = 2.0 * T + (dE3_dq2 if p.self_locking else 0.0)
    return tuple.__new__(Efforts, (tau1_gravity, f2_gravity, dV_dq1,
                                   f2_gravity + dE3_dq2 - f2_worm, T, f2_worm))


def _free_length_factor(p: Parameters, length_squared: float) -> float:
    """1 - L0 / l of a spring of length l (its force per unit length over k); 1 where
    l = 0, the zero-free-length limit (no direction to pull in)."""
    length = math.sqrt(max(length_squared, 0.0))
    return 1.0 - p.L0 / length if length > 0.0 else 1.0


def _held_by_stop(p: Parameters, q2: float, q2_dot: float, force: float) -> bool:
    """True when q2 rests exactly on an end stop and the net force drives it into that stop.

    A state beyond a stop (inside an RK4 sub-step) is integrated freely and clamped after
    the sub-step: holding it there would mix two right-hand sides in one RK4 step and spoil
    the energy balance."""
    return q2_dot == 0.0 and ((q2 == p.q2_min and force <= 0.0)
                              or (q2 == p.q2_max and force >= 0.0))


def derivatives(p: Parameters, u: Inputs, s: State, rates: Inputs | None = None,
                mode: tuple[int, ...] | None = None) -> State:
    """Time derivative of the state (see _derivatives) as a State; one regime (the stops
    hold q2 where the state says so): mode is not used."""
    return State._make(_derivatives(p, u, s, rates))


def _derivatives(p: Parameters, u: Inputs, s: State, rates: Inputs | None = None
                 ) -> tuple[float, ...]:
    """Time derivative of the state for constant inputs, in State's field order (`rates`,
    d/dt of the inputs, as the other mechanisms take it: no mass changes here, so it is not
    used). A plain tuple: this runs four times per RK4 sub-step."""
    q1, w1, q2, w2 = s[:4]
    lc2 = p.ls0 + q2
    eff = efforts(p, q1, q2)
    tau1 = u.tau1 - p.d1 * w1 - 2.0 * p.m2 * lc2 * w1 * w2 - eff.tau1_gravity_residual
    f2 = u.f2 - p.d2 * w2 + p.m2 * lc2 * w1 * w1 - eff.f2_gravity_residual
    q2_dot, w2_dot = w2, f2 / p.mass_2
    if _held_by_stop(p, q2, w2, f2):
        q2_dot = w2_dot = 0.0
    return (w1, tau1 / p.inertia_1(q2), q2_dot, w2_dot, u.tau1 * w1 + u.f2 * q2_dot,
            eff.f2_worm * q2_dot, p.d1 * w1 * w1 + p.d2 * q2_dot * q2_dot, 0.0)


def characteristic_rate(p: Parameters, u: Inputs, s: State) -> float:
    """Fastest rate of the local dynamics [1/s]: sets the internal integration step (the
    inputs, efforts only, do not change it)."""
    lc2 = p.ls0 + s.q2
    J, mass = p.inertia_1(s.q2), p.mass_2
    stiffness_1 = p.g * (p.m1 * p.lc1 + p.m2 * abs(lc2))
    stiffness_2 = p.m2 * p.g / max(abs(lc2), p.ls0)
    if p.compensated:
        k3, rho = p.k3_used, p.rho_used
        stiffness_1 += (p.k1_used * p.r * p.r + p.c * p.d * p.k2_used
                        + p.a * abs(p.b + rho * s.q2) * k3)
        stiffness_2 += k3 * rho * rho
    return max(math.sqrt(stiffness_1 / J), math.sqrt(stiffness_2 / mass), p.d1 / J,
               p.d2 / mass, 2.0 * abs(s.q1_dot), abs(s.q2_dot) / max(abs(lc2), p.ls0))


def mechanical_energy(p: Parameters, s: State) -> float:
    """E_grav + E_springs + E_kin [J] (as `outputs` reports them)."""
    E_grav, E_springs, E_kin = ledger_terms(p, Inputs(), s)[:3]
    return E_grav + E_springs + E_kin


def _apply_stops(p: Parameters, s: State) -> State:
    """Clamp q2 to its end stops (inelastic: the energy the clamp removes goes to E_impact)."""
    if p.q2_min <= s.q2 <= p.q2_max:
        return s
    if s.q2 < p.q2_min:
        clamped = s._replace(q2=p.q2_min, q2_dot=max(s.q2_dot, 0.0))
    else:
        clamped = s._replace(q2=p.q2_max, q2_dot=min(s.q2_dot, 0.0))
    loss = mechanical_energy(p, s) - mechanical_energy(p, clamped)
    return clamped._replace(E_impact=s.E_impact + loss)


def ledger_terms(p: Parameters, u: Inputs, s: State) -> tuple[float, ...]:
    """The signed terms of the energy ledger [J], E_grav, E_springs, E_kin, E_loss (in
    parts), -W_drive and -W_worm (as `outputs` reports them; E_added is 0): their sum is
    constant (docs/energy_ledger.md)."""
    q1, w1, q2, w2, W_drive, W_worm, E_friction, E_impact = s
    return ((p.m1 * p.lc1 + p.m2 * (p.ls0 + q2)) * p.g * math.sin(q1), spring_energy(p, q1, q2),
            0.5 * p.inertia_1(q2) * w1 * w1 + 0.5 * p.mass_2 * w2 * w2, E_friction, E_impact,
            -W_drive, -W_worm)


def advance(p: Parameters, u: Inputs, s: State, dt: float) -> State:
    """Integrate over one communication step dt [s] with inputs held constant: RK4 sub-steps
    from the rate rule, raised until the energy ledger meets p.ledger_accuracy
    (`integration.ledger_controlled`)."""
    return ledger_controlled(
        lambda n: integrate_substeps(partial(_derivatives, p, u), s, dt, n,
                                     partial(_apply_stops, p)),
        partial(ledger_terms, p, u), (4, 5), s,
        first_substeps(dt, characteristic_rate(p, u, s)), dt, p)


switch_inputs = no_input_events  # EVENT_INPUTS is empty


# ---- Model Exchange: the stroke limits as state events -----------------------------------
EVENT_INDICATORS = (
    variable_named("q2_min_reached", variable(
        "m", "q2 - q2_min: the inner end stop is hit where it reaches 0 (the stroke while q2 "
        "rests on it)")),
    variable_named("q2_max_reached", variable(
        "m", "q2_max - q2: the outer end stop is hit where it reaches 0 (the stroke while q2 "
        "rests on it)")),
)
mode = no_mode   # the stops hold q2 by the state alone (_held_by_stop)


def event_indicators(p: Parameters, u: Inputs, s: State, mode: tuple[int, ...]
                     ) -> tuple[float, float]:
    """The distances of q2 from its end stops [m]; the stroke where it rests on one, so that
    resting there is no event (leaving it, q2 moves inside)."""
    stroke, q2 = p.q2_max - p.q2_min, s.q2
    return (q2 - p.q2_min if q2 != p.q2_min else stroke,
            p.q2_max - q2 if q2 != p.q2_max else stroke)


def event_update(p: Parameters, u: Inputs, s: State, mode: tuple[int, ...]) -> State:
    """A stop reached: q2 clamped to it, the impact's energy to E_impact (`_apply_stops`, as
    after every RK4 sub-step of `advance`)."""
    return _apply_stops(p, s)


def state_nominals(p: Parameters) -> tuple[float, ...]:
    """1 rad and 1 rad/s for the revolute joint, ls0 [m] and ls0 per second for the
    prismatic one, 1 J for the energies."""
    return (1.0, 1.0, p.ls0, p.ls0, 1.0, 1.0, 1.0, 1.0)


class Outputs(NamedTuple):
    """Observable quantities (README.md; SI units)."""

    q1: float
    q1_dot: float
    q2: float
    q2_dot: float
    tau1_gravity: float
    f2_gravity: float
    tau1_gravity_residual: float
    f2_gravity_residual: float
    T_wire: float
    f2_worm: float
    E_grav: float
    E_springs: float
    E_kin: float
    W_drive: float
    W_worm: float
    E_friction: float
    E_loss: float
    E_added: float


# the FMU's output variables, one per Outputs field; each a function of the state alone
OUTPUT_VARIABLES = output_variables(
    Outputs, Inputs,
    q1=variable("rad", "Angle of link 1 from the horizontal, counter-clockwise positive"),
    q1_dot=variable("rad/s", "Revolute joint speed"),
    q2=variable("m", "Prismatic joint travel along the link (m2 at ls0 + q2 from O)"),
    q2_dot=variable("m/s", "Prismatic joint speed"),
    tau1_gravity=variable("N.m", "Gravity torque effort of the revolute joint, uncompensated "
                                 "(eq. 3.1)"),
    f2_gravity=variable("N", "Gravity force effort of the prismatic joint, uncompensated "
                             "(eq. 3.3)"),
    tau1_gravity_residual=variable("N.m", "Torque a drive must supply to hold the arm at rest: "
                                          "gravity effort minus spring compensation"),
    f2_gravity_residual=variable("N", "Force a drive must supply to hold the arm at rest: "
                                      "gravity effort minus spring and wire compensation"),
    T_wire=variable("N", "Tension of the pin-slot spring wire, k1 r sin(q1) (0 when slack); "
                         "2 T_wire acts on the slider"),
    f2_worm=variable("N", "Force of the self-locking worms on the prismatic joint beyond the "
                          "spring energies (2 T_wire, plus dE_k3/dq2 when self_locking)"),
    E_grav=variable("J", "Gravitational potential energy of m1 and m2 (0 at q1 = 0)"),
    E_springs=variable("J", "Elastic energy of springs k1, k2, k3"),
    E_kin=variable("J", "Kinetic energy of the arm and of the drive rotors (J_drive1, "
                        "m_drive2)"),
    W_drive=variable("J", "Cumulative work of tau1 and f2 on the arm"),
    W_worm=variable("J", "Cumulative work of the worms on the arm (integral of f2_worm "
                         "q2_dot)"),
    E_friction=variable("J", "Cumulative energy dissipated by d1 and d2"),
    E_loss=variable("J", "Cumulative energy dissipated: E_friction plus the end-stop impacts of "
                         "q2"),
    E_added=variable("J", "Energy brought in by masses joining or leaving: always 0 here (the "
                          "mechanisms' common ledger E_grav + E_springs + E_kin + E_loss - "
                          "W_drive - W_worm - E_added is constant)"),
)


def spring_energy(p: Parameters, q1: float, q2: float) -> float:
    """Elastic energy of springs k1, k2, k3 (0 when not compensated) [J]."""
    if not p.compensated:
        return 0.0
    sin_q = math.sin(q1)
    e = p.b + p.rho_used * q2
    l2_squared = p.c * p.c + p.d * p.d - 2.0 * p.c * p.d * sin_q
    l3_squared = p.a * p.a + e * e - 2.0 * p.a * e * sin_q
    energy = 0.5 * (p.k1_used * (p.r * max(sin_q, 0.0)) ** 2 + p.k2_used * l2_squared
                    + p.k3_used * l3_squared)
    if p.L0:  # 1/2 k (l - L0)^2 = 1/2 k l^2 + k L0 (L0 / 2 - l)
        energy += sum(k * p.L0 * (0.5 * p.L0 - math.sqrt(max(squared, 0.0)))
                      for k, squared in ((p.k2_used, l2_squared), (p.k3_used, l3_squared)))
    return energy


def outputs(p: Parameters, u: Inputs, s: State) -> Outputs:
    """All outputs for the state s (the signature of the other mechanisms' `outputs`; none
    depends on the inputs u here)."""
    q1, w1, q2, w2, W_drive, W_worm, E_friction, E_impact = s
    lc2 = p.ls0 + q2
    # In field order, built by tuple.__new__: Outputs(...) with keywords is a costly call.
    return tuple.__new__(Outputs, (
        q1, w1, q2, w2, *efforts(p, q1, q2),
        (p.m1 * p.lc1 + p.m2 * lc2) * p.g * math.sin(q1),                 # E_grav
        spring_energy(p, q1, q2),                                          # E_springs
        0.5 * p.inertia_1(q2) * w1 * w1 + 0.5 * p.mass_2 * w2 * w2,        # E_kin
        W_drive, W_worm, E_friction, E_friction + E_impact, 0.0))          # ..., E_loss, E_added


# the Model Exchange state no output reports (E_loss is E_friction + E_impact)
STATE_VARIABLES = state_variables(
    State, Outputs,
    E_impact=variable("J", "Cumulative energy dissipated by the end stops of q2"),
)
