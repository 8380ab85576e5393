"""The self-regulating spring balancer's data types, parameters, forces, energies, outputs and
energy-ledger terms (standard library only; the equations are in physics.py's docstring).

`physics` integrates the model over a communication step and maps it across input events; it
takes from here what the `fmu_src.mechanism.Physics` protocol names (Parameters, Inputs, State,
Outputs, validate, initial_state, outputs, ledger_terms)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

from fmu_src.integration import kept_outputs, ledger_accuracy
from fmu_src.mechanism import input_variables, output_variables, variable
from fmu_src.mechanisms.self_regulating.design import (
    _free_length_factor,
    _wire_pull,
    design_slider_position,
    gravity_moment,
    spring_length,
)
from fmu_src.memo import derive, slot
from fmu_src.parameters import DomainError, check_ranges, parameter

DEG = math.pi / 180.0
_new = tuple.__new__  # a NamedTuple from a tuple of its fields, without a Python call


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
    mu_slider: float = parameter(0.0, "1", "Coulomb friction coefficient of the slider on the "
                                 "link (normal force from the spring's F_n and the slider's "
                                 "weight)", min=0.0)
    J_pulley: float = parameter(0.0, "kg.m2", "Moment of inertia of the compound pulley",
                                min=0.0)
    d_pulley: float = parameter(0.0, "N.m.s/rad", "Viscous friction of the pulley's bearing",
                                min=0.0)
    g: float = parameter(9.81, "m/s2", "Gravitational acceleration", min=0.0,
                         min_exclusive=True)
    theta0: float = parameter(60.0 * DEG, "rad", "Initial link angle from the upward vertical")
    omega0: float = parameter(0.0, "rad/s", "Initial link angular velocity")
    J_drive: float = parameter(0.0, "kg.m2", "Drive inertia reflected to the link (J_rotor N^2)",
                               min=0.0)
    paper_design: bool = parameter(
        False, None, "M0 and payload_max from eqs. 10 and 16 as printed (ideal spring, massless "
        "slider), whatever L0 and m_slider: the paper's design, for comparison")
    ledger_accuracy: float = ledger_accuracy()

    @cached_property
    def b_design(self) -> float:
        """Slider position M0 holds at theta = pi: design_slider_position (b0 for Table 1,
        eq. 2), or where eq. 10's M0 holds it with paper_design [m]."""
        if self.paper_design:
            return self.M0 * self.g * self.R / (self.r * self.k) - self.a + self.L0 + (
                self.m_slider * self.g / self.k) if self.k > 0.0 else self.b0
        return design_slider_position(self)

    @cached_property
    def M0(self) -> float:
        """Counterweight mass that holds the slider at b_design with theta = pi [kg]:
        (k (a + b_design - L0) - m_slider g) r / (g R), eq. 10 when L0 = m_slider = 0 and
        b0 balances the link (0 if the spring cannot hold the slider's weight there)."""
        if self.g <= 0:
            return 0.0
        if self.paper_design:
            return self.k * (self.a + self.b0) * self.r / (self.g * self.R)
        return max(_wire_pull(self, self.b_design), 0.0) * self.r / (self.g * self.R)

    @cached_property
    def payload_max(self) -> float:
        """Largest payload whose regulation at theta = pi (the same mass added to the
        counterweight) keeps the slider within b_max: k r (b_max - b_design) / (g R) [kg].
        Eq. 16 when R/r = w/a, b_max = w and b_design = b0 (at theta = pi the spring force
        grows by k per metre of slider travel, whatever L0)."""
        if self.g <= 0:
            return math.inf
        if self.paper_design:
            return self.k * self.a * (self.w - self.b0) / (self.w * self.g)
        return self.k * (self.b_max - self.b_design) * self.r / (self.g * self.R)

    @cached_property
    def pulley_ratio(self) -> float:
        """Counterweight travel per unit slider travel, R/r (design value w/a, eq. 13)."""
        return self.R / self.r

    def __post_init__(self) -> None:
        # the slots (fmu_src.memo) of `_link_terms`, ((payload, b), terms) keyed by equality,
        # two entries, the latest first (a locked slider and a held payload repeat them at
        # every step; a payload event reads them before and after it); of `ledger_terms`,
        # (state, inputs, outputs) keyed by identity, for `outputs` of the very same state
        # and inputs (the end of a step: the ledger's control evaluates it, then the slave
        # reads its outputs)
        derive(self, _link_memo=slot(((math.nan, math.nan), ()), 2),
               _kept_outputs=slot((None, None, None)))


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


# the FMU's input variables, one per Inputs field
INPUT_VARIABLES = input_variables(
    Inputs,
    tau_drive=variable("N.m", "Drive torque on the link about O"),
    payload=variable("kg", "Payload mass at distance w (the paper's delta m)", min=0.0),
    counterweight_added=variable(
        "kg", "Mass added to the counterweight M0 (same as the payload when regulating)"),
    slider_locked=variable(None, "Slider clamped to the link (db/dt = 0)"),
    pulley_locked=variable(
        None, "Pulley locked to the frame: counterweight idle, slider wire unloaded"),
)


# inputs whose change at a communication point is an event (switch_inputs)
EVENT_INPUTS = ("payload", "counterweight_added", "slider_locked", "pulley_locked")


class State(NamedTuple):
    """Continuous state: link angle and speed, slider position and speed, counterweight descent,
    and the energy ledger [J]."""

    theta: float
    omega: float
    b: float
    v: float
    s_cw: float = 0.0
    W_drive: float = 0.0    # work of tau_drive on the link
    E_loss: float = 0.0     # dissipated: dampers, end-stop impacts, lock events, pick-ups
    E_added: float = 0.0    # brought in (+) or taken out (-) by masses joining or leaving


def initial_state(params: Parameters) -> State:
    """State at t = 0: link at theta0, omega0, slider at rest at b0, empty ledger."""
    return State(params.theta0, params.omega0, params.b0, 0.0)


def wire_tension(p: Parameters, u: Inputs) -> float:
    """Pull of the counterweight wire on the slider, outward along the link [N]."""
    if u.pulley_locked:
        return 0.0
    return (p.M0 + u.counterweight_added) * p.g * p.pulley_ratio


def slider_mass(p: Parameters, u: Inputs) -> float:
    """Effective mass of the slider, with the counterweight and the pulley reflected through
    the pulley (it turns at v / r) [kg]."""
    if u.pulley_locked:
        return p.m_slider
    return (p.m_slider + (p.M0 + u.counterweight_added) * p.pulley_ratio ** 2
            + p.J_pulley / (p.r * p.r))


def _free_slider_inertia(p: Parameters, u: Inputs) -> tuple[float, float]:
    """(slider_mass, slider_damping) of the released slider; DomainError naming m_slider and
    d_slider when both vanish, since nothing then determines its motion."""
    m_eff, damping = slider_mass(p, u), slider_damping(p, u)
    if m_eff == 0.0 and damping == 0.0:
        raise DomainError(
            f"the released slider has neither mass nor damping (m_slider = {p.m_slider} "
            f"kg{' with the pulley locked' if u.pulley_locked else ''}, d_slider = "
            f"{p.d_slider} N.s/m): its motion is undefined; set m_slider > 0 or d_slider > 0")
    return m_eff, damping


def slider_damping(p: Parameters, u: Inputs) -> float:
    """Viscous damping of the slider, with the pulley's bearing reflected while it turns
    [N s/m]."""
    return p.d_slider if u.pulley_locked else p.d_slider + p.d_pulley / (p.r * p.r)


def slider_friction(p: Parameters, theta: float, factor: float) -> float:
    """Coulomb friction force limit mu_slider |F_n - m_slider g sin(theta)| on the slider [N]
    (the spring's and the weight's components normal to the link); factor is
    _free_length_factor(p, theta, b)."""
    if p.mu_slider == 0.0:
        return 0.0
    return p.mu_slider * abs((p.k * p.a * factor - p.m_slider * p.g) * math.sin(theta))


def link_inertia(p: Parameters, payload: float, b: float) -> float:
    """J = J_link + payload w^2 + m_slider b^2 + J_drive [kg m^2]."""
    return p.J_link + payload * p.w * p.w + p.m_slider * b * b + p.J_drive


def _slider_force(p: Parameters, theta: float, omega: float, b: float, v: float,
                  factor: float, pull: float, damping: float) -> float:
    """Net force along the link on the slider, outward positive, excluding its inertia [N].

    factor is _free_length_factor(p, theta, b), pull wire_tension(p, u) and damping
    slider_damping(p, u) (constant while the inputs are held).
    """
    spring = p.k * (b - p.a * math.cos(theta)) * factor
    return p.m_slider * (b * omega * omega - p.g * math.cos(theta)) - spring + pull - damping * v


def _at_stop(p: Parameters, b: float, push: float) -> bool:
    """True when the slider rests exactly on an end stop and the load pushes it into that stop.

    A state beyond a stop (inside an RK4 sub-step) is integrated freely and clamped after the
    sub-step: holding it there would mix two right-hand sides in one RK4 step and spoil the
    energy balance."""
    return (b == p.b_min and push <= 0.0) or (b == p.b_max and push >= 0.0)


def _slip(p: Parameters, b: float, v: float, force: float, friction: float) -> float:
    """Friction state of a slider with mass at speed v under the net force [N]: 0 when it
    sticks (at rest, the force within the friction limit or into a stop), else the direction
    it slides in."""
    if v != 0.0:
        return math.copysign(1.0, v)
    if abs(force) <= friction or _at_stop(p, b, force):
        return 0.0
    return math.copysign(1.0, force)


def _creep_speed(pull: float, friction: float, damping: float) -> float:
    """Speed of a massless slider under the net pull [N] (damper excluded) against Coulomb
    friction up to `friction` [N] and viscous damping [N s/m]: 0 while it sticks."""
    if abs(pull) <= friction:
        return 0.0
    return (pull - math.copysign(friction, pull)) / damping


def _link_terms(p: Parameters, payload: float, b: float) -> tuple[float, ...]:
    """(gravity_moment [N m], link_inertia J [kg m^2], the spring's moment amplitude k a b
    [N m], the fastest rate of the link's own dynamics but for its speed [1/s], and the
    outputs' terms balance_error = gravity_moment - k a b [N m], delta_b = b - b0 [m],
    a^2 + b^2 and 2 a b [m^2] of the spring length) with the slider at b: constant while the
    slider is locked and the payload held, so the last ones are kept with the parameters and
    reused (the same numbers as computed afresh)."""
    memo = p._link_memo
    key, terms = memo[0]
    if key[0] == payload and key[1] == b:
        return terms
    key, terms = memo[1]
    if key[0] == payload and key[1] == b:
        return terms
    moment, J = gravity_moment(p, payload, b), link_inertia(p, payload, b)
    stiffness = abs(moment) + p.k * p.a * (abs(b) + p.a)
    spring = p.k * p.a * b
    terms = (moment, J, spring, max(math.sqrt(stiffness / J), p.d_link / J),
             # outputs' terms of the slider position alone
             moment - spring, b - p.b0, p.a * p.a + b * b, 2.0 * p.a * b)
    memo[1] = memo[0]
    memo[0] = ((payload, b), terms)  # one assignment: key and terms change together
    return terms


def mechanical_energy(p: Parameters, u: Inputs, s: State) -> float:
    """E_t + E_cw + E_kin [J] (as `outputs` reports them)."""
    return _mechanical_energy(p, u, s, p.m_slider if u.slider_locked else slider_mass(p, u))


def _mechanical_energy(p: Parameters, u: Inputs, s: State, mass: float) -> float:
    """mechanical_energy with the slider's effective mass [kg] known."""
    E_p, E_e, E_cw, E_link, E_slider = _mechanical_energies(p, u, s, mass)
    return E_p + E_e + E_cw + E_link + E_slider


def _mechanical_energies(p: Parameters, u: Inputs, s: State, mass: float
                         ) -> tuple[float, float, float, float, float]:
    """The link's potential, the spring's, the counterweight's and the kinetic energies of
    link and slider [J], for the slider's effective mass [kg]."""
    theta, omega, b, v, s_cw = s[:5]
    moment, J = _link_terms(p, u.payload, b)[:2]
    return (moment * math.cos(theta), 0.5 * p.k * (spring_length(p, theta, b) - p.L0) ** 2,
            -(p.M0 + u.counterweight_added) * p.g * s_cw, 0.5 * J * omega ** 2,
            0.5 * mass * v * v)


def _damper_speed(p: Parameters, u: Inputs, s: State) -> float:
    """Speed of a free massless slider with the pulley locked, set by the forces [m/s]."""
    factor, damping = _free_length_factor(p, s.theta, s.b), _free_slider_inertia(p, u)[1]
    v = _creep_speed(_slider_force(p, s.theta, s.omega, s.b, 0.0, factor, wire_tension(p, u),
                                   damping),
                     slider_friction(p, s.theta, factor), damping)
    return 0.0 if _at_stop(p, s.b, v) else v


def _friction_state(p: Parameters, u: Inputs, s: State) -> float:
    """_slip of the free slider in state s."""
    factor = _free_length_factor(p, s.theta, s.b)
    force = _slider_force(p, s.theta, s.omega, s.b, s.v, factor, wire_tension(p, u),
                          slider_damping(p, u))
    return _slip(p, s.b, s.v, force, slider_friction(p, s.theta, factor))


def slider_at_stop(p: Parameters, u: Inputs, s: State) -> bool:
    """True when the free slider rests on b_min or b_max."""
    return not u.slider_locked and (s.b <= p.b_min or s.b >= p.b_max)


class Outputs(NamedTuple):
    """Observable quantities (README.md; SI units)."""

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
    W_drive: float
    E_loss: float
    E_added: float


# the FMU's output variables, one per Outputs field, with the inputs each reads directly in
# `outputs` (its ModelStructure dependencies; none: a function of the state alone)
OUTPUT_VARIABLES = output_variables(
    Outputs, Inputs,
    theta=variable("rad", "Link angle from the upward vertical, counter-clockwise positive"),
    omega=variable("rad/s", "Link angular velocity"),
    b=variable("m", "Slider position along the link (O to B)"),
    delta_b=variable("m", "Slider displacement from b0"),
    x=variable("m", "Spring length A-B (eq. 4)"),
    F_t=variable("N", "Spring force on the slider along the link, towards O"),
    F_n=variable("N", "Spring force on the slider normal to the link"),
    tau_gravity=variable("N.m", "Gravity plus spring torque on the link about O, -dE_t/dtheta",
                         depends_on=("payload",)),
    balance_error=variable("N.m", "(m c + payload w + m_slider b) g - k a b; 0 when balanced",
                           depends_on=("payload",)),
    E_p=variable("J", "Gravitational potential energy of link, payload and slider",
                 depends_on=("payload",)),
    E_e=variable("J", "Elastic energy of the spring"),
    E_t=variable("J", "Total potential energy E_p + E_e", depends_on=("payload",)),
    E_cw=variable("J", "Potential energy of the counterweight relative to its start",
                  depends_on=("counterweight_added",)),
    # the slider's effective mass includes the counterweight's while slider and pulley are free
    E_kin=variable("J", "Kinetic energy of link, payload, drive rotor, slider and counterweight",
                   depends_on=("payload", "counterweight_added", "slider_locked",
                               "pulley_locked")),
    slider_at_stop=variable(None, "Free slider resting on an end stop (b_min or b_max)",
                            depends_on=("slider_locked",)),
    W_drive=variable("J", "Cumulative work of tau_drive on the link"),
    E_loss=variable("J", "Cumulative energy dissipated: dampers, end-stop impacts, lock events, "
                         "masses picked up while moving"),
    E_added=variable("J", "Cumulative energy brought in (+) or taken out (-) by payload and "
                          "counterweight mass joining or leaving; E_t + E_cw + E_kin + E_loss - "
                          "W_drive - E_added is constant"),
)


def ledger_terms(p: Parameters, u: Inputs, s: State) -> tuple[float, ...]:
    """The signed terms of the energy ledger [J], E_t + E_cw + E_kin (in parts), E_loss,
    -W_drive and -E_added (as `outputs` reports them): their sum is constant
    (docs/energy_ledger.md). The outputs come with them, from the same energies, kept for
    `outputs` (the end of a step is evaluated once, for the ledger's control and the slave)."""
    theta, omega, b, v, s_cw, W_drive, E_loss, E_added = s
    _, payload, counterweight_added, slider_locked, _ = u
    sin_t, cos_t = math.sin(theta), math.cos(theta)
    moment, J, spring, _, balance_error, delta_b, a2_b2, two_a_b = _link_terms(p, payload, b)
    x2 = a2_b2 - two_a_b * cos_t
    x = math.sqrt(0.0 if 0.0 > x2 else x2)  # spring_length (max(x2, 0.0) without its call)
    factor = 1.0 - p.L0 / x if p.L0 > 0.0 else 1.0  # _free_length_factor, x known
    E_p = moment * cos_t
    E_e = 0.5 * p.k * (x - p.L0) ** 2
    E_cw = -(p.M0 + counterweight_added) * p.g * s_cw
    mass = p.m_slider if slider_locked else slider_mass(p, u)
    E_link = 0.5 * J * omega ** 2
    E_kin = E_link + 0.5 * mass * v ** 2
    F_t = p.k * (b - p.a * cos_t) * factor
    F_n = p.k * p.a * sin_t * factor
    tau_gravity = (moment - spring * factor) * sin_t
    at_stop = not slider_locked and (b <= p.b_min or b >= p.b_max)  # slider_at_stop
    # Built by tuple.__new__ in field order: Outputs(...) would add a Python call per step.
    out = _new(Outputs, (theta, omega, b, delta_b, x, F_t, F_n, tau_gravity, balance_error,
                         E_p, E_e, E_p + E_e, E_cw, E_kin, at_stop, W_drive, E_loss, E_added))
    p._kept_outputs[0] = (s, u, out)
    return E_p, E_e, E_cw, E_link, 0.5 * mass * v * v, E_loss, -W_drive, -E_added


outputs = kept_outputs(ledger_terms)
