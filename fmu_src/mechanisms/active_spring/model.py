"""The active-spring balancer's data types, parameters, screw, spring, forces, outputs
(standard library only; the equations are in physics.py's docstring).

`physics` integrates the model over a communication step and keeps its energy ledger; it
takes from here what the `fmu_src.mechanism.Physics` protocol names (Parameters, Inputs, State,
Outputs, validate, initial_state, outputs)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

from fmu_src.integration import ledger_accuracy
from fmu_src.mechanism import input_variables, output_variables, variable
from fmu_src.memo import derive, slot
from fmu_src.parameters import check_ranges, parameter

DEG = math.pi / 180.0
# Tr 10x2 (ISO 2904): lead 2 mm on a pitch diameter of 9 mm
TR10X2_LEAD_ANGLE = math.atan(0.002 / (math.pi * 0.009))


@dataclass(frozen=True)
class Parameters:
    """Parameters of the mechanism. The paper gives no numbers for Fig. 8; the defaults put
    Franchetti's Table 1 link and spring on it (ours): the spring's link joint at the slider
    position b0 = 0.06 m, the frame joint above O at a = 0.1 m, which balances the bare link
    ((m c) g = k x1A Y_B0); a 0.5 kg carriage, damping 100 N s/m (time constant 5 ms).

    The screw: a Tr 10x2 (lead angle 4.05 deg) with mu = 0.1, steel on lubricated bronze:
    eta_f = 0.403, self-locking (README.md).

    Derived: carriage_inertia = m_q + m_drive_q, the inertia of the prismatic joint [kg];
    eta_forward and eta_backward, the screw's efficiencies (`screw_efficiencies`, the
    lossless limits at mu = 0) [1].
    """

    m: float = parameter(3.0, "kg", "Link mass (the paper's m1)", min=0.0)
    c: float = parameter(0.2, "m", "Distance from pivot O to the link centre of mass (OC1)",
                         min=0.0)
    J_link: float = parameter(0.16, "kg.m2", "Link moment of inertia about O (m L^2/3, "
                              "L = 0.4 m)", min=0.0)
    w: float = parameter(0.35, "m", "Distance from O to the payload (x1A for the paper's "
                         "payload at A)", min=0.0)
    x1A: float = parameter(0.06, "m", "Distance from O to the spring's link joint A", min=0.0,
                           min_exclusive=True)
    k: float = parameter(981.0, "N/m", "Spring stiffness", min=0.0, min_exclusive=True)
    F_s0: float = parameter(0.0, "N", "Spring force at the length l_s0 (eq. 19)", min=0.0)
    l_s0: float = parameter(0.0, "m", "Spring length at which the force is F_s0 (F_s0 = k "
                            "l_s0: zero-free-length spring)", min=0.0)
    X_B: float = parameter(0.0, "m", "Abscissa of the spring's frame joint B (the paper's "
                           "X_B is -X_B: its figure is mirrored)")
    Y_B0: float = parameter(0.1, "m", "Ordinate of the frame joint B at q = 0")
    m_q: float = parameter(0.5, "kg", "Mass of the carriage carrying B (moving part of the "
                           "prismatic joint)", min=0.0, min_exclusive=True)
    m_drive_q: float = parameter(0.0, "kg", "Drive inertia reflected to the prismatic joint "
                                 "(J_rotor N^2 of a lead screw, N = 2 pi / lead)", min=0.0)
    d_q: float = parameter(100.0, "N.s/m", "Viscous damping of the prismatic joint", min=0.0)
    self_locking: bool = parameter(True, None, "The screw holds any load that would drive "
                                   "it; with mu = 0 the ideal self-locking screw (lossless "
                                   "forward) or, false, a lossless back-drivable one; with "
                                   "mu > 0 it must equal friction angle >= lead angle")
    mu: float = parameter(0.1, "1", "Thread friction coefficient of the screw (steel on "
                          "bronze, lubricated); 0: lossless (self_locking picks the limit)",
                          min=0.0, max=0.5)
    lead_angle: float = parameter(TR10X2_LEAD_ANGLE, "rad", "Lead angle of the screw, "
                                  "atan(lead / (pi d2)) (Tr 10x2: 4.05 deg)", min=0.0,
                                  max=math.pi / 4, min_exclusive=True)
    flank_angle: float = parameter(15.0 * DEG, "rad", "Flank half-angle of the screw's thread "
                                   "(trapezoidal 15 deg, square 0)", min=0.0, max=math.pi / 6)
    d_link: float = parameter(0.01, "N.m.s/rad", "Viscous friction at the pivot", min=0.0)
    g: float = parameter(9.81, "m/s2", "Gravitational acceleration", min=0.0)
    theta0: float = parameter(60.0 * DEG, "rad", "Initial link angle from the upward vertical")
    omega0: float = parameter(0.0, "rad/s", "Initial link angular velocity")
    q0: float = parameter(0.0, "m", "Initial travel of the prismatic joint")
    q_dot0: float = parameter(0.0, "m/s", "Initial speed of the prismatic joint")
    J_drive: float = parameter(0.0, "kg.m2", "Drive inertia reflected to the link "
                               "(J_rotor N^2)", min=0.0)
    ledger_accuracy: float = ledger_accuracy()

    def __post_init__(self) -> None:
        # the derived constants and slots (fmu_src.memo): `outputs` keeps (state, l_s, F_s),
        # keyed by identity, for the next step's rate; `_payload_terms` keeps (payload,
        # inertia, moment, stage rates), keyed by equality; `_stage_rates` reads
        # _stage_constants, in one tuple
        carriage_inertia = self.m_q + self.m_drive_q
        if self.mu > 0.0:
            eta_forward, eta_backward = screw_efficiencies(self.mu, self.lead_angle,
                                                           self.flank_angle)
        else:
            eta_forward, eta_backward = 1.0, 0.0 if self.self_locking else 1.0
        derive(self, carriage_inertia=carriage_inertia, eta_forward=eta_forward,
               eta_backward=eta_backward, _kept_spring=slot((None, 0.0, 0.0)),
               _kept_payload=slot((None, 0.0, 0.0, None)), _stage_constants=(
                   self.X_B, self.x1A, -self.x1A, self.Y_B0, self.k, self.F_s0, self.l_s0,
                   self.d_link, self.d_q, carriage_inertia, self.m_q * self.g,
                   1.0 / eta_forward, eta_backward, eta_forward == eta_backward == 1.0))

    @property
    def free_length(self) -> float:
        """Length at which the spring force vanishes, l_s0 - F_s0 / k [m] (0: ideal spring)."""
        return self.l_s0 - self.F_s0 / self.k


def friction_angle(mu: float, flank_angle: float) -> float:
    """The thread's effective friction angle rho' = atan(mu / cos(flank_angle)) [rad]."""
    return math.atan(mu / math.cos(flank_angle))


def screw_efficiencies(mu: float, lead_angle: float, flank_angle: float) -> tuple[float, float]:
    """The screw's efficiencies [1], forward (the actuator drives the load)
    tan(lambda) / tan(lambda + rho') and backward (the load drives the actuator)
    tan(lambda - rho') / tan(lambda), for the friction coefficient mu, the lead angle lambda
    and the flank half-angle [rad]; backward <= 0: self-locking."""
    rho = friction_angle(mu, flank_angle)
    tan_lead = math.tan(lead_angle)
    return tan_lead / math.tan(lead_angle + rho), math.tan(lead_angle - rho) / tan_lead


def validate(params: Parameters) -> None:
    """Raise ValueError naming the first parameter that is NaN or outside its physical range,
    or a self_locking that contradicts the screw's friction."""
    check_ranges(params)
    if params.mu > 0.0 and params.self_locking != (params.eta_backward <= 0.0):
        rho = friction_angle(params.mu, params.flank_angle)
        raise ValueError(
            f"self_locking = {str(params.self_locking).lower()} contradicts the screw: its "
            f"friction angle atan(mu / cos(flank_angle)) = {rho / DEG:.4g} deg is "
            f"{'below' if rho < params.lead_angle else 'at least'} the lead angle "
            f"{params.lead_angle / DEG:.4g} deg (self-locking exactly when at least)")


class Inputs(NamedTuple):
    """Inputs held constant over a communication step."""

    tau_drive: float = 0.0  # N m, drive torque on the link
    F_adjust: float = 0.0   # N, actuator's force on the carriage along +q
    payload: float = 0.0    # kg, payload at distance w


# the FMU's input variables, one per Inputs field
INPUT_VARIABLES = input_variables(
    Inputs,
    tau_drive=variable("N.m", "Drive torque on the link about O"),
    F_adjust=variable("N", "Actuator's force on the screw along +q (upward): its torque times "
                           "2 pi / lead"),
    payload=variable("kg", "Payload mass at distance w", min=0.0),
)


# inputs whose change at a communication point is an event (switch_inputs)
EVENT_INPUTS = ("payload",)


class State(NamedTuple):
    """Positions and speeds, and the cumulative energies of the ledger [J]."""

    theta: float
    omega: float
    q: float
    q_dot: float
    W_drive: float = 0.0   # work of tau_drive on the link
    W_adjust: float = 0.0  # work of F_adjust on the screw
    E_loss: float = 0.0    # dissipated by d_link, d_q, the screw's friction, payload catches
    E_added: float = 0.0   # brought in (taken out) by payload changes


def initial_state(p: Parameters) -> State:
    """State at t = 0 from theta0, omega0, q0, q_dot0."""
    return State(p.theta0, p.omega0, p.q0, p.q_dot0)


def link_inertia(p: Parameters, payload: float) -> float:
    """J = J_link + payload w^2 + J_drive [kg m^2]."""
    return p.J_link + payload * p.w * p.w + p.J_drive


def gravity_moment(p: Parameters, payload: float) -> float:
    """(m c + payload w) g: gravity moment amplitude on the link [N m] (eq. 18 and 28)."""
    return (p.m * p.c + payload * p.w) * p.g


class Spring(NamedTuple):
    """The spring A-B at a configuration."""

    l_s: float          # length [m]
    F_s: float          # force, tension positive [N]
    tau: float          # torque on the link about O [N m]
    F_q: float          # pull on the carriage along +q [N]
    moment: float       # x1A Y_B F_s / l_s: the sin(theta) coefficient of -tau with X_B = 0 [N m]


def spring(p: Parameters, theta: float, Y_B: float) -> Spring:
    """Spring length, force, torque on the link and pull on the carriage (eqs. 19-21).

    At l_s = 0 (A on B) the direction is undefined; the force per length is then taken as
    its zero-free-length value k (exact when F_s0 = k l_s0, the only spring finite there).
    """
    return Spring._make(_spring(p, theta, Y_B))


def _spring(p: Parameters, theta: float, Y_B: float) -> tuple[float, float, float, float,
                                                              float]:
    """`spring` as a plain tuple in Spring's order (the integrator's stages need no names)."""
    sin_t, cos_t = math.sin(theta), math.cos(theta)
    dx = p.X_B + p.x1A * sin_t
    dy = Y_B - p.x1A * cos_t
    l_s = math.hypot(dx, dy)
    F_s = p.F_s0 + p.k * (l_s - p.l_s0)
    per_length = F_s / l_s if l_s > 0.0 else p.k
    return (l_s, F_s, -p.x1A * per_length * (Y_B * sin_t + p.X_B * cos_t),
            -per_length * dy, p.x1A * Y_B * per_length)


def tau_gravity(p: Parameters, payload: float, theta: float, Y_B: float) -> float:
    """Gravity plus spring torque on the link about O, -dV/dtheta [N m]."""
    return _tau_gravity(p, payload, theta, spring(p, theta, Y_B))


def _tau_gravity(p: Parameters, payload: float, theta: float, sp: Spring) -> float:
    """tau_gravity for the spring sp at theta."""
    return gravity_moment(p, payload) * math.sin(theta) + sp.tau


def balance_error(p: Parameters, payload: float, theta: float, Y_B: float) -> float:
    """(m c + payload w) g - x1A Y_B F_s / l_s [N m]: tau_gravity / sin(theta) when X_B = 0."""
    return gravity_moment(p, payload) - spring(p, theta, Y_B).moment


def carriage(p: Parameters, F_adjust: float, load: float, q_dot: float,
             direction: float) -> tuple[float, float]:
    """Acceleration of the carriage [m/s^2] and the screw's reaction F_lock [N], for the
    actuator's force F_adjust and the load L = F_q - m_q g along +q [N].

    direction: the sign of q_dot at the start of the integration sub-step, fixed over it so
    that its stages see one smooth law (0: from rest, the forces decide at each stage).
    """
    inverse_eta_forward, eta_backward = 1.0 / p.eta_forward, p.eta_backward
    if p.eta_forward == eta_backward == 1.0:     # lossless and back-drivable
        return (F_adjust + load - p.d_q * q_dot) / p.carriage_inertia, 0.0
    if direction == 0.0:
        direction = q_dot
    if direction == 0.0:     # at rest: does the net force break the screw loose?
        push = F_adjust + (load * inverse_eta_forward if load < 0.0 else load * eta_backward)
        if push <= 0.0:
            push = F_adjust + (load * inverse_eta_forward if load > 0.0 else
                               load * eta_backward)
            if push >= 0.0:
                return 0.0, -(F_adjust + load)
    else:
        push = F_adjust + (load * inverse_eta_forward if load * direction < 0.0 else
                           load * eta_backward)
    return (push - p.d_q * q_dot) / p.carriage_inertia, push - F_adjust - load


class Outputs(NamedTuple):
    """Observable quantities (SI units)."""

    theta: float
    omega: float
    q: float
    q_dot: float
    Y_B: float
    l_s: float
    F_s: float
    tau_gravity: float
    F_q: float
    F_lock: float
    F_hold: float
    balance_error: float
    E_p: float
    E_e: float
    E_t: float
    E_kin: float
    W_drive: float
    W_adjust: float
    E_loss: float
    E_added: float


# the FMU's output variables, one per Outputs field, with the inputs each reads directly in
# `outputs` (its ModelStructure dependencies; none: a function of the state alone)
OUTPUT_VARIABLES = output_variables(
    Outputs, Inputs,
    theta=variable("rad", "Link angle from the upward vertical, counter-clockwise positive"),
    omega=variable("rad/s", "Link angular velocity"),
    q=variable("m", "Travel of the prismatic joint along +y"),
    q_dot=variable("m/s", "Speed of the prismatic joint"),
    Y_B=variable("m", "Ordinate of the spring's frame joint B, Y_B0 + q"),
    l_s=variable("m", "Spring length A-B (eq. 21)"),
    F_s=variable("N", "Spring force F_s0 + k (l_s - l_s0), tension positive (eq. 19)"),
    tau_gravity=variable("N.m", "Gravity plus spring torque on the link about O, -dE_t/dtheta",
                         depends_on=("payload",)),
    F_q=variable("N", "Spring's force on the carriage along +q"),
    F_lock=variable("N", "Screw's reaction on the carriage along +q beyond F_adjust: holding it "
                         "at rest, its thread friction while it moves", depends_on=("F_adjust",)),
    F_hold=variable("N", "Least actuator force that holds the carriage at rest: 0 on a "
                         "self-locking screw, eta_b (m_q g - F_q) on a back-drivable one"),
    balance_error=variable("N.m", "(m c + payload w) g - x1A Y_B F_s / l_s; 0 when balanced "
                                  "(with X_B = 0, tau_gravity = balance_error sin(theta))",
                           depends_on=("payload",)),
    E_p=variable("J", "Gravitational potential energy of link, payload and carriage",
                 depends_on=("payload",)),
    E_e=variable("J", "Elastic energy of the spring, 1/2 k (l_s - l_s0 + F_s0/k)^2"),
    E_t=variable("J", "Total potential energy E_p + E_e", depends_on=("payload",)),
    E_kin=variable("J", "Kinetic energy of link, payload, carriage and both drive rotors",
                   depends_on=("payload",)),
    W_drive=variable("J", "Cumulative work of tau_drive on the link"),
    W_adjust=variable("J", "Cumulative work of F_adjust on the screw (the actuator's mechanical "
                           "work)"),
    E_loss=variable("J", "Energy dissipated so far (d_link, d_q, the screw's friction, payload "
                         "catches)"),
    E_added=variable("J", "Energy brought in (taken out) by payload changes"),
)


def elastic_energy(p: Parameters, l_s: float) -> float:
    """1/2 k (l_s - L_free)^2 [J], zero at the free length."""
    return 0.5 * p.k * (l_s - p.free_length) ** 2


def outputs(p: Parameters, u: Inputs, s: State) -> Outputs:
    """All outputs for the state s and inputs u."""
    theta, omega, q, q_dot, W_drive, W_adjust, E_loss, E_added = s
    Y_B = p.Y_B0 + q
    l_s, F_s, spring_torque, F_q, spring_moment = _spring(p, theta, Y_B)
    p._kept_spring[0] = (s, l_s, F_s)
    moment = gravity_moment(p, u.payload)
    E_p = moment * math.cos(theta) + p.m_q * p.g * Y_B
    E_e = elastic_energy(p, l_s)
    E_kin = 0.5 * (link_inertia(p, u.payload) * omega ** 2 + p.carriage_inertia * q_dot ** 2)
    F_adjust = u.F_adjust
    _, F_lock = carriage(p, F_adjust, F_q - p.m_q * p.g, q_dot, q_dot)
    # the least actuator force the screw holds the carriage with at rest
    F_hold = max(p.eta_backward, 0.0) * (p.m_q * p.g - F_q)
    # built at C level: Outputs(...) is a Python call
    return tuple.__new__(Outputs, (
        theta, omega, q, q_dot, Y_B, l_s, F_s, moment * math.sin(theta) + spring_torque, F_q,
        F_lock, F_hold, moment - spring_moment, E_p, E_e, E_p + E_e, E_kin, W_drive, W_adjust,
        E_loss, E_added))
