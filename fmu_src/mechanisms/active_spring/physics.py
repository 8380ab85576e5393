"""Physics of the spring balancer with an actively relocated frame joint (Ciupitu 2018, Fig. 8).

Pure model, standard library only: no FMI and no I/O. It is shared by the FMU slave
`ActiveSpringBalancer`, the harness command `active-design` and the tests. This module holds
the rates, the integration over a step (`advance`), the ledger terms and the payload event;
`model` holds the data types, parameters, the screw's and the spring's laws and the outputs.
Conventions of the project: theta from the upward vertical, counter-clockwise positive, unit
vector along the link e = (-sin theta, cos theta), gravity along -y, pivot O at the origin.

Geometry. The link carries its centre of mass at c e, the payload (kg) at w e and the
spring's link joint A at x1A e. The spring's frame joint B = (X_B, Y_B) with Y_B = Y_B0 + q
rides on a carriage of mass m_q, the moving part of a prismatic joint along the vertical, q
its travel. The spring force follows the paper's linear law (eqs. 19, 24)

    F_s = F_s0 + k (l_s - l_s0),   l_s = |B - A|                          (eq. 21)

at every length (F_s < 0 pushes); F_s0 = k l_s0 is a zero-free-length spring. Its energy,
with the free length L_free = l_s0 - F_s0 / k, is E_e = 1/2 k (l_s - L_free)^2.

Paper angle. Ciupitu measures the arm angle phi_1 from the horizontal; as for the
CiupituBalancer, the paper's figure is the project's mirrored left to right: phi_1 = pi/2 -
theta and the paper's X_B is -X_B here (Y is common). The payload at A (w = x1A) is the
paper's case; w is free here.

Lagrangian, with J = J_link + payload w^2 + J_drive and generalised coordinates (theta, q):

    T = 1/2 J omega^2 + 1/2 M_q q_dot^2,   M_q = m_q + m_drive_q
    V = E_p + E_e,   E_p = (m c + payload w) g cos(theta) + m_q g Y_B

    J omega' = tau_drive + tau_gravity - d_link omega,   tau_gravity = -dV/dtheta
    M_q q_dot' = F_adjust + L + F_lock - d_q q_dot,      L = F_q - m_q g = -dV/dq

with the spring's pull on the carriage along +q, F_q = -dE_e/dq = -F_s (Y_B - Y_A) / l_s, and
the torques about O

    tau_gravity = (m c + payload w) g sin(theta) - x1A F_s (Y_B sin(theta) + X_B cos(theta)) / l_s

The screw. The actuator's force F_adjust (its torque times 2 pi / lead, the force a lossless
screw would give) reaches the carriage through a screw with thread friction: lead angle
lambda, friction coefficient mu, flank half-angle beta, friction angle
rho' = atan(mu / cos(beta)) (`screw_efficiencies`):

    eta_f = tan(lambda) / tan(lambda + rho')     the actuator drives the load
    eta_b = tan(lambda - rho') / tan(lambda)     the load drives the actuator

and the screw self-locks exactly when rho' >= lambda (eta_b <= 0). The thread carries the
load L (spring and carriage weight; the rotor's inertia, lumped into M_q, and the guide's
damper d_q act beside it), so the actuator meets the effective load L_eff:
- moving against the load (L q_dot < 0): L_eff = L / eta_f;
- moving with the load (L q_dot > 0): L_eff = eta_b L (eta_b < 0: the actuator must push
  the carriage along, the screw absorbs the load; eta_b > 0: the load drives it);
- at rest: the carriage starts in the direction s = +-1 in which s (F_adjust + L_eff) > 0
  (at most one), else the screw holds it with F_lock = -(F_adjust + L): holding costs no power.
F_lock = L_eff - L is the screw's friction force on the carriage while it moves; its power
-F_lock q_dot >= 0 goes to E_loss. The regime changes only where q_dot = 0: a carriage whose
speed would change sign stops (its remaining kinetic energy, a sub-step's worth, goes to
E_loss) and starts again only if the forces break it loose.
Lossless limits, mu = 0: `self_locking` true is the ideal self-locking screw (eta_f = 1,
eta_b = 0: lossless forward, the load's power absorbed), a lower bound of a real screw's
cost; false a lossless back-drivable screw (eta_f = eta_b = 1). With mu > 0, `self_locking`
must state what the friction does (rho' >= lambda), `validate` checks it.
W_adjust = integral of F_adjust q_dot dt is the actuator's mechanical work. No stroke limits:
q is unbounded.

Balance. With X_B = 0, tau_gravity = balance_error sin(theta) exactly, where

    balance_error = (m c + payload w) g - x1A Y_B F_s / l_s                [N m]

is the paper's eq. 27 divided by cos(phi_1) (sign reversed: gravity minus spring); for a
zero-free-length spring (F_s / l_s = k) it is (m c + payload w) g - k x1A Y_B, so
Y_B = (m c + payload w) g / (k x1A) balances at every angle. With X_B != 0 the spring keeps
a torque at the vertical and balance_error is only the sin(theta) coefficient's part.

Payload changes (ledger). A payload that joins the link does so at rest at w e: angular
momentum is conserved (omega scales by J_before / J_after), the kinetic energy lost in
that inelastic catch goes to E_loss, and its potential energy on arrival, dm g w cos(theta),
to E_added. A payload that leaves takes its potential and kinetic energy with it (E_added
decreases by them). So E_t + E_kin + E_loss - W_drive - W_adjust - E_added stays constant,
with E_loss also counting the dampers d_link and d_q and the screw's friction.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING

from fmu_src import ledger
from fmu_src.integration import first_substeps, ledger_controlled, rk4_link_carriage_step
from fmu_src.mechanism import state_variables, variable, variable_named

# model.py holds the Physics protocol's data types, validate, initial_state and outputs:
# imported here because the harness and the slave call them as physics.<name>
from fmu_src.mechanisms.active_spring.model import (  # noqa: F401
    EVENT_INPUTS,
    INPUT_VARIABLES,
    OUTPUT_VARIABLES,
    Inputs,
    Outputs,
    Parameters,
    State,
    _spring,
    elastic_energy,
    gravity_moment,
    initial_state,
    link_inertia,
    outputs,
    validate,
)

# A moving carriage takes sub-steps this much finer than the rate rule of fmu_src.integration:
# its load (tens of newtons on a light carriage) multiplies its position error in the energy
# ledger (1e-9 J per millisecond at the rate rule, 1e-12 J with this factor).
CARRIAGE_ACCURACY = 4.0


def derivatives(p: Parameters, u: Inputs, s: State, rates: Inputs | None = None,
                mode: tuple[float, ...] | None = None) -> State:
    """Time derivative of the state for constant inputs (`rates`, d/dt of the inputs, as the
    other mechanisms take it: a payload changes only at events here, so it is not used);
    mode: (direction,), the screw's regime held through an RK4 sub-step or until the next
    event, as `carriage` takes it (its sign counts), () or None for that of s's q_dot."""
    direction = mode[0] if mode else None
    theta, omega, q, q_dot = s[:4]
    if direction is None:
        direction = q_dot
    omega_dot, q_ddot, loss_rate = _payload_terms(p, u.payload)[2](
        theta, omega, q, q_dot, direction, u.tau_drive, u.F_adjust)
    return State(omega, omega_dot, q_dot, q_ddot, u.tau_drive * omega, u.F_adjust * q_dot,
                 loss_rate, 0.0)


if TYPE_CHECKING:   # annotations only: Python 3.8 cannot subscript tuple and Callable
    StageRates = Callable[[float, float, float, float, float, float, float],
                         tuple[float, float, float]]


def _payload_terms(p: Parameters, payload: float) -> tuple[float, float, StageRates]:
    """The link's inertia [kg m^2] and gravity moment [N m] (`link_inertia`,
    `gravity_moment`) and the stage rates (`_stage_rates`) for the payload [kg], kept with
    the parameters while the payload stays the same (equal floats give the same terms)."""
    kept = p._kept_payload[0]
    if kept[0] != payload:
        inertia, moment = link_inertia(p, payload), gravity_moment(p, payload)
        kept = p._kept_payload[0] = (payload, inertia, moment,
                                     _stage_rates(p, inertia, moment))
    return kept[1], kept[2], kept[3]


def _stage_rates(p: Parameters, inertia: float, moment: float) -> StageRates:
    """The rates an RK4 stage needs, (omega', q_dot'', E_loss') as a function of theta,
    omega, q, q_dot, the carriage's direction (as for `carriage`), tau_drive and F_adjust,
    for the link's inertia [kg m^2] and gravity moment [N m] (`link_inertia`,
    `gravity_moment`); the other rates follow (theta' = omega, q' = q_dot, W_drive' =
    tau_drive omega, W_adjust' = F_adjust q_dot, E_added' = 0).

    `_spring`, the torque and `carriage` written out operation for operation, with the terms
    that only the parameters and the payload set read once: one call per stage.
    """
    sin, cos, hypot = math.sin, math.cos, math.hypot
    (X_B, x1A, neg_x1A, Y_B0, k, F_s0, l_s0, d_link, d_q, M_q, weight_q, inverse_eta_forward,
     eta_backward, lossless) = p._stage_constants

    def rates(theta: float, omega: float, q: float, q_dot: float, direction: float,
              tau_drive: float, F_adjust: float) -> tuple[float, float, float]:
        Y_B = Y_B0 + q
        sin_t, cos_t = sin(theta), cos(theta)
        dy = Y_B - x1A * cos_t
        l_s = hypot(X_B + x1A * sin_t, dy)
        F_s = F_s0 + k * (l_s - l_s0)
        per_length = F_s / l_s if l_s > 0.0 else k
        torque = moment * sin_t + neg_x1A * per_length * (Y_B * sin_t + X_B * cos_t)
        omega_dot = (tau_drive + torque - d_link * omega) / inertia
        load = -per_length * dy - weight_q
        if lossless:
            q_ddot, lock = (F_adjust + load - d_q * q_dot) / M_q, 0.0
        else:
            moving, held = direction if direction != 0.0 else q_dot, False
            if moving == 0.0:      # at rest: upwards, else downwards, else held
                push = F_adjust + (load * inverse_eta_forward if load < 0.0 else
                                   load * eta_backward)
                if push <= 0.0:
                    push = F_adjust + (load * inverse_eta_forward if load > 0.0 else
                                       load * eta_backward)
                    held = push >= 0.0
            else:
                push = F_adjust + (load * inverse_eta_forward if load * moving < 0.0 else
                                   load * eta_backward)
            if held:
                q_ddot, lock = 0.0, -(F_adjust + load)
            else:
                q_ddot, lock = (push - d_q * q_dot) / M_q, push - F_adjust - load
        return omega_dot, q_ddot, d_link * omega * omega + d_q * q_dot * q_dot - lock * q_dot

    return rates


def characteristic_rate(p: Parameters, u: Inputs, s: State) -> float:
    """Fastest rate of the local dynamics [1/s]: sets the internal integration step."""
    return _rate(p, u, s, link_inertia(p, u.payload), gravity_moment(p, u.payload))


def _rate(p: Parameters, u: Inputs, s: State, J: float, moment: float) -> float:
    """`characteristic_rate` for the link's inertia J [kg m^2] and gravity moment [N m] of
    the step (`link_inertia`, `gravity_moment`); the larger of two rates by comparison (as
    `max` takes it) instead of a call."""
    kept_state, l_s, F_s = p._kept_spring[0]
    if kept_state is not s:     # `outputs` keeps the spring of the state a step starts from
        l_s, F_s = _spring(p, s.theta, p.Y_B0 + s.q)[:2]
    reach = p.x1A + math.hypot(p.X_B, p.Y_B0 + s.q)
    per_length = abs(F_s) / l_s if l_s > 0.0 else p.k
    stiffness = abs(moment) + p.x1A * reach * (p.k + per_length)
    rate = math.sqrt(stiffness / J)
    damping_rate, speed = p.d_link / J, abs(s.omega)
    if damping_rate > rate:
        rate = damping_rate
    if speed > rate:
        rate = speed
    if s.q_dot != 0.0 or u.F_adjust != 0.0 or p.eta_backward > 0.0:   # the carriage moves
        M_q = p.carriage_inertia
        # the screw's friction scales the spring's stiffness the carriage meets by 1 / eta_f
        carriage_rate = max(p.d_q / M_q,
                            math.sqrt((p.k + per_length) / p.eta_forward / M_q),
                            abs(s.q_dot) / max(l_s, p.x1A))
        rate = max(rate, CARRIAGE_ACCURACY * carriage_rate)
    return rate


def advance(p: Parameters, u: Inputs, s: State, dt: float) -> State:
    """Integrate over one communication step dt [s] with inputs held constant: RK4 sub-steps
    from the rate rule, raised until the energy ledger meets p.ledger_accuracy
    (`integration.ledger_controlled`).

    A carriage whose speed changes sign within a sub-step stops (but on the lossless
    back-drivable screw, whose law is smooth there): the sub-step is split where the speed,
    interpolated linearly, reaches zero; there the carriage is at rest (the kinetic energy of
    the interpolation's residual speed goes to E_loss) and the rest of the sub-step starts
    from rest, where the screw holds it or the forces break it loose.
    """
    inertia, moment, rates = _payload_terms(p, u.payload)
    return ledger_controlled(lambda n: _integrate(p, u, s, dt, n, rates),
                             partial(ledger_terms, p, u), (4, 5), s,
                             first_substeps(dt, _rate(p, u, s, inertia, moment)), dt, p,
                             (u.payload,))


def _stop_carriage(p: Parameters, s: State) -> State:
    """The carriage stopped where its speed changed sign: q_dot = 0, the kinetic energy of
    its residual speed to E_loss."""
    return s._replace(q_dot=0.0, E_loss=s.E_loss + 0.5 * p.carriage_inertia * s.q_dot ** 2)


def _integrate(p: Parameters, u: Inputs, s: State, dt: float, n: int, rates: StageRates
               ) -> State:
    """`advance` over dt [s] in n RK4 sub-steps, for the stage rates of the payload."""
    h = dt / n
    tau_drive, F_adjust = u.tau_drive, u.F_adjust
    lossless = p._stage_constants[-1]
    for _ in range(n):
        new = rk4_link_carriage_step(rates, tau_drive, F_adjust, s, h)
        if not lossless and new.q_dot * s.q_dot < 0.0:
            h_stop = h * s.q_dot / (s.q_dot - new.q_dot)
            stopped = _stop_carriage(p, rk4_link_carriage_step(rates, tau_drive, F_adjust, s,
                                                                h_stop))
            new = rk4_link_carriage_step(rates, tau_drive, F_adjust, stopped, h - h_stop)
        s = new
    return s


def ledger_terms(p: Parameters, u: Inputs, s: State) -> tuple[float, ...]:
    """The signed terms of the energy ledger [J], E_t (E_p, E_e), E_kin, E_loss, -W_drive,
    -W_adjust and -E_added (as `outputs` reports them): their sum is constant
    (docs/energy_ledger.md)."""
    theta, omega, q, q_dot, W_drive, W_adjust, E_loss, E_added = s
    inertia, moment = _payload_terms(p, u.payload)[:2]
    Y_B = p.Y_B0 + q
    l_s = _spring(p, theta, Y_B)[0]
    return (moment * math.cos(theta) + p.m_q * p.g * Y_B, elastic_energy(p, l_s),
            0.5 * (inertia * omega ** 2 + p.carriage_inertia * q_dot ** 2), E_loss, -W_drive,
            -W_adjust, -E_added)


def switch_inputs(p: Parameters, before: Inputs, after: Inputs, s: State) -> State:
    """The state just after the inputs change at a communication point: a payload caught
    from rest or released with its speed (`ledger.change_payload`)."""
    return ledger.change_payload(s, before.payload, after.payload, p.w, p.g,
                                 lambda payload: link_inertia(p, payload))


# ---- Model Exchange: the carriage's stops as state events ---------------------------------
STATE_VARIABLES = state_variables(State, Outputs)   # every state is an output
EVENT_INDICATORS = (
    variable_named("carriage_stops", variable(
        "m/s", "q_dot times the direction the carriage moves in on a screw that is not "
        "lossless and back-drivable: it stops where this reaches 0 (1 m/s while it rests)")),
)


def mode(p: Parameters, u: Inputs, s: State) -> tuple[int, ...]:
    """(the carriage's direction: +1 up, -1 down, 0 at rest), whose screw law `advance`
    holds through each RK4 sub-step; () on a lossless back-drivable screw, whose law is
    smooth."""
    if _lossless(p):
        return ()
    return (1 if s.q_dot > 0.0 else -1 if s.q_dot < 0.0 else 0,)


def event_indicators(p: Parameters, u: Inputs, s: State, mode: tuple[int, ...]
                     ) -> tuple[float]:
    """The EVENT_INDICATORS: q_dot times the direction held (from rest the screw's law is
    continuous as the carriage breaks loose: no event)."""
    return (s.q_dot * mode[0] if mode and mode[0] != 0 else 1.0,)


def event_update(p: Parameters, u: Inputs, s: State, mode: tuple[int, ...]) -> State:
    """A moving carriage whose speed reached zero stops (`_stop_carriage`, as `advance`
    stops it within a sub-step)."""
    if mode and mode[0] != 0 and s.q_dot * mode[0] <= 0.0:
        return _stop_carriage(p, s)
    return s


def state_nominals(p: Parameters) -> tuple[float, ...]:
    """1 rad and 1 rad/s for the link, 0.1 m and 0.1 m/s for the carriage, 1 J for the
    energies."""
    return (1.0, 1.0, 0.1, 0.1, 1.0, 1.0, 1.0, 1.0)


def _lossless(p: Parameters) -> bool:
    """A lossless back-drivable screw (eta_forward = eta_backward = 1)."""
    return p.eta_forward == p.eta_backward == 1.0


