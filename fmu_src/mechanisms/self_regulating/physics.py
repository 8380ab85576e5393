"""Physics of the self-regulating spring balancer (Franchetti, Boschetti, Lenzo 2021).

Pure model, standard library only: no FMI and no I/O. It is shared by the FMU slave
`SelfRegulatingBalancer`, the harness and the tests. This module holds the rates, the
integration over a step (`advance`) and the event physics (`switch_inputs`); `model` holds the
data types, parameters, forces, energies, outputs and ledger terms. Conventions are those of
docs/conventions.md: theta from the upward vertical, counter-clockwise positive, unit vector along
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

Energy ledger (docs/energy_ledger.md): W_drive (work of tau_drive) and E_loss (dampers, end
stops, lock events, masses picked up while moving) are states, E_added (energy that masses
bring in or take out as they join or leave) changes at input events only, so that
E_t + E_cw + E_kin + E_loss - W_drive - E_added is constant. Inputs change only at
communication points; `switch_inputs` maps the state across such a change (momentum
conserved where the bodies couple or decouple), `advance` integrates between them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from functools import partial

from fmu_src.integration import (
    first_substeps,
    integrate_link_slider,
    integrate_sine_arm,
    integrate_substeps,
    ledger_controlled,
    substeps,
)
from fmu_src.mechanism import state_variables, variable, variable_named
from fmu_src.mechanisms.self_regulating.design import _free_length_factor

# model.py holds the Physics protocol's data types, validate, initial_state, outputs and
# ledger_terms: imported here because the harness and the slave call them as physics.<name>
from fmu_src.mechanisms.self_regulating.model import (  # noqa: F401
    EVENT_INPUTS,
    INPUT_VARIABLES,
    OUTPUT_VARIABLES,
    Inputs,
    Outputs,
    Parameters,
    State,
    _at_stop,
    _creep_speed,
    _damper_speed,
    _free_slider_inertia,
    _friction_state,
    _link_terms,
    _mechanical_energy,
    _new,
    _slider_force,
    _slip,
    initial_state,
    ledger_terms,
    link_inertia,
    mechanical_energy,
    outputs,
    slider_damping,
    slider_friction,
    slider_mass,
    validate,
    wire_tension,
)

# A free slider starts every lock event with a jump in its acceleration, which RK4 at the
# shared step-rate product resolves to ~1e-9 J of the energy ledger per event; sub-steps four
# times finer on the slider's rates keep it near 1e-11 J (the link's own rate is unchanged).
SLIDER_RATE_FACTOR = 4.0


def derivatives(p: Parameters, u: Inputs, s: State, rates: Inputs | None = None,
                mode: tuple[int, ...] | None = None) -> State:
    """Time derivative of the state (see _derivatives) as a State; mode (`mode`): the
    friction state held, () or None to decide it from s."""
    return State._make(_derivatives(p, u, s, rates, mode[0] if mode else None))


def _derivatives(p: Parameters, u: Inputs, s: State, rates: Inputs | None = None,
                 slip: float | None = None) -> tuple[float, ...]:
    """Time derivative of the state, in State's field order, for inputs u that are constant
    or, for a continuous-time model such as the harness's reference, change at `rates`
    (d/dt of the Real inputs; masses then join and leave continuously, see _mass_flow).
    `slip` fixes the slider's friction state for a whole RK4 sub-step (0: stuck, +1 or -1:
    sliding out or in; see advance); None decides it from s."""
    d = _state_rates(p, u, slip)(s)
    return d if rates is None else _mass_flow(p, u, rates, s, d)


def _state_rates(p: Parameters, u: Inputs, slip: float | None = None
                 ) -> Callable[[Sequence[float]], tuple[float, ...]]:
    """The time derivative of the state as a function of the state (read by position; a
    plain tuple in State's field order) for inputs u held and the friction state slip (see
    _derivatives), built on _slider_rates."""
    tau, pulley_locked, cw_ratio = u.tau_drive, u.pulley_locked, p.pulley_ratio
    rates = _slider_rates(p, u, slip)

    def state_rates(s: Sequence[float]) -> tuple[float, ...]:
        theta, omega, b, v = s[:4]
        omega_dot, b_dot, v_dot, loss = rates(theta, omega, b, v)
        return (omega, omega_dot, b_dot, v_dot, 0.0 if pulley_locked else cw_ratio * b_dot,
                tau * omega, loss, 0.0)
    return state_rates


def _slider_rates(p: Parameters, u: Inputs, slip: float | None = None
                  ) -> Callable[[float, float, float, float], tuple[float, float, float, float]]:
    """(omega', b', v', E_loss') as a function of theta, omega, b and v for inputs u held and
    the friction state slip (see _derivatives); the other rates follow from these: theta' =
    omega, s_cw' = (R/r) b' while the pulley turns, W_drive' = tau_drive omega, E_added' = 0.
    The terms constant while the inputs are held are computed once, for the RK4 stages of a
    whole step."""
    tau, payload, _, slider_locked, _ = u
    moment_base = p.m * p.c + payload * p.w      # gravity_moment less m_slider b, times g
    inertia_base = p.J_link + payload * p.w * p.w  # link_inertia less m_slider b^2 + J_drive
    g, k_a, d_link, m_slider, J_drive = p.g, p.k * p.a, p.d_link, p.m_slider, p.J_drive
    coriolis_factor = 2.0 * m_slider
    real_spring = p.L0 > 0.0
    if not slider_locked:
        (m_eff, damping), pull = _free_slider_inertia(p, u), wire_tension(p, u)
        no_friction = p.mu_slider == 0.0
    fixed_slip = slip

    def slider_rates(theta: float, omega: float, b: float, v: float
                     ) -> tuple[float, float, float, float]:
        sin_t = math.sin(theta)
        factor = _free_length_factor(p, theta, b) if real_spring else 1.0
        # the link's angular acceleration with the slider at b moving at v along it
        spring_torque = k_a * b * sin_t * factor
        coriolis = coriolis_factor * b * v * omega
        omega_dot = (tau + (moment_base + m_slider * b) * g * sin_t - spring_torque
                     - d_link * omega - coriolis) / (inertia_base + m_slider * b * b + J_drive)
        link_loss = d_link * omega * omega
        if slider_locked:
            return omega_dot, 0.0, 0.0, link_loss
        force = _slider_force(p, theta, omega, b, v, factor, pull, damping)
        friction = 0.0 if no_friction else slider_friction(p, theta, factor)
        if m_eff > 0.0:
            if fixed_slip is not None:
                slip = fixed_slip
            elif v != 0.0:
                slip = math.copysign(1.0, v)  # _slip's answer for a moving slider, no call
            else:
                slip = _slip(p, b, v, force, friction)
            if slip == 0.0 or (v == 0.0 and _at_stop(p, b, force)):  # stuck or held by a stop
                return omega_dot, 0.0, 0.0, link_loss
            b_dot = v
            v_dot = (force - slip * friction) / m_eff
            rubbing = slip * friction * v  # power of the friction force -slip friction
        else:
            # Massless slider: damping v = F_spring + T - friction (v eliminated, an output).
            b_dot = _creep_speed(force + damping * v, friction, damping)
            if _at_stop(p, b, b_dot):
                b_dot = 0.0
            v_dot = 0.0
            rubbing = friction * abs(b_dot)
        return omega_dot, b_dot, v_dot, link_loss + damping * b_dot * b_dot + rubbing
    return slider_rates


def _mass_flow(p: Parameters, u: Inputs, rates: Inputs, s: State, d: tuple[float, ...]
               ) -> tuple[float, ...]:
    """d with the continuous-time limit of switch_inputs for masses changing at `rates`:
    payload joining from rest brakes the link, J omega' gains -payload_rate w^2 omega, and
    costs 1/2 payload_rate w^2 omega^2 of E_loss; leaving, it takes its kinetic energy
    (E_added); likewise counterweight mass joining or leaving the moving counterweight."""
    theta, omega, b, v, s_cw = s[:5]
    gain, drop = max(rates.payload, 0.0), min(rates.payload, 0.0)
    omega_dot = d[1] - gain * p.w * p.w * omega / link_inertia(p, u.payload, b)
    loss = 0.5 * gain * (p.w * omega) ** 2
    added = rates.payload * p.g * p.w * math.cos(theta) + 0.5 * drop * (p.w * omega) ** 2
    added -= rates.counterweight_added * p.g * s_cw
    v_dot = d[3]
    m_eff = slider_mass(p, u)
    if not (u.slider_locked or u.pulley_locked) and m_eff > 0.0 and d[2] != 0.0:
        reflected = p.pulley_ratio ** 2 * v * v
        gain_cw = max(rates.counterweight_added, 0.0)
        v_dot -= gain_cw * p.pulley_ratio ** 2 * v / m_eff
        loss += 0.5 * gain_cw * reflected
        added += 0.5 * min(rates.counterweight_added, 0.0) * reflected
    return (d[0], omega_dot, d[2], v_dot, d[4], d[5], d[6] + loss, added)


def characteristic_rate(p: Parameters, u: Inputs, s: State) -> float:
    """Fastest rate of the local dynamics [1/s]: sets the internal integration step."""
    # max(a, b) as `b if b > a else a` (the same value; the builtin's call costs more)
    rate, speed = _link_terms(p, u.payload, s.b)[3], abs(s.omega)
    rate = speed if speed > rate else rate
    if not u.slider_locked:
        m_eff, damping = _free_slider_inertia(p, u)
        k_b = p.k + p.m_slider * s.omega ** 2
        if m_eff > 0.0:
            slider_rate, decay = math.sqrt(k_b / m_eff), damping / m_eff
            slider_rate = decay if decay > slider_rate else slider_rate
        else:
            slider_rate = k_b / damping
        slider_rate *= SLIDER_RATE_FACTOR
        rate = slider_rate if slider_rate > rate else rate
    return rate


def _controlled(p: Parameters, u: Inputs, s: State, dt: float, run: Callable[[int], State],
                n: int) -> State:
    """run(n), the step of dt [s] from s with n sub-steps, under the ledger's control (its
    event inputs u[1:], EVENT_INPUTS in field order)."""
    return ledger_controlled(run, partial(ledger_terms, p, u), (5,), s, n, dt, p, u[1:])


def _apply_constraints(p: Parameters, u: Inputs, s: State) -> State:
    """Clamp the free slider to its end stops (inelastic: the energy the clamp removes goes to
    E_loss), moving the counterweight with it while the pulley turns."""
    b, v = s.b, s.v
    if p.b_min <= b <= p.b_max:
        if slider_mass(p, u) == 0.0:
            return s._replace(v=_damper_speed(p, u, s))
        return s
    stop = p.b_min if b < p.b_min else p.b_max
    v = max(v, 0.0) if b < p.b_min else min(v, 0.0)
    s_cw = s.s_cw if u.pulley_locked else s.s_cw + p.pulley_ratio * (stop - b)
    clamped = s._replace(b=stop, v=v, s_cw=s_cw)
    if slider_mass(p, u) == 0.0:
        clamped = clamped._replace(v=_damper_speed(p, u, clamped))
    loss = mechanical_energy(p, u, s) - mechanical_energy(p, u, clamped)
    return clamped._replace(E_loss=s.E_loss + loss)


def _advance_free_slider(p: Parameters, u: Inputs, s: State, dt: float) -> State:
    """advance with the slider free."""
    n = substeps(dt, characteristic_rate(p, u, s))
    if p.mu_slider == 0.0 or slider_mass(p, u) == 0.0:
        return _controlled(p, u, s, dt, lambda m: _integrate_free_slider(p, u, s, dt, m), n)
    return _controlled(p, u, s, dt, lambda m: _integrate_with_friction(p, u, s, dt, m), n)


def _integrate_with_friction(p: Parameters, u: Inputs, s: State, dt: float, n: int) -> State:
    """A free slider with Coulomb friction over dt [s] in n sub-steps: the friction state is
    decided at the start of each sub-step and held through it, so that RK4 sees one smooth
    right-hand side (and the ledger stays exact)."""
    slip = [_friction_state(p, u, s)]

    def stick(state: State) -> State:
        """`_stick` after the sub-step, and the friction state of the next."""
        state = _stick(p, u, state, slip[0])
        slip[0] = _friction_state(p, u, state)
        return state

    return integrate_substeps(lambda state: _derivatives(p, u, state, None, slip[0]), s, dt, n,
                              stick)


def _stick(p: Parameters, u: Inputs, s: State, slip: float) -> State:
    """_apply_constraints, then: a slider that slid in the direction slip (+1 or -1) and
    whose speed changed sign has stopped, and sticks (v = 0, its kinetic energy to E_loss)
    until the pull exceeds the friction limit."""
    s = _apply_constraints(p, u, s)
    if s.v * slip < 0.0:
        stuck = s._replace(v=0.0)
        s = stuck._replace(E_loss=s.E_loss + mechanical_energy(p, u, s)
                           - mechanical_energy(p, u, stuck))
    return s


def advance(p: Parameters, u: Inputs, s: State, dt: float) -> State:
    """Integrate over one communication step dt [s] with inputs held constant: RK4 sub-steps
    from the rate rule, raised until the energy ledger meets p.ledger_accuracy
    (`integration.ledger_controlled`).

    A clamped slider (the usual step) leaves a 1-DOF link: b and s_cw stay put and v = 0, so
    RK4 runs over the link and its ledger alone (`_integrate_locked_slider`), with the terms
    constant over the step computed once. The same numbers, bit for bit (same operations in
    the same order), as `integrate_substeps` over the full state with the derivatives of
    `_state_rates`.
    """
    if not u.slider_locked:
        return _advance_free_slider(p, u, s, dt)
    rate = _link_terms(p, u.payload, s.b)[3]
    speed = abs(s.omega)
    rate = speed if speed > rate else rate  # max(rate, speed), without the builtin's call
    return _controlled(p, u, s, dt, lambda n: _integrate_locked_slider(p, u, s, dt, n),
                       first_substeps(dt, rate))


def _integrate_locked_slider(p: Parameters, u: Inputs, s: State, dt: float, n: int) -> State:
    """The link with the slider clamped over dt [s] in n RK4 sub-steps (`advance`): a link
    of constant inertia with gravity, the spring's moment spring sin(theta) (1 - L0/x) and
    the link damper (`integrate_sine_arm`)."""
    theta, omega, b, _, s_cw, W_drive, E_loss, E_added = s
    moment, J, spring = _link_terms(p, u.payload, b)[:3]
    factor = (lambda theta: _free_length_factor(p, theta, b)) if p.L0 > 0.0 else None
    theta, omega, W_drive, E_loss = integrate_sine_arm(
        u.tau_drive, moment, spring, factor, p.d_link, J, theta, omega, W_drive, E_loss, dt, n)
    return _new(State, (theta, omega, b, 0.0, s_cw, W_drive, E_loss, E_added))


def _integrate_free_slider(p: Parameters, u: Inputs, s: State, dt: float, n: int) -> State:
    """`integrate_substeps` (n sub-steps over dt [s]) over the state with the derivatives of
    `_state_rates` and `_apply_constraints` after each sub-step (a free slider with no
    friction state to hold): `integrate_link_slider` for the rates of `_slider_rates`, the
    counterweight coupled while the pulley turns, `_apply_constraints` wherever it can change
    something (beyond a stop, or a massless slider after every sub-step)."""
    low, high = (p.b_min, p.b_max) if slider_mass(p, u) != 0.0 else (math.inf, -math.inf)
    return integrate_link_slider(_slider_rates(p, u), s, u.tau_drive,
                                 None if u.pulley_locked else p.pulley_ratio, dt, n, low, high,
                                 _apply_constraints, p, u)


def switch_inputs(p: Parameters, before: Inputs, after: Inputs, s: State) -> State:
    """The state just after the inputs change from `before` to `after` at a communication point.

    Event physics (docs/energy_ledger.md), in this order:
    - payload added: picked up from rest, the link's angular momentum J omega is conserved;
      payload removed: it leaves with its own velocity, omega unchanged, and takes its
      kinetic energy with it;
    - counterweight mass, while it moves with the slider (both free): added from rest, the
      momentum m_eff v of slider and counterweight is conserved; removed, v unchanged;
    - slider locked: the clamp stops it (v = 0) and the counterweight with it; the clamp acts
      along the link, so omega does not change;
    - pulley released with the slider free: the slider's momentum m_slider v is shared with
      the counterweight at rest (a massless slider carries none: v = 0); pulley locked: the
      counterweight stops, the slider keeps v.
    Masses joining or leaving book their potential energy (and the kinetic energy they take
    away) to E_added; the kinetic energy the events destroy goes to E_loss.
    """
    theta, omega, b, v, s_cw = s[:5]
    # the slider's effective masses (mechanical_energy's), each computed once
    mass_before = p.m_slider if before.slider_locked else slider_mass(p, before)
    mass_after = p.m_slider if after.slider_locked else slider_mass(p, after)
    added = 0.0
    d_payload = after.payload - before.payload
    if d_payload != 0.0:
        added += d_payload * p.g * p.w * math.cos(theta)
        if d_payload > 0.0:
            omega *= _link_terms(p, before.payload, b)[1] / _link_terms(p, after.payload, b)[1]
        else:
            added += 0.5 * d_payload * (p.w * omega) ** 2
    moving_cw = not (before.slider_locked or before.pulley_locked)
    d_cw = after.counterweight_added - before.counterweight_added
    if d_cw != 0.0:
        added -= d_cw * p.g * s_cw
        if moving_cw and d_cw > 0.0:
            heavier = _new(Inputs, (before.tau_drive, before.payload, after.counterweight_added,
                                    before.slider_locked, before.pulley_locked))
            v *= mass_before / slider_mass(p, heavier)
        elif moving_cw:
            added += 0.5 * d_cw * (p.pulley_ratio * v) ** 2
    if after.slider_locked:
        v = 0.0
    elif not before.slider_locked and not after.pulley_locked and before.pulley_locked:
        v = v * p.m_slider / mass_after if mass_after > 0.0 else 0.0
    if not after.slider_locked and mass_after == 0.0:
        v = _damper_speed(p, after, State(theta, omega, b, v))
    new = _new(State, (theta, omega, b, v, s_cw, s.W_drive, s.E_loss, s.E_added + added))
    loss = (_mechanical_energy(p, before, s, mass_before) + added
            - _mechanical_energy(p, after, new, mass_after))
    return _new(State, (*new[:6], s.E_loss + loss, new[7]))


# ---- Model Exchange: the events `advance` handles after each sub-step, as state events ----
# the states no output reports
STATE_VARIABLES = state_variables(
    State, Outputs,
    v=variable("m/s", "Slider speed along the link (0 while it is locked)"),
    s_cw=variable("m", "Descent of the counterweight from its start (R/r times the slider's "
                       "travel while the pulley turns)"),
)
EVENT_INDICATORS = (
    variable_named("b_min_reached", variable(
        "m", "b - b_min of the free slider: it hits the inner end stop where this reaches 0 "
        "(b_max - b_min while it rests there or the slider is locked)")),
    variable_named("b_max_reached", variable(
        "m", "b_max - b of the free slider: it hits the outer end stop where this reaches 0 "
        "(b_max - b_min while it rests there or the slider is locked)")),
    variable_named("friction_state_ends", variable(
        None, "With Coulomb friction (mu_slider > 0), in the friction state held: sliding, "
        "v times its direction [m/s] (it sticks at 0); stuck, the friction limit less the "
        "pull away from where it rests [N] (it breaks loose at 0); b_max - b_min otherwise")),
)


def mode(p: Parameters, u: Inputs, s: State) -> tuple[int, ...]:
    """The friction state of a free slider with mass and Coulomb friction (_friction_state:
    -1 or +1 sliding in or out, 0 stuck or resting on a stop), which `advance` holds through
    each RK4 sub-step; () otherwise (the locked slider's link, a frictionless or a massless
    slider have one smooth regime)."""
    if u.slider_locked or p.mu_slider == 0.0 or slider_mass(p, u) == 0.0:
        return ()
    return (int(_friction_state(p, u, s)),)


def event_indicators(p: Parameters, u: Inputs, s: State, mode: tuple[int, ...]
                     ) -> tuple[float, float, float]:
    """The EVENT_INDICATORS: positive while the slider stays within its stops and in the
    friction state mode."""
    span, b = p.b_max - p.b_min, s.b
    if u.slider_locked:
        return span, span, span
    stops = (b - p.b_min if b != p.b_min else span, p.b_max - b if b != p.b_max else span)
    if not mode:
        return (*stops, span)
    if mode[0] != 0:
        return (*stops, s.v * mode[0])
    factor = _free_length_factor(p, s.theta, b)
    force = _slider_force(p, s.theta, s.omega, b, s.v, factor, wire_tension(p, u),
                          slider_damping(p, u))
    friction = slider_friction(p, s.theta, factor)
    # stuck while |force| <= friction, and on a stop while it pushes into it (_slip)
    margin = (friction - force if b == p.b_min else friction + force if b == p.b_max
              else friction - abs(force))
    return (*stops, margin)


def event_update(p: Parameters, u: Inputs, s: State, mode: tuple[int, ...]) -> State:
    """A stop reached (clamped, the impact's energy to E_loss) and a sliding slider stopped
    (it sticks): `_stick`, as after every RK4 sub-step of `advance`."""
    if u.slider_locked:
        return s
    return _stick(p, u, s, mode[0] if mode else 0.0)


def state_nominals(p: Parameters) -> tuple[float, ...]:
    """1 rad and 1 rad/s for the link, the slider's travel b_max - b_min [m] (per second for
    its speed, times R/r for the counterweight), 1 J for the energies."""
    span = p.b_max - p.b_min
    return (1.0, 1.0, span, span, p.pulley_ratio * span, 1.0, 1.0, 1.0)
