"""Physics of Ciupitu's passive translational counterweight (Ciupitu 2018, Figure 4a).

Pure model, standard library only: no FMI and no I/O. It is shared by the FMU slave
`CiupituBalancer`, the harness command `ciupitu-example` and the tests (README.md).

Geometry. A counterweight of weight G2 = m2 g slides along the arm on the side opposite to
the payload; a bar of length AB joins it to the ground pivot A, a distance OA above O. The
paper's arm angle phi is measured from the horizontal, phi = pi/2 - theta, with theta the
project's angle (docs/conventions.md: from the upward vertical, counter-clockwise; the project's
figure is the paper's Figure 4a mirrored left to right). The counterweight sits at

    OB(phi) = sqrt(AB^2 - OA^2 cos^2 phi) - OA sin phi                  (eq. 13, AB > OA)

which is >= AB - OA > 0 at every angle, so the arm may turn fully. Eq. 14 is a misprint.

Moments about O in the paper's sign convention (positive in the direction of increasing
phi, i.e. of decreasing theta), eqs. 8, 12 and 16:

    M_g = -G_pv OP cos phi,   M_b = G2 OB cos phi,   M_u = M_b + M_g

Static example (paper Section 4): the arm rocks uniformly, one stroke from phi = +pi/2 to
-pi/2 per half period T/2, so s = t/T = (pi/2 - phi)/(2 pi) in [0, 1/2]; payload laws
G_pv = 4 G_max s (1 - s) (parabolic, eq. 7 without its constant part) and G_pv = 2 G_max s
(linear). The interpretation that reproduces the paper's numbers: E_u and E_b are the NET
work over one stroke, the absolute value of the signed integral of M_g and of M_u over phi
(over t it is the same up to the constant factor dphi/dt, which cancels in eps), and
eps = 1 - E_b/E_u (eq. 31, E_b printed as E_e). For the paper's data this gives
eps_parabolic = 0.9734464 and eps_linear = 0.6320306 (paper: 0.973446, 0.632031), and
max |M_u| = 0.82786 N m at phi = 0.1047 rad (parabolic; paper 0.828 N m at 0.095 rad, where
|M_u| = 0.82765 N m: the maximum is flat) and 1.3666 N m at phi = -0.479 rad (linear; paper
"about 1.4 N m at -0.5 rad"). Absolute work (integral of |M|) gives eps_parabolic = 0.895884
instead, so it is not the paper's reading; for the linear law M_u keeps one sign and both
readings agree.

Caveat (kept, because the paper defines M_b so): M_b is the moment of the
counterweight's weight alone. The bar AB also pushes the counterweight, along a line through
A rather than O, so the torque the arm really receives (virtual work, -dE_p/dtheta) has a
further term, the static moment of the bar force about O:

    M_bar = G2 (dOB/dphi) sin phi

which vanishes only at phi = 0 and +-pi/2. With it the counterweight's work over a stroke is
G2 times the rise of B, 2 AB G2, so E_b = |2 AB G2 - E_u|: for the paper's example
eps = 0.932601 (parabolic) and 0.5 (linear). A dynamic run through a drive sees these, not
the paper's values.

Dynamics (one degree of freedom, FMU state theta and omega = dtheta/dt). The link has mass m
at c, inertia J_link about O, a payload (kg) at w = OP, a fixed counterweight m_fixed_cw at
c_fixed_cw on the side opposite to the payload, and the sliding counterweight m2 at OB on the
same opposite side. With OB' = dOB/dphi (dphi = -dtheta):

    E_p = g cos(theta) (m c + payload w - m_fixed_cw c_fixed_cw - m2 OB)
    J(theta) = J_link + payload w^2 + m_fixed_cw c_fixed_cw^2 + J_drive + m2 (OB^2 + OB'^2)
    E_kin = 1/2 J omega^2
    J omega' = tau_drive + tau_gravity - (d_link + d_cw OB'^2) omega - 1/2 (dJ/dtheta) omega^2

from the Lagrangian L = E_kin - E_p, with tau_gravity = -dE_p/dtheta. In terms of the
paper's moments (all static):

    tau_gravity = -(M_u + M_bar + (m_fixed_cw c_fixed_cw - m c) g cos phi)

with G_pv = payload g, OP = w and G2 = m2 g; the last term is zero when the fixed
counterweight balances the link (m_fixed_cw c_fixed_cw = m c, the default).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import NamedTuple

from fmu_src import ledger
from fmu_src.integration import advance_arm, kept_outputs, ledger_accuracy
from fmu_src.mechanism import (
    input_variables,
    no_event_indicators,
    no_event_update,
    no_mode,
    output_variables,
    state_variables,
    variable,
)
from fmu_src.mechanisms.ciupitu.statics import _check_bar, _geometry, _moments
from fmu_src.memo import derive, slot
from fmu_src.parameters import check_ranges, parameter

DEG = math.pi / 180.0
HALF_PI = 0.5 * math.pi


# ---- dynamics for the FMU ---------------------------------------------------------------
@dataclass(frozen=True)
class Parameters:
    """Parameters of the arm; the link is Franchetti's (Table 1, as for SelfRegulatingBalancer).

    Ours, not from a paper: J_link = m L^2/3 with L = 2 c (0.16 kg m^2); fixed counterweight
    6 kg at 0.1 m (balances m c = 0.6 kg m with half the inertia of a mirror image of the link
    mass); d_link = 0.01 N m s/rad. PLACEHOLDERS, to be replaced by the harness optimisation:
    m2 = 0.75 kg, OA = 0.175 m, AB = 0.35 m, the paper's example scaled to a 1 kg payload at
    w = 0.35 m (lengths by w/OP, weights by 1 kg g / G_max).
    """

    m: float = parameter(3.0, "kg", "Link mass", min=0.0)
    c: float = parameter(0.2, "m", "Distance from pivot O to the link centre of mass", min=0.0)
    J_link: float = parameter(0.16, "kg.m2", "Link moment of inertia about O (m L^2/3, L = 0.4 m)",
                              min=0.0)
    w: float = parameter(0.35, "m", "Distance from O to the payload (the paper's OP)", min=0.0)
    m2: float = parameter(0.75, "kg", "Mass of the sliding counterweight (G2/g)", min=0.0)
    OA: float = parameter(0.175, "m", "Height of the ground pivot A above O", min=0.0)
    AB: float = parameter(0.35, "m", "Length of the bar joining A to the sliding counterweight B",
                          min=0.0, min_exclusive=True)
    m_fixed_cw: float = parameter(6.0, "kg", "Mass of the fixed counterweight opposite the payload",
                                  min=0.0)
    c_fixed_cw: float = parameter(0.1, "m", "Distance from O to the fixed counterweight", min=0.0)
    d_link: float = parameter(0.01, "N.m.s/rad", "Viscous friction at the pivot", min=0.0)
    d_cw: float = parameter(0.0, "N.s/m", "Viscous friction of the counterweight sliding along "
                            "the arm (it slides at dOB/dt = -OB' omega)", min=0.0)
    g: float = parameter(9.81, "m/s2", "Gravitational acceleration", min=0.0)
    theta0: float = parameter(60.0 * DEG, "rad", "Initial arm angle from the upward vertical")
    omega0: float = parameter(0.0, "rad/s", "Initial arm angular velocity")
    J_drive: float = parameter(0.0, "kg.m2", "Drive inertia reflected to the arm (J_rotor N^2)",
                               min=0.0)
    ledger_accuracy: float = ledger_accuracy()

    @property
    def J_min(self) -> float:
        """Lower bound of the arm's inertia without payload (OB >= AB - OA) [kg m^2]."""
        return (self.J_link + self.J_drive + self.m_fixed_cw * self.c_fixed_cw ** 2
                + self.m2 * (self.AB - self.OA) ** 2)

    def __post_init__(self) -> None:
        # the slots (fmu_src.memo) of `_held`, (payload, terms), and `_arm_terms`, (theta,
        # payload, terms), keyed by identity; (state, inputs, outputs) of `ledger_terms`,
        # for `outputs`
        derive(self, _last_held=slot((None, ())), _last_terms=slot((None, None, ())),
               _kept_outputs=slot((None, None, None)))


def validate(params: Parameters) -> None:
    """Raise ValueError naming the first parameter that is NaN or outside its physical range."""
    check_ranges(params)
    _check_bar(params.OA, params.AB)
    if not params.J_min > 0.0:
        raise ValueError("J_link + J_drive + m_fixed_cw c_fixed_cw^2 + m2 (AB - OA)^2 = "
                         f"{params.J_min} kg.m2 must be positive: the arm needs inertia")


class Inputs(NamedTuple):
    """Inputs held constant over a communication step."""

    tau_drive: float = 0.0    # N m, drive torque on the arm (counter-clockwise, along theta)
    payload: float = 0.0      # kg, payload at distance w


# the FMU's input variables, one per Inputs field (every payload arm's)
INPUT_VARIABLES = input_variables(
    Inputs,
    tau_drive=variable("N.m", "Drive torque on the arm about O, along theta"),
    payload=variable("kg", "Payload mass at distance w (the paper's G_pv/g)", min=0.0),
)


# inputs whose change at a communication point is an event (switch_inputs)
EVENT_INPUTS = ("payload",)


class State(NamedTuple):
    """Continuous state: arm angle from the upward vertical [rad] and its rate [rad/s], and the
    energy ledger [J] (E_p + E_kin + E_loss - W_drive - E_added is constant)."""

    theta: float
    omega: float
    W_drive: float = 0.0    # work of tau_drive on the arm
    E_loss: float = 0.0     # dissipated: pivot friction, payload picked up while moving
    E_added: float = 0.0    # brought in (+) or taken out (-) by payload joining or leaving


def initial_state(params: Parameters) -> State:
    """State at t = 0."""
    return State(params.theta0, params.omega0)


class _Held(NamedTuple):
    """Terms of the dynamics that the parameters and a held payload set."""

    OA: float               # m
    OA2: float              # m^2, OA^2
    AB2: float              # m^2, AB^2
    m2: float               # kg
    g: float                # m/s^2
    d_link: float           # N m s/rad
    d_cw: float             # N s/m
    w: float                # m
    G2: float               # N, m2 g
    J_held: float           # kg m^2, J_link + payload w^2 + m_fixed_cw c_fixed_cw^2 + J_drive
    arm_held: float         # kg m, m c + payload w - m_fixed_cw c_fixed_cw
    stiffness_held: float   # kg m, m c + payload w + m_fixed_cw c_fixed_cw


def _held(p: Parameters, payload: float) -> _Held:
    """The terms the parameters and the payload [kg] set: the last ones are kept with the
    parameters, for the very object payload (an input held over many steps)."""
    last_payload, held = p._last_held[0]
    if last_payload is payload:
        return held
    mc, payload_moment, mc_fixed_cw = p.m * p.c, payload * p.w, p.m_fixed_cw * p.c_fixed_cw
    held = _Held(p.OA, p.OA * p.OA, p.AB * p.AB, p.m2, p.g, p.d_link, p.d_cw, p.w, p.m2 * p.g,
                 p.J_link + payload * p.w ** 2 + p.m_fixed_cw * p.c_fixed_cw ** 2 + p.J_drive,
                 mc + payload_moment - mc_fixed_cw, mc + payload_moment + mc_fixed_cw)
    p._last_held[0] = (payload, held)   # one assignment: key and terms together
    return held


def _arm_terms(p: Parameters, payload: float, theta: float
               ) -> tuple[float, float, float, float, float, float, float]:
    """(OB [m], OB' [m/rad], OB'' [m/rad^2], J [kg m^2], dJ/dtheta [kg m^2/rad], damping
    d(theta) = d_link + d_cw OB'^2 [N m s/rad], tau_gravity [N m]) at theta with the
    payload [kg].

    The last ones are kept with the parameters, for the very objects theta and payload: the
    outputs after a step compute them at the state the next step starts from, where its rate
    and its first RK4 stage need them again.
    """
    last = p._last_terms[0]
    if last[0] is theta and last[1] is payload:
        return last[2]
    _, _, _, m2, g, d_link, d_cw, _, _, J_held, arm_held, _ = _held(p, payload)
    OB, dOB, d2OB = _geometry(p.OA, p.AB, HALF_PI - theta)
    terms = (OB, dOB, d2OB, J_held + m2 * (OB * OB + dOB * dOB), -2.0 * m2 * dOB * (OB + d2OB),
             d_link + d_cw * dOB * dOB,
             g * (math.sin(theta) * (arm_held - m2 * OB) - math.cos(theta) * m2 * dOB))
    p._last_terms[0] = (theta, payload, terms)   # one assignment: key and terms together
    return terms


def kept_start(last_terms: list, payload: float) -> tuple[float | None, tuple]:
    """(theta, terms) that a one-link arm's _arm_terms kept last in last_terms, for this very
    payload object, else (None, ()): the terms a step's first RK4 stage may take."""
    theta, last_payload, terms = last_terms[0]
    return (theta, terms) if last_payload is payload else (None, ())


def inertia(p: Parameters, payload: float, theta: float) -> tuple[float, float]:
    """J(theta) [kg m^2] and dJ/dtheta [kg m^2/rad]."""
    return _arm_terms(p, payload, theta)[3:5]


def tau_gravity(p: Parameters, payload: float, theta: float) -> float:
    """Gravity torque on the arm about O along theta, -dE_p/dtheta [N m]."""
    return _arm_terms(p, payload, theta)[6]


def acceleration(p: Parameters, payload: float, tau_drive: float, theta: float,
                 omega: float) -> float:
    """Angular acceleration [rad/s^2] from the Lagrange equation
    J(theta) theta'' + 1/2 J'(theta) omega^2 = tau_drive + tau_gravity - d(theta) omega."""
    return _arm_rates(p, payload, tau_drive)(theta, omega)[0]


def _arm_rates(p: Parameters, payload: float, tau_drive: float
               ) -> Callable[[float, float], tuple[float, float]]:
    """(theta, omega) -> (the angular acceleration [rad/s^2] (`acceleration`), the friction
    loss d(theta) omega^2 [W]) with the payload and the drive torque held.

    It runs four times per RK4 sub-step, so _arm_terms is written out in it, operation for
    operation (the same numbers; tests/test_ciupitu.py checks it), with the terms the
    payload sets computed once: a call and a tuple per stage cost more than the arithmetic.
    At the angle _arm_terms computed last (the step's start) it takes its terms.
    Measured against `_arm_terms` called per stage (with integrate_arm and the slots): the
    three save 111 k of 219 k instructions per FMU step (OA = 0; 97 k of 220 k at the
    defaults), far above 10 % of a closed-loop step (fmu_src/integration.py).
    """
    held = _held(p, payload)
    last_theta, last = kept_start(p._last_terms, payload)

    def rates(theta: float, omega: float) -> tuple[float, float]:
        if theta is last_theta:
            _, _, _, J, dJ, damping, gravity = last
        else:
            OA, OA2, AB2, m2, g, d_link, d_cw, _, _, J_held, arm_held, _ = held
            phi = HALF_PI - theta
            sin_p, cos_p = math.sin(phi), math.cos(phi)
            root = math.sqrt(AB2 - (OA * cos_p) ** 2)
            d_root = OA2 * sin_p * cos_p / root
            OB = root - OA * sin_p
            dOB = d_root - OA * cos_p
            d2OB = (OA2 * math.cos(2.0 * phi) - d_root * d_root) / root + OA * sin_p
            J = J_held + m2 * (OB * OB + dOB * dOB)
            dJ = -2.0 * m2 * dOB * (OB + d2OB)
            damping = d_link + d_cw * dOB * dOB
            gravity = g * (math.sin(theta) * (arm_held - m2 * OB) - math.cos(theta) * m2 * dOB)
        return ((tau_drive + gravity - damping * omega - 0.5 * dJ * omega * omega) / J,
                damping * omega * omega)

    OA = held[0]
    if OA == 0.0 and math.copysign(1.0, OA) > 0.0:
        return _pivoted_rates(held, tau_drive, rates)
    return rates


def _pivoted_rates(held: _Held, tau_drive: float,
                   rates: Callable[[float, float], tuple[float, float]]
                   ) -> Callable[[float, float], tuple[float, float]]:
    """`_arm_rates`'s rates for OA = +0, with fewer operations and the same numbers.

    The bar then pivots at O and the counterweight stays at OB = AB: the written-out terms
    give OB' = OB'' = +-0, so J, d(theta) and the net moment arm do not change with the
    angle, and dJ/dtheta and the bar's gravity term are +-0, whose subtraction leaves a
    non-zero finite sum as it is. Where the sum is zero or not finite, rates computes it.
    """
    _, _, AB2, m2, g, d_link, d_cw, _, _, J_held, arm_held, _ = held
    OB = math.sqrt(AB2)                       # root - OA sin(phi) with OA = +0
    J = J_held + m2 * (OB * OB + 0.0)         # J_held + m2 (OB^2 + OB'^2), OB'^2 = +0
    damping = d_link + d_cw * 0.0 * 0.0       # d_cw OB'^2 has the sign of d_cw
    net = arm_held - m2 * OB

    def pivoted(theta: float, omega: float) -> tuple[float, float]:
        moment = math.sin(theta) * net
        if moment != 0.0:
            torque = tau_drive + g * moment - damping * omega
            if torque != 0.0 and -math.inf < torque < math.inf:
                return torque / J, damping * omega * omega
        return rates(theta, omega)

    return pivoted


# d/dt of the state, for constant or continuously changing inputs (docs/energy_ledger.md)
derivatives = ledger.payload_derivatives(_arm_rates, inertia, State)


def characteristic_rate(p: Parameters, u: Inputs, s: State) -> float:
    """Fastest rate of the local dynamics [1/s]: sets the internal integration step."""
    payload = u.payload
    OB, dOB, d2OB, J, dJ, damping, _ = _arm_terms(p, payload, s.theta)
    _, _, _, m2, g, _, _, _, _, _, _, stiffness_held = _held(p, payload)
    stiffness = g * (stiffness_held + m2 * (OB + 2.0 * abs(dOB) + abs(d2OB)))
    return max(math.sqrt(stiffness / J), damping / J, abs(s.omega) * (1.0 + abs(dJ) / J))


def ledger_terms(p: Parameters, u: Inputs, s: State) -> tuple[float, ...]:
    """The signed terms of the energy ledger [J]: E_p in its three parts (the link with its
    payload, the fixed counterweight, the sliding counterweight), E_kin, E_loss, -W_drive
    and -E_added (as `outputs` reports them): their sum is constant
    (docs/energy_ledger.md). E_p goes in parts so that the ledger's rounding allowance
    (which scales with the sum of |term|) sees the moments that cancel in it, as
    `rocking_counterweight.ledger_terms` explains. The outputs come with them, from the same
    energies, kept for `outputs` (the end of a step is evaluated once, for the ledger's
    control and the slave)."""
    theta, omega, payload = s.theta, s.omega, u.payload
    OB, dOB, _, J, _, _, gravity = _arm_terms(p, payload, theta)
    _, _, _, m2, g, _, _, w, G2, _, arm_held, _ = _held(p, payload)
    M_g, M_b, M_u = _moments(payload * g, w, G2, OB, math.sin(theta))  # cos(phi)
    E_p, E_kin = g * math.cos(theta) * (arm_held - m2 * OB), 0.5 * J * omega ** 2
    W_drive, E_loss, E_added = s.W_drive, s.E_loss, s.E_added
    # In field order, built by tuple.__new__: Outputs(...) with keywords is a costly call.
    p._kept_outputs[0] = (s, u, tuple.__new__(Outputs, (
        theta, omega, OB, gravity, E_p, E_kin, M_g, M_b, M_u,
        G2 * dOB * math.sin(HALF_PI - theta),                               # M_bar
        W_drive, E_loss, E_added)))
    lever = g * math.cos(theta)
    return (lever * (p.m * p.c + payload * w), -lever * (p.m_fixed_cw * p.c_fixed_cw),
            -lever * m2 * OB, E_kin, E_loss, -W_drive, -E_added)


def advance(p: Parameters, u: Inputs, s: State, dt: float) -> State:
    """Integrate over one communication step dt [s] with inputs held constant."""
    tau = u.tau_drive
    rate = characteristic_rate(p, u, s)    # first: its terms at s.theta serve the first stage
    return advance_arm(_arm_rates(p, u.payload, tau), s, tau, dt, rate,
                       partial(ledger_terms, p, u), p, u.payload)


# a payload caught from rest or released at a communication point (docs/energy_ledger.md)
switch_inputs = ledger.payload_switch(inertia)



class Outputs(NamedTuple):
    """Observable quantities (README.md; SI units)."""

    theta: float
    omega: float
    OB: float
    tau_gravity: float
    E_p: float
    E_kin: float
    M_g: float
    M_b: float
    M_u: float
    M_bar: float
    W_drive: float
    E_loss: float
    E_added: float


# The output variables every payload arm has (the rocking counterweight's too), by name:
# the payload's moment, inertia and weight act at once on those that depend on it.
ARM_OUTPUTS = dict(
    theta=variable("rad", "Arm angle from the upward vertical, counter-clockwise positive "
                          "(the paper's phi = pi/2 - theta)"),
    omega=variable("rad/s", "Arm angular velocity"),
    E_p=variable("J", "Gravitational potential energy of link, payload and both "
                      "counterweights", depends_on=("payload",)),
    E_kin=variable("J", "Kinetic energy of link, payload, counterweights and drive rotor",
                   depends_on=("payload",)),
    M_g=variable("N.m", "Payload moment about O, -payload g w cos(phi) (eq. 8, paper's sign)",
                 depends_on=("payload",)),
    M_u=variable("N.m", "Unbalanced moment M_b + M_g (eq. 16)", depends_on=("payload",)),
    W_drive=variable("J", "Cumulative work of tau_drive on the arm"),
    E_loss=variable("J", "Cumulative energy dissipated: pivot friction, payload picked up "
                         "while moving"),
    E_added=variable("J", "Cumulative energy brought in (+) or taken out (-) by payload joining "
                          "or leaving; E_p + E_kin + E_loss - W_drive - E_added is constant"),
)
# the FMU's output variables, one per Outputs field
OUTPUT_VARIABLES = output_variables(
    Outputs, Inputs,
    theta=ARM_OUTPUTS["theta"],
    omega=ARM_OUTPUTS["omega"],
    OB=variable("m", "Distance from O to the sliding counterweight B (eq. 13)"),
    tau_gravity=variable("N.m", "Gravity torque on the arm about O along theta, -dE_p/dtheta "
                                "= -(M_u + M_bar) when the fixed counterweight balances m c",
                         depends_on=("payload",)),
    E_p=ARM_OUTPUTS["E_p"],
    E_kin=ARM_OUTPUTS["E_kin"],
    M_g=ARM_OUTPUTS["M_g"],
    M_b=variable("N.m", "Moment of the counterweight's weight about O, m2 g OB cos(phi) "
                        "(eq. 12)"),
    M_u=ARM_OUTPUTS["M_u"],
    M_bar=variable("N.m", "Static moment about O of the bar AB's force on the counterweight, "
                          "m2 g (dOB/dphi) sin(phi) (omitted by the paper)"),
    W_drive=ARM_OUTPUTS["W_drive"],
    E_loss=ARM_OUTPUTS["E_loss"],
    E_added=ARM_OUTPUTS["E_added"],
)


outputs = kept_outputs(ledger_terms)


# Model Exchange: one smooth regime, no state events (a payload changes in event mode)
STATE_VARIABLES = state_variables(State, Outputs)   # every state is an output
EVENT_INDICATORS = ()
mode, event_indicators, event_update = no_mode, no_event_indicators, no_event_update
state_nominals = ledger.arm_state_nominals
