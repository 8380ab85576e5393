"""Physics of the self-regulating spring balancer (Franchetti, Boschetti, Lenzo 2021).

Pure model, standard library only: no FMI and no I/O. It is shared by the FMU slave
`SelfRegulatingBalancer`, the harness and the tests. Conventions are those of SPEC.md
section 2: theta from the upward vertical, counter-clockwise positive, unit vector along
the link e = (-sin theta, cos theta), gravity along -y.

Generalised coordinates: the link angle theta and the slider position b along the link.
The counterweight hangs from the pulley of radius R; while the pulley turns it moves
(R/r) times the slider travel, so its descent s_cw is a state too (it carries E_cw).

Lagrangian, with J0 = J_link + payload w^2 + J_drive and M_cw = M0 + counterweight_added:

    T = 1/2 (J0 + m_slider b^2) omega^2 + 1/2 (m_slider + M_cw (R/r)^2 [pulley free]) v^2
    V = (m c + payload w + m_slider b) g cos(theta) + 1/2 k (x - L0)^2 - M_cw g s_cw

    (J0 + m_slider b^2) omega' = tau_drive + tau_gravity - d_link omega - 2 m_slider b v omega
    m_eff v' = m_slider b omega^2 - m_slider g cos(theta) - F_t + T_wire - d_slider v

with T_wire = M_cw g R / r while the pulley turns (0 when it is locked). A massless slider
with the pulley locked (m_eff = 0) has first-order dynamics d_slider v = F_net.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

from fmu_src.integration import integrate, integrate_second_order
from fmu_src.parameters import check_ranges, parameter

DEG = math.pi / 180.0


@dataclass(frozen=True)
class Parameters:
    """Parameters of the mechanism; defaults are the paper's Table 1 plus our documented choices.

    Not in the paper (ours): J_link = m L^2 / 3 with L = 2 c = 0.4 m (uniform rod about O),
    m_slider = 0, L0 = 0 (ideal spring), b_min = 0 (slider at the pivot), b_max = w (eq. 15),
    d_link = 0.01 N m s/rad (small bearing friction), d_slider = 500 N s/m (near critical:
    2 sqrt(k M0 (R/r)^2) = 469 N s/m with no payload, 517 N s/m with 1 kg added).
    """

    m: float = parameter(3.0, "kg", "Link mass", min=0.0)
    c: float = parameter(0.2, "m", "Distance from pivot O to the link centre of mass C", min=0.0)
    J_link: float = parameter(0.16, "kg.m2", "Link moment of inertia about O (m L^2/3, L = 0.4 m)",
                              min=0.0, min_exclusive=True)
    a: float = parameter(0.1, "m", "Distance from O to the frame spring anchor A", min=0.0,
                         min_exclusive=True)
    b0: float = parameter(0.06, "m", "Initial slider position along the link (O to B)", min=0.0)
    w: float = parameter(0.35, "m", "Distance from O to the payload W", min=0.0, min_exclusive=True)
    k: float = parameter(981.0, "N/m", "Spring stiffness", min=0.0)
    L0: float = parameter(0.0, "m", "Spring free length (0: ideal zero-free-length spring)",
                          min=0.0)
    R: float = parameter(0.035, "m", "Radius of the pulley carrying the counterweight", min=0.0,
                         min_exclusive=True)
    r: float = parameter(0.01, "m", "Radius of the pulley carrying the slider wire", min=0.0,
                         min_exclusive=True)
    m_slider: float = parameter(0.0, "kg", "Slider mass", min=0.0)
    b_min: float = parameter(0.0, "m", "Inner end stop of the slider", min=0.0)
    b_max: float = parameter(0.35, "m", "Outer end stop of the slider (default w, eq. 15)", min=0.0)
    d_link: float = parameter(0.01, "N.m.s/rad", "Viscous friction at the pivot", min=0.0)
    d_slider: float = parameter(500.0, "N.s/m", "Viscous damping of the slider on the link",
                                min=0.0)
    g: float = parameter(9.81, "m/s2", "Gravitational acceleration", min=0.0,
                         min_exclusive=True)
    theta0: float = parameter(60.0 * DEG, "rad", "Initial link angle from the upward vertical")
    omega0: float = parameter(0.0, "rad/s", "Initial link angular velocity")
    J_drive: float = parameter(0.0, "kg.m2", "Drive inertia reflected to the link (J_rotor N^2)",
                               min=0.0)

    @cached_property
    def M0(self) -> float:
        """Counterweight mass that holds the slider at b0 with theta = pi, eq. 10 [kg]."""
        return self.k * (self.a + self.b0) * self.r / (self.g * self.R) if self.g > 0 else 0.0

    @cached_property
    def payload_max(self) -> float:
        """Largest payload the slider travel up to w can balance, eq. 16 [kg]."""
        return self.k * self.a * (self.w - self.b0) / (self.w * self.g) if self.g > 0 else math.inf

    @cached_property
    def pulley_ratio(self) -> float:
        """Counterweight travel per unit slider travel, R/r (design value w/a, eq. 13)."""
        return self.R / self.r


def validate(params: Parameters) -> None:
    """Raise ValueError naming the first parameter that is NaN or outside its physical range."""
    check_ranges(params)
    if not params.b_min < params.b_max:
        raise ValueError(f"b_min = {params.b_min} m must be below b_max = {params.b_max} m")
    if not params.b_min <= params.b0 <= params.b_max:
        raise ValueError(f"b0 = {params.b0} m is outside [b_min, b_max] = "
                         f"[{params.b_min}, {params.b_max}] m")


class Inputs(NamedTuple):
    """Inputs held constant over a communication step."""

    tau_drive: float = 0.0          # N m, drive torque on the link
    payload: float = 0.0            # kg, payload at distance w
    counterweight_added: float = 0.0  # kg, mass added to the counterweight M0
    slider_locked: bool = True
    pulley_locked: bool = True


class State(NamedTuple):
    """Continuous state: link angle and speed, slider position and speed, counterweight descent."""

    theta: float
    omega: float
    b: float
    v: float
    s_cw: float = 0.0


def initial_state(params: Parameters) -> State:
    """State at t = 0: link at theta0, omega0, slider at rest at b0."""
    return State(params.theta0, params.omega0, params.b0, 0.0, 0.0)


def spring_length(p: Parameters, theta: float, b: float) -> float:
    """Distance A-B, eq. 4 [m]."""
    return math.sqrt(max(p.a * p.a + b * b - 2.0 * p.a * b * math.cos(theta), 0.0))


def _free_length_factor(p: Parameters, theta: float, b: float) -> float:
    """(1 - L0/x): scales the zero-free-length force laws to a spring of free length L0.

    x is computed only when L0 > 0: the ideal spring needs no square root per evaluation.
    """
    return 1.0 - p.L0 / spring_length(p, theta, b) if p.L0 > 0.0 else 1.0


def gravity_moment(p: Parameters, payload: float, b: float) -> float:
    """(m c + payload w + m_slider b) g: gravity moment amplitude on the link [N m]."""
    return (p.m * p.c + payload * p.w + p.m_slider * b) * p.g


def wire_tension(p: Parameters, u: Inputs) -> float:
    """Pull of the counterweight wire on the slider, outward along the link [N]."""
    if u.pulley_locked:
        return 0.0
    return (p.M0 + u.counterweight_added) * p.g * p.pulley_ratio


def slider_mass(p: Parameters, u: Inputs) -> float:
    """Effective mass of the slider, with the counterweight reflected through the pulley [kg]."""
    if u.pulley_locked:
        return p.m_slider
    return p.m_slider + (p.M0 + u.counterweight_added) * p.pulley_ratio ** 2


def link_inertia(p: Parameters, payload: float, b: float) -> float:
    """J = J_link + payload w^2 + m_slider b^2 + J_drive [kg m^2]."""
    return p.J_link + payload * p.w * p.w + p.m_slider * b * b + p.J_drive


def _slider_force(p: Parameters, u: Inputs, theta: float, omega: float, b: float, v: float,
                  factor: float) -> float:
    """Net force along the link on the slider, outward positive, excluding its inertia [N].

    factor is _free_length_factor(p, theta, b).
    """
    spring = p.k * (b - p.a * math.cos(theta)) * factor
    return (p.m_slider * (b * omega * omega - p.g * math.cos(theta)) - spring
            + wire_tension(p, u) - p.d_slider * v)


def _at_stop(p: Parameters, b: float, push: float) -> bool:
    """True when the slider rests on an end stop and the load pushes it into that stop."""
    return (b <= p.b_min and push <= 0.0) or (b >= p.b_max and push >= 0.0)


def _link_acceleration(p: Parameters, u: Inputs, theta: float, omega: float, b: float,
                       v: float) -> float:
    """Angular acceleration of the link with the slider at b moving at v along it [rad/s^2]."""
    sin_t = math.sin(theta)
    spring_torque = p.k * p.a * b * sin_t * _free_length_factor(p, theta, b)
    coriolis = 2.0 * p.m_slider * b * v * omega
    return (u.tau_drive + gravity_moment(p, u.payload, b) * sin_t - spring_torque
            - p.d_link * omega - coriolis) / link_inertia(p, u.payload, b)


def derivatives(p: Parameters, u: Inputs, s: State) -> tuple[float, ...]:
    """Time derivative of the state for constant inputs, in State's field order.

    A plain tuple, not a State: this runs four times per RK4 step and a NamedTuple costs more.
    """
    theta, omega, b, v, _ = s
    omega_dot = _link_acceleration(p, u, theta, omega, b, v)
    if u.slider_locked:
        return (omega, omega_dot, 0.0, 0.0, 0.0)
    m_eff = slider_mass(p, u)
    force = _slider_force(p, u, theta, omega, b, v, _free_length_factor(p, theta, b))
    if m_eff > 0.0:
        if _at_stop(p, b, force if v == 0.0 else v):
            return (omega, omega_dot, 0.0, 0.0, 0.0)
        b_dot, v_dot = v, force / m_eff
    else:
        # Massless slider: d_slider v = F_spring + T (v eliminated, kept as an output).
        b_dot = (force + p.d_slider * v) / p.d_slider
        if _at_stop(p, b, b_dot):
            b_dot = 0.0
        v_dot = 0.0
    s_cw_dot = 0.0 if u.pulley_locked else p.pulley_ratio * b_dot
    return (omega, omega_dot, b_dot, v_dot, s_cw_dot)


def characteristic_rate(p: Parameters, u: Inputs, s: State) -> float:
    """Fastest rate of the local dynamics [1/s]: sets the internal integration step."""
    J = link_inertia(p, u.payload, s.b)
    stiffness = abs(gravity_moment(p, u.payload, s.b)) + p.k * p.a * (abs(s.b) + p.a)
    rate = max(math.sqrt(stiffness / J), p.d_link / J, abs(s.omega))
    if not u.slider_locked:
        m_eff = slider_mass(p, u)
        k_b = p.k + p.m_slider * s.omega ** 2
        if m_eff > 0.0:
            rate = max(rate, math.sqrt(k_b / m_eff), p.d_slider / m_eff)
        else:
            rate = max(rate, k_b / p.d_slider)
    return rate


def _apply_constraints(p: Parameters, u: Inputs, s: State) -> State:
    """Clamp the slider to its end stops (inelastic) and hold it still when locked."""
    theta, omega, b, v, s_cw = s
    if u.slider_locked:
        return State(theta, omega, b, 0.0, s_cw)
    if b < p.b_min:
        return State(theta, omega, p.b_min, max(v, 0.0), s_cw)
    if b > p.b_max:
        return State(theta, omega, p.b_max, min(v, 0.0), s_cw)
    if slider_mass(p, u) == 0.0:
        # Massless slider: its speed is the damper speed set by the forces.
        v = _slider_force(p, u, theta, omega, b, 0.0, _free_length_factor(p, theta, b)) / p.d_slider
        if _at_stop(p, b, v):
            v = 0.0
    return State(theta, omega, b, v, s_cw)


def advance(p: Parameters, u: Inputs, s: State, dt: float) -> State:
    """Integrate over one communication step dt [s] with inputs held constant."""
    rate = characteristic_rate(p, u, s)
    if u.slider_locked:
        # A clamped slider leaves a 1-DOF link: b and s_cw stay put and v = 0. RK4 over the
        # link alone gives the same numbers as over the full state (whose other derivatives
        # are zero) at less than half the cost of a step.
        b = s.b
        theta, omega = integrate_second_order(
            lambda theta, omega: _link_acceleration(p, u, theta, omega, b, 0.0),
            s.theta, s.omega, dt, rate)
        return State(theta, omega, b, 0.0, s.s_cw)
    return integrate(lambda state: derivatives(p, u, state), s, dt, rate,
                     lambda state: _apply_constraints(p, u, state))


def slider_at_stop(p: Parameters, u: Inputs, s: State) -> bool:
    """True when the free slider rests on b_min or b_max."""
    return not u.slider_locked and (s.b <= p.b_min or s.b >= p.b_max)


def regulated_slider_position(p: Parameters, u: Inputs, theta: float) -> float:
    """Static equilibrium of a free slider at angle theta with the pulley turning [m].

    Solves F_t(theta, b) = T_wire + m_slider g (-cos theta) for b (bisection on the monotonic
    spring force), clipped to the end stops. With L0 = 0 and theta = pi this is
    b0 + payload w g / (k a) (eq. 8) when counterweight_added equals the payload.
    """
    def net(b: float) -> float:
        if spring_length(p, theta, b) == 0.0:
            return 1.0
        return _slider_force(p, u, theta, 0.0, b, 0.0, _free_length_factor(p, theta, b))
    lo, hi = p.b_min, p.b_max
    if net(lo) <= 0.0:
        return lo
    if net(hi) >= 0.0:
        return hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if net(mid) > 0.0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


class Outputs(NamedTuple):
    """Observable quantities of SPEC section 3 (SI units)."""

    theta: float
    omega: float
    b: float
    delta_b: float
    x: float
    F_t: float
    F_n: float
    tau_gravity: float
    balance_error: float
    E_p: float
    E_e: float
    E_t: float
    E_cw: float
    E_kin: float
    slider_at_stop: bool


def outputs(p: Parameters, u: Inputs, s: State) -> Outputs:
    """All outputs for the state s and inputs u."""
    theta, omega, b, v, s_cw = s
    sin_t, cos_t = math.sin(theta), math.cos(theta)
    x = spring_length(p, theta, b)
    factor = _free_length_factor(p, theta, b)
    moment = gravity_moment(p, u.payload, b)
    E_p = moment * cos_t
    E_e = 0.5 * p.k * (x - p.L0) ** 2
    E_cw = -(p.M0 + u.counterweight_added) * p.g * s_cw
    mass = slider_mass(p, u) if not u.slider_locked else p.m_slider
    E_kin = 0.5 * link_inertia(p, u.payload, b) * omega ** 2 + 0.5 * mass * v ** 2
    F_t = p.k * (b - p.a * cos_t) * factor
    F_n = p.k * p.a * sin_t * factor
    tau_gravity = (moment - p.k * p.a * b * factor) * sin_t
    balance_error = moment - p.k * p.a * b
    # Positional, in field order: keyword arguments would add a microsecond to every step.
    return Outputs(theta, omega, b, b - p.b0, x, F_t, F_n, tau_gravity, balance_error,
                   E_p, E_e, E_p + E_e, E_cw, E_kin, slider_at_stop(p, u, s))

