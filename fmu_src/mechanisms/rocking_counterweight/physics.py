"""Physics of Ciupitu's rocking counterweight (Ciupitu 2018, Figure 4b).

Pure model, standard library only: no FMI and no I/O. It is shared by the FMU slave
`RockingCounterweightBalancer`, the harness (`ciupitu-example`, the design in
`harness.design.rocking_counterweight`) and the tests. The derivation is in
README.md. This module holds the arm's dynamics; `statics` the linkage (the counterweight's
position and its derivatives), its static moments and the paper's stroke.

Geometry, in the paper's frame XOY (X horizontal towards the payload's side, Y up: the
project's frame mirrored, X = -x, docs/conventions.md) and the paper's arm angle
phi = pi/2 - theta. The arm (1) turns about O; its own frame has x_1 along the arm towards
the payload P and y_1 across it, upwards when the arm is horizontal. The counterweight bar
(2) is pivoted on the arm at A = (x1A, y1A) (arm frame); bar (3), of length BC, ties its
point B (AB from A) to the ground pivot C = (XC, YC). O-A-B-C is a four-bar linkage whose
crank is the arm; the counterweight, a point mass m2 (weight G2 = m2 g), sits on bar 2 at the
signed distance AC2 from A along A -> B (the coupler point). With u(a) = (cos a, sin a):

    A = R(phi) (x1A, y1A),   B = A + AB u(beta) = C + BC u(delta),   P = A + AC2 u(beta)

beta follows from the triangle A-B-C (law of cosines); `B_left` picks which of its two
mirror images (B on the left or the right of the line A -> C). Differentiating the loop
closure with respect to phi (A' = perp(A), A'' = -A, s = sin(delta - beta)):

    beta'  = -A'.u(delta) / (AB s),   delta' = -A'.u(beta) / (BC s)
    beta'' = (AB beta'^2 cos(beta - delta) - BC delta'^2 - A''.u(delta)) / (AB s)
    P'  = A' + AC2 beta' perp(u(beta)),   P'' = A'' + AC2 (beta'' perp(u(beta)) - beta'^2 u(beta))

The triangle A-B-C never flattens (s != 0) at any arm angle when
|AB - BC| < |OA - OC| and OA + OC < AB + BC (OA, OC: distances of A and C from O), because
the distance AC then stays strictly between |AB - BC| and AB + BC: every arm angle is then
reachable, as with the translational counterweight, and `validate` requires it.

Moments about O, the paper's sign (positive towards increasing phi). The paper gives no
formula for the rocking counterweight's moment; here it is the whole moment the counterweight
and its bars exert on the arm, from virtual work (the translational model's M_b + M_bar):

    M_g = -G_pv OP cos phi,   M_b = -G2 dY_P/dphi,   M_u = M_b + M_g

Dynamics (one degree of freedom, FMU state theta and omega): the link (m at c, J_link about
O), a payload (kg) at w = OP, a fixed counterweight m_fixed_cw at c_fixed_cw opposite the
payload, and the counterweight m2 at P (bars massless, the counterweight a point mass):

    E_p = g (sin(phi) (m c + payload w - m_fixed_cw c_fixed_cw) + m2 Y_P)
    J(phi) = J_link + payload w^2 + m_fixed_cw c_fixed_cw^2 + J_drive + m2 |P'|^2
    J omega' = tau_drive + tau_gravity - d_link omega - 1/2 (dJ/dtheta) omega^2

from the Lagrangian E_kin - E_p with E_kin = 1/2 J omega^2, tau_gravity = -dE_p/dtheta =
dE_p/dphi and dJ/dtheta = -2 m2 P'.P''. The energy ledger (W_drive, E_loss, E_added) and the
payload events follow the project's other mechanisms: a payload added is picked up from rest
(J omega conserved), a payload removed leaves with its own speed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields
from functools import partial
from typing import Any, NamedTuple

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
from fmu_src.mechanisms.ciupitu import physics as ciupitu
from fmu_src.mechanisms.rocking_counterweight.statics import (
    HALF_PI,
    Geometry,
    Linkage,
    _moments,
    check_linkage,
    geometry,
)
from fmu_src.memo import derive, slot
from fmu_src.parameters import check_ranges, parameter

# ---- dynamics for the FMU ---------------------------------------------------------------
_ARM = {f.name: f for f in fields(ciupitu.Parameters)}


def _as_translational(name: str) -> Any:
    """The translational counterweight's declaration of an arm parameter (one source)."""
    f = _ARM[name]
    meta = f.metadata
    return parameter(f.default, meta["unit"], meta["description"], min=meta["min"],
                     max=meta["max"], min_exclusive=meta["min_exclusive"])


@dataclass(frozen=True)
class Parameters:
    """Parameters of the arm and the linkage.

    The arm (link, payload distance, fixed counterweight, friction, drive) is
    CiupituBalancer's, with its defaults. The linkage defaults are placeholders: the
    parabolic design of the paper's example (harness.design.rocking_counterweight) scaled, as
    CiupituBalancer's bar, to a 1 kg payload at w = 0.35 m (lengths by w/OP = 0.175, m2 by
    1 kg g / G_max).
    """

    m: float = _as_translational("m")
    c: float = _as_translational("c")
    J_link: float = _as_translational("J_link")
    w: float = _as_translational("w")
    m2: float = parameter(0.75, "kg", "Mass of the rocking counterweight (G2/g)", min=0.0)
    x1A: float = parameter(-0.029334375, "m", "Pivot A of the counterweight bar on the arm, "
                           "along the arm towards the payload")
    y1A: float = parameter(-0.0143332, "m", "Pivot A of the counterweight bar on the arm, across "
                           "it (upwards when the arm is horizontal)")
    XC: float = parameter(0.00174965, "m", "Ground pivot C of bar 3, horizontal towards the "
                          "payload's side (the paper's X = -x)")
    YC: float = parameter(0.006236125, "m", "Ground pivot C of bar 3, height above O")
    AB: float = parameter(0.02297925, "m", "Length of the counterweight bar from A to the joint B "
                          "with bar 3", min=0.0, min_exclusive=True)
    BC: float = parameter(0.0175, "m", "Length of bar 3, from B to the ground pivot C",
                          min=0.0, min_exclusive=True)
    AC2: float = parameter(-0.299018125, "m", "Position of the counterweight on its bar, from A "
                           "along A -> B (signed)")
    B_left: bool = parameter(False, None, "Assembly: B on the left of the line from A to C "
                             "(paper's frame), else on its right")
    m_fixed_cw: float = _as_translational("m_fixed_cw")
    c_fixed_cw: float = _as_translational("c_fixed_cw")
    d_link: float = _as_translational("d_link")
    g: float = _as_translational("g")
    theta0: float = _as_translational("theta0")
    omega0: float = _as_translational("omega0")
    J_drive: float = _as_translational("J_drive")
    ledger_accuracy: float = ledger_accuracy()

    def __post_init__(self) -> None:
        # (fmu_src.memo) the linkage fields as one Linkage, which the dynamics read at every
        # evaluation; the slots of `_arm_terms`, (theta, payload, terms) keyed by identity,
        # and of `ledger_terms`, (state, inputs, outputs) for `outputs`
        derive(self, linkage=Linkage.of(self), _last_terms=slot((None, None, ())),
               _kept_outputs=slot((None, None, None)))

    @property
    def J_fixed(self) -> float:
        """The arm's inertia without payload and counterweight [kg m^2]."""
        return self.J_link + self.J_drive + self.m_fixed_cw * self.c_fixed_cw ** 2


def validate(params: Parameters) -> None:
    """Raise ValueError naming the first parameter that is NaN or outside its physical range,
    or a linkage that cannot move through every arm angle."""
    check_ranges(params)
    check_linkage(Linkage.of(params))
    if not params.J_fixed > 0.0:
        raise ValueError(f"J_link + J_drive + m_fixed_cw c_fixed_cw^2 = {params.J_fixed} kg.m2 "
                         "must be positive: the arm needs inertia at every angle")


class Inputs(NamedTuple):
    """Inputs held constant over a communication step."""

    tau_drive: float = 0.0    # N m, drive torque on the arm (counter-clockwise, along theta)
    payload: float = 0.0      # kg, payload at distance w


# the FMU's input variables: the Ciupitu arm's
INPUT_VARIABLES = input_variables(Inputs, **{v.name: v for v in ciupitu.INPUT_VARIABLES})


# inputs whose change at a communication point is an event (switch_inputs)
EVENT_INPUTS = ("payload",)


class State(NamedTuple):
    """Arm angle from the upward vertical [rad] and its rate [rad/s], and the energy ledger
    [J] (E_p + E_kin + E_loss - W_drive - E_added is constant)."""

    theta: float
    omega: float
    W_drive: float = 0.0    # work of tau_drive on the arm
    E_loss: float = 0.0     # dissipated: pivot friction, payload picked up while moving
    E_added: float = 0.0    # brought in (+) or taken out (-) by payload joining or leaving


def initial_state(params: Parameters) -> State:
    """State at t = 0."""
    return State(params.theta0, params.omega0)


def _inertia(p: Parameters, payload: float, q: Geometry) -> tuple[float, float]:
    """J [kg m^2] and dJ/dtheta [kg m^2/rad] at the counterweight geometry q."""
    J = p.J_fixed + payload * p.w ** 2 + p.m2 * (q.dX * q.dX + q.dY * q.dY)
    return J, -2.0 * p.m2 * (q.dX * q.d2X + q.dY * q.d2Y)


def _arm_moment(p: Parameters, payload: float) -> float:
    """m c + payload w - m_fixed_cw c_fixed_cw [kg m]: the arm's E_p is g sin(phi) times it."""
    return p.m * p.c + payload * p.w - p.m_fixed_cw * p.c_fixed_cw


def _arm_terms(p: Parameters, payload: float, theta: float
               ) -> tuple[Geometry, float, float, float]:
    """(geometry, J [kg m^2], dJ/dtheta [kg m^2/rad], tau_gravity [N m]) at theta with the
    payload [kg]; the last ones kept with the parameters, as `ciupitu._arm_terms` keeps its."""
    last = p._last_terms[0]
    if last[0] is theta and last[1] is payload:
        return last[2]
    q = geometry(p.linkage, HALF_PI - theta)
    J, dJ = _inertia(p, payload, q)
    terms = (q, J, dJ, p.g * (math.sin(theta) * _arm_moment(p, payload) + p.m2 * q.dY))
    p._last_terms[0] = (theta, payload, terms)   # one assignment: key and terms together
    return terms


def inertia(p: Parameters, payload: float, theta: float) -> tuple[float, float]:
    """J(theta) [kg m^2] and dJ/dtheta [kg m^2/rad]."""
    return _arm_terms(p, payload, theta)[1:3]


def potential_energy(p: Parameters, payload: float, theta: float) -> float:
    """E_p [J], zero at the height of O."""
    q = geometry(p.linkage, HALF_PI - theta)
    return p.g * (math.cos(theta) * _arm_moment(p, payload) + p.m2 * q.Y)


def tau_gravity(p: Parameters, payload: float, theta: float) -> float:
    """Gravity torque on the arm about O along theta, -dE_p/dtheta [N m]."""
    q = geometry(p.linkage, HALF_PI - theta)
    return p.g * (math.sin(theta) * _arm_moment(p, payload) + p.m2 * q.dY)


def acceleration(p: Parameters, payload: float, tau_drive: float, theta: float,
                 omega: float) -> float:
    """Angular acceleration [rad/s^2] from the Lagrange equation
    J theta'' + 1/2 (dJ/dtheta) omega^2 = tau_drive + tau_gravity - d_link omega."""
    return _arm_rates(p, payload, tau_drive)(theta, omega)[0]


def _arm_rates(p: Parameters, payload: float, tau_drive: float
               ) -> Callable[[float, float], tuple[float, float]]:
    """(theta, omega) -> (the angular acceleration [rad/s^2] (`acceleration`), the pivot's
    friction loss d_link omega^2 [W]) with the payload and the drive torque held.

    It runs four times per RK4 sub-step: the terms the parameters and the payload set are
    computed once, and _arm_terms is written out, operation for operation (the same numbers;
    tests/test_rocking.py checks it). At the angle _arm_terms computed last (the step's
    start) it takes its terms.
    Measured against `_arm_terms` called per stage (with integrate_arm and the slots): the
    three save 153 k of 390 k instructions per FMU step (payload ramping), far above 10 % of
    a closed-loop step (fmu_src/integration.py).
    """
    k, m2, g, d_link = p.linkage, p.m2, p.g, p.d_link
    J_held = p.J_fixed + payload * p.w ** 2
    arm = _arm_moment(p, payload)
    last_theta, last = ciupitu.kept_start(p._last_terms, payload)

    def rates(theta: float, omega: float) -> tuple[float, float]:
        if theta is last_theta:
            _, J, dJ, gravity = last
        else:
            _, _, dX, dY, d2X, d2Y, _ = geometry(k, HALF_PI - theta)
            J = J_held + m2 * (dX * dX + dY * dY)
            dJ = -2.0 * m2 * (dX * d2X + dY * d2Y)
            gravity = g * (math.sin(theta) * arm + m2 * dY)
        return ((tau_drive + gravity - d_link * omega - 0.5 * dJ * omega * omega) / J,
                d_link * omega * omega)

    return rates


# d/dt of the state, for constant or continuously changing inputs (docs/energy_ledger.md)
derivatives = ledger.payload_derivatives(_arm_rates, inertia, State)


def characteristic_rate(p: Parameters, u: Inputs, s: State) -> float:
    """Fastest rate of the local dynamics [1/s]: sets the internal integration step."""
    q, J, dJ, _ = _arm_terms(p, u.payload, s.theta)
    stiffness = p.g * (p.m * p.c + u.payload * p.w + p.m_fixed_cw * p.c_fixed_cw
                       + p.m2 * math.hypot(q.d2X, q.d2Y))
    return max(math.sqrt(stiffness / J), p.d_link / J, abs(s.omega) * (1.0 + abs(dJ) / J))


def advance(p: Parameters, u: Inputs, s: State, dt: float) -> State:
    """Integrate over one communication step dt [s] with inputs held constant."""
    tau = u.tau_drive
    rate = characteristic_rate(p, u, s)    # first: its terms at s.theta serve the first stage
    return advance_arm(_arm_rates(p, u.payload, tau), s, tau, dt, rate,
                       partial(ledger_terms, p, u), p, u.payload)


def ledger_terms(p: Parameters, u: Inputs, s: State) -> tuple[float, ...]:
    """The signed terms of the energy ledger [J]: E_p in its three parts (the link with its
    payload, the fixed counterweight, the rocking counterweight), E_kin, E_loss, -W_drive and
    -E_added (as `outputs` reports them): their sum is constant (docs/energy_ledger.md). E_p
    goes in parts so that the ledger's rounding allowance (which scales with the sum of
    |term|) sees the moments that cancel in it: with the fixed counterweight balancing the
    bare link, E_p near theta = 0 is the difference of two terms of g m c, whose rounding a
    step of a small throughput could not meet otherwise. The outputs come with them, from
    the same energies, kept for `outputs` (the end of a step is evaluated once, for the
    ledger's control and the slave)."""
    theta, payload, g, m2 = s.theta, u.payload, p.g, p.m2
    q, _, _, gravity = _arm_terms(p, payload, theta)
    M = _moments(payload * g, p.w, m2 * g, q.dY, math.sin(theta))  # sin(theta) = cos(phi)
    E_p, E_kin = mechanical_energies(p, payload, s)
    W_drive, E_loss, E_added = s.W_drive, s.E_loss, s.E_added
    # In field order, built by tuple.__new__: Outputs(...) with keywords is a costly call.
    p._kept_outputs[0] = (s, u, tuple.__new__(Outputs, (
        theta, s.omega, gravity, E_p, E_kin,
        *M, q.X, q.Y, q.psi,                            # M_g, M_b, M_u, X_cw, Y_cw, psi
        W_drive, E_loss, E_added)))
    lever = g * math.cos(theta)
    return (lever * (p.m * p.c + payload * p.w), -lever * (p.m_fixed_cw * p.c_fixed_cw),
            g * m2 * q.Y, E_kin, E_loss, -W_drive, -E_added)


def mechanical_energies(p: Parameters, payload: float, s: State) -> tuple[float, float]:
    """E_p and E_kin [J] (as `outputs` reports them)."""
    theta = s.theta
    q, J, _, _ = _arm_terms(p, payload, theta)
    return (p.g * (math.cos(theta) * _arm_moment(p, payload) + p.m2 * q.Y),
            0.5 * J * s.omega ** 2)


def mechanical_energy(p: Parameters, payload: float, s: State) -> float:
    """E_p + E_kin [J] (as `outputs` reports them)."""
    E_p, E_kin = mechanical_energies(p, payload, s)
    return E_p + E_kin


# a payload caught from rest or released at a communication point (docs/energy_ledger.md)
switch_inputs = ledger.payload_switch(inertia)



class Outputs(NamedTuple):
    """Observable quantities (README.md; SI units)."""

    theta: float
    omega: float
    tau_gravity: float
    E_p: float
    E_kin: float
    M_g: float
    M_b: float
    M_u: float
    X_cw: float
    Y_cw: float
    psi: float
    W_drive: float
    E_loss: float
    E_added: float


# the FMU's output variables, one per Outputs field (ciupitu.ARM_OUTPUTS: every arm's)
OUTPUT_VARIABLES = output_variables(
    Outputs, Inputs,
    theta=ciupitu.ARM_OUTPUTS["theta"],
    omega=ciupitu.ARM_OUTPUTS["omega"],
    tau_gravity=variable("N.m", "Gravity torque on the arm about O along theta, -dE_p/dtheta "
                                "= -M_u when the fixed counterweight balances m c",
                         depends_on=("payload",)),
    E_p=ciupitu.ARM_OUTPUTS["E_p"],
    E_kin=ciupitu.ARM_OUTPUTS["E_kin"],
    M_g=ciupitu.ARM_OUTPUTS["M_g"],
    M_b=variable("N.m", "Moment of the rocking counterweight and its bars about O, -m2 g "
                        "dY_cw/dphi (paper's sign)"),
    M_u=ciupitu.ARM_OUTPUTS["M_u"],
    X_cw=variable("m", "Counterweight position, horizontal towards the payload's side (the "
                       "paper's X = -x)"),
    Y_cw=variable("m", "Counterweight height above O"),
    psi=variable("rad", "Angle of the counterweight bar (A -> B) from the arm, counter-clockwise "
                        "in the paper's frame"),
    W_drive=ciupitu.ARM_OUTPUTS["W_drive"],
    E_loss=ciupitu.ARM_OUTPUTS["E_loss"],
    E_added=ciupitu.ARM_OUTPUTS["E_added"],
)


outputs = kept_outputs(ledger_terms)


# Model Exchange: one smooth regime, no state events (a payload changes in event mode)
STATE_VARIABLES = state_variables(State, Outputs)   # every state is an output
EVENT_INDICATORS = ()
mode, event_indicators, event_update = no_mode, no_event_indicators, no_event_update
state_nominals = ledger.arm_state_nominals
