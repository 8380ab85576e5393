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
from functools import partial

from fmu_src import ledger
from fmu_src.integration import first_substeps, ledger_controlled, rk4

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
    carriage,
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
                direction: float | None = None) -> State:
    """Time derivative of the state for constant inputs (`rates`, d/dt of the inputs, as the
    other mechanisms take it: a payload changes only at events here, so it is not used);
    direction as for `carriage` (the screw's regime held through an RK4 sub-step), None for
    that of s's q_dot."""
    theta, omega, q, q_dot = s[:4]
    tau_drive, F_adjust, payload = u
    _, _, spring_torque, F_q, _ = _spring(p, theta, p.Y_B0 + q)
    omega_dot = ((tau_drive + (gravity_moment(p, payload) * math.sin(theta) + spring_torque)
                  - p.d_link * omega) / link_inertia(p, payload))
    q_ddot, lock = carriage(p, F_adjust, F_q - p.m_q * p.g, q_dot,
                            q_dot if direction is None else direction)
    return State(omega, omega_dot, q_dot, q_ddot, tau_drive * omega, F_adjust * q_dot,
                 p.d_link * omega * omega + p.d_q * q_dot * q_dot - lock * q_dot, 0.0)


def characteristic_rate(p: Parameters, u: Inputs, s: State) -> float:
    """Fastest rate of the local dynamics [1/s]: sets the internal integration step."""
    J, moment = link_inertia(p, u.payload), gravity_moment(p, u.payload)
    l_s, F_s = _spring(p, s.theta, p.Y_B0 + s.q)[:2]
    reach = p.x1A + math.hypot(p.X_B, p.Y_B0 + s.q)
    per_length = abs(F_s) / l_s if l_s > 0.0 else p.k
    stiffness = abs(moment) + p.x1A * reach * (p.k + per_length)
    rate = max(math.sqrt(stiffness / J), p.d_link / J, abs(s.omega))
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
    return ledger_controlled(lambda n: _integrate(p, u, s, dt, n),
                             partial(ledger_terms, p, u), (4, 5), s,
                             first_substeps(dt, characteristic_rate(p, u, s)), dt, p,
                             (u.payload,))


def _carriage_step(p: Parameters, u: Inputs, s: State, h: float) -> State:
    """One RK4 sub-step of h [s] from s with the screw's regime of s held (`derivatives`'
    direction: that of s's q_dot)."""
    return rk4(partial(derivatives, p, u, direction=s.q_dot), s, h)


def _integrate(p: Parameters, u: Inputs, s: State, dt: float, n: int) -> State:
    """`advance` over dt [s] in n RK4 sub-steps."""
    h = dt / n
    lossless = p.eta_forward == p.eta_backward == 1.0
    for _ in range(n):
        new = _carriage_step(p, u, s, h)
        if not lossless and new.q_dot * s.q_dot < 0.0:
            h_stop = h * s.q_dot / (s.q_dot - new.q_dot)
            stopped = _carriage_step(p, u, s, h_stop)
            stopped = stopped._replace(
                q_dot=0.0,
                E_loss=stopped.E_loss + 0.5 * p.carriage_inertia * stopped.q_dot ** 2)
            new = _carriage_step(p, u, stopped, h - h_stop)
        s = new
    return s


def ledger_terms(p: Parameters, u: Inputs, s: State) -> tuple[float, ...]:
    """The signed terms of the energy ledger [J], E_t (E_p, E_e), E_kin, E_loss, -W_drive,
    -W_adjust and -E_added (as `outputs` reports them): their sum is constant
    (docs/energy_ledger.md)."""
    theta, omega, q, q_dot, W_drive, W_adjust, E_loss, E_added = s
    inertia, moment = link_inertia(p, u.payload), gravity_moment(p, u.payload)
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


