"""Ciupitu 2018 Fig. 8 (spring frame joint relocated by a prismatic joint): the physics of
`fmu_src.mechanisms.active_spring.physics` and the `active-design` command, against closed
forms, finite differences, conservation laws and eq. 27 written out here in the paper's own
frame."""

from __future__ import annotations

import json
import math
from functools import partial

import pytest

from fmu_src import integration
from fmu_src.mechanisms.active_spring import model, physics
from harness import cli
from harness.design import active_spring as active_design

G = 9.81
M1, OC1, X1A, W, K = 3.0, 0.2, 0.06, 0.35, 981.0   # the defaults (Franchetti's Table 1 link)
REAL_SPRING = {"F_s0": 20.0, "l_s0": 0.05, "X_B": 0.03}
DEFAULT_OPTIONS = {"m1": M1, "OC1": OC1, "x1A": X1A, "w": W, "mp": 0.0, "dmp": 1.0, "k": K,
                   "Fs0": 0.0, "ls0": 0.0, "XB": 0.0, "YB": 0.1, "phi": 0.0}
ANGLES = [0.0, 0.4, 1.0, math.pi / 2, 2.0, math.pi, 4.0, 5.5]
IDEAL = {"mu": 0.0}   # the lossless limit of the screw (self-locking: the ideal lock)
# screws with friction: the default Tr 10x2 (self-locking) and a back-drivable one
FRICTION_SCREWS = {"tr10x2": {}, "back_drivable": {"mu": 0.03, "self_locking": False}}


def ledger(p: physics.Parameters, payload: float, s: physics.State) -> float:
    """E_t + E_kin + E_loss - W_drive - W_adjust - E_added [J]."""
    o = physics.outputs(p, physics.Inputs(payload=payload), s)
    return o.E_t + o.E_kin + o.E_loss - o.W_drive - o.W_adjust - o.E_added


def potential(p: physics.Parameters, payload: float, theta: float, Y_B: float) -> float:
    """E_t from coordinates: link, payload and carriage weights, spring energy 1/2 k (l - L)^2
    with the free length L = l_s0 - F_s0/k."""
    A = (-X1A * math.sin(theta), X1A * math.cos(theta))
    length = math.hypot(p.X_B - A[0], Y_B - A[1])
    free = p.l_s0 - p.F_s0 / p.k
    return ((p.m * p.c + payload * p.w) * G * math.cos(theta) + p.m_q * G * Y_B
            + 0.5 * p.k * (length - free) ** 2)


# ---- statics ------------------------------------------------------------------------

@pytest.mark.parametrize("spring", [{}, REAL_SPRING], ids=["zero_free_length", "real"])
@pytest.mark.parametrize("theta", [0.3, 1.7, 2.9, 4.4])
def test_torque_and_carriage_force_are_the_potential_gradient(spring: dict[str, float],
                                                             theta: float) -> None:
    """tau_gravity = -dE_t/dtheta and F_q - m_q g = -dE_t/dq (central differences)."""
    p = physics.Parameters(**spring)
    payload, Y_B, h = 0.7, 0.13, 1e-6
    o = physics.outputs(p, physics.Inputs(payload=payload),
                        physics.State(theta, 0.0, Y_B - p.Y_B0, 0.0))
    d_theta = (potential(p, payload, theta + h, Y_B) - potential(p, payload, theta - h, Y_B))
    d_q = (potential(p, payload, theta, Y_B + h) - potential(p, payload, theta, Y_B - h))
    assert o.tau_gravity == pytest.approx(-d_theta / (2 * h), abs=1e-7)
    assert o.F_q - p.m_q * G == pytest.approx(-d_q / (2 * h), abs=1e-7)
    assert o.E_t == pytest.approx(potential(p, payload, theta, Y_B), abs=1e-12)


@pytest.mark.parametrize("payload", [0.0, 1.0, 4.0])
def test_zero_free_length_spring_balances_at_every_angle(payload: float) -> None:
    """F_s0 = k l_s0, X_B = 0: Y_B = (m c + payload w) g / (k x1A) leaves no torque at any
    angle; elsewhere tau_gravity = [(m c + payload w) g - k x1A Y_B] sin(theta)."""
    p = physics.Parameters(F_s0=K * 0.04, l_s0=0.04)
    balanced = (M1 * OC1 + payload * W) * G / (K * X1A)
    for theta in ANGLES:
        assert model.tau_gravity(p, payload, theta, balanced) == pytest.approx(0.0, abs=1e-12)
        assert model.balance_error(p, payload, theta, balanced) == pytest.approx(0.0, abs=1e-12)
        off = balanced + 0.01
        assert model.tau_gravity(p, payload, theta, off) == pytest.approx(
            -K * X1A * 0.01 * math.sin(theta), abs=1e-12)


# ---- dynamics and ledger --------------------------------------------------------------

def run(p: physics.Parameters, schedule: list[tuple[float, float, float]], steps: int,
        dt: float = 1e-3) -> tuple[physics.State, float]:
    """Step with inputs (tau_drive, F_adjust, payload) from schedule[n * len // steps];
    returns the last state and the largest drift of the ledger [J]."""
    s, payload = physics.initial_state(p), schedule[0][2]
    reference, drift = ledger(p, payload, s), 0.0
    for n in range(steps):
        u = physics.Inputs(*schedule[n * len(schedule) // steps])
        s = physics.switch_inputs(p, physics.Inputs(payload=payload), u, s)
        payload = u.payload
        s = physics.advance(p, u, s, dt)
        drift = max(drift, abs(ledger(p, payload, s) - reference))
    return s, drift


@pytest.mark.parametrize("self_locking", [True, False], ids=["self_locking", "back_drivable"])
@pytest.mark.parametrize("spring", [{}, REAL_SPRING], ids=["zero_free_length", "real"])
def test_ledger_closes_with_drives_dampers_and_payload_changes(spring: dict[str, float],
                                                               self_locking: bool) -> None:
    """Lossless screw. Payloads join (0 -> 0.3 kg) and leave (-> 0.1 kg) a swinging link while
    both drives push, the carriage raised against the spring and then lowered with it
    (actuator forces a few newtons either side of the load at the start): E_t + E_kin +
    E_loss - W_drive - W_adjust - E_added is constant to 1e-9 J (measured 1e-11 to 9e-11 J)."""
    p = physics.Parameters(**spring, **IDEAL, omega0=0.5, q_dot0=0.02,
                           self_locking=self_locking, J_drive=0.05, m_drive_q=0.3)
    load = model.spring(p, 1.0, p.Y_B0).F_q - p.m_q * G   # -71 N (real spring: -53 N)
    schedule = [(0.05, 2.0 - load, 0.0), (0.05, 0.5 - load, 0.3), (-0.05, -3.0 - load, 0.1),
                (0.0, -1.0 - load, 0.1)]
    s, drift = run(p, schedule, 3000)
    assert drift < 1e-9
    assert s.E_loss > 0.1 and s.W_drive != 0.0 and abs(s.W_adjust) > 0.1 and s.E_added != 0.0


def test_payload_catch_conserves_angular_momentum() -> None:
    """A payload joining at rest: J omega is conserved, the kinetic energy lost is
    1/2 J_b omega^2 (1 - J_b / J_a) and its potential energy dm g w cos(theta) is added; a
    payload leaving takes dm g w cos(theta) + 1/2 dm w^2 omega^2 and omega is unchanged."""
    p = physics.Parameters()
    theta, omega, dm = 2.0, 1.5, 0.8
    J_b, J_a = 0.16, 0.16 + dm * W * W
    s = physics.switch_inputs(p, physics.Inputs(), physics.Inputs(payload=dm),
                              physics.State(theta, omega, 0.0, 0.0))
    assert J_a * s.omega == pytest.approx(J_b * omega, rel=1e-15)
    assert s.E_loss == pytest.approx(0.5 * J_b * omega ** 2 * (1 - J_b / J_a), rel=1e-12)
    assert s.E_added == pytest.approx(dm * G * W * math.cos(theta), rel=1e-12)
    back = physics.switch_inputs(p, physics.Inputs(payload=dm), physics.Inputs(), s)
    assert back.omega == s.omega
    assert back.E_added - s.E_added == pytest.approx(
        -dm * G * W * math.cos(theta) - 0.5 * dm * (W * s.omega) ** 2, rel=1e-12)


def test_self_locking_carriage_holds_the_spring_without_the_actuator() -> None:
    """F_adjust = 0: the carriage stays put while the unbalanced link swings and the spring
    pulls on it with tens of newtons, held by the screw (F_lock = m_q g - F_q); back-drivable,
    the spring pulls it down."""
    p = physics.Parameters(**IDEAL, theta0=1.0)
    s, _ = run(p, [(0.0, 0.0, 2.0)], 500)
    assert s.q == 0.0 and s.q_dot == 0.0 and s.W_adjust == 0.0 and s.E_loss > 0.0
    assert abs(s.theta - 1.0) > 0.1
    o = physics.outputs(p, physics.Inputs(payload=2.0), s)
    assert o.F_q < -10.0 and o.F_lock == pytest.approx(p.m_q * G - o.F_q, rel=1e-15)
    free, _ = run(physics.Parameters(**IDEAL, theta0=1.0, self_locking=False),
                  [(0.0, 0.0, 2.0)], 500)
    assert free.q < -0.01


@pytest.mark.parametrize("m_drive_q", [0.0, 2.0])
def test_self_locking_carriage_lowered_by_the_actuator_dissipates_the_load(
        m_drive_q: float) -> None:
    """Lowering (F_adjust < 0, the load L = F_q - m_q g < 0 assists): the screw absorbs the
    load, so (m_q + m_drive_q) q'' = F - d_q q' whatever the spring:
    q = F/d_q (t - tau (1 - exp(-t/tau))), tau = (m_q + m_drive_q) / d_q, and the load's work
    -L dq goes to E_loss. Link held balanced (defaults)."""
    p = physics.Parameters(**IDEAL, theta0=math.pi, m_drive_q=m_drive_q)
    force, t = -2.0, 0.05
    s, drift = run(p, [(0.0, force, 0.0)], 50)
    tau = (0.5 + m_drive_q) / p.d_q
    assert s.q == pytest.approx(force / p.d_q * (t - tau * (1 - math.exp(-t / tau))), rel=1e-9)
    spring_work = model.elastic_energy(p, model.spring(p, s.theta, p.Y_B0).l_s) - (
        model.elastic_energy(p, model.spring(p, s.theta, p.Y_B0 + s.q).l_s))
    damper = s.E_loss - (spring_work - p.m_q * G * s.q)
    assert 0.0 < damper < s.W_adjust and drift < 1e-9


def test_self_locking_carriage_rises_only_when_the_actuator_beats_the_load() -> None:
    """Raising against the load: an actuator force 1 N short of the load leaves the carriage at
    rest, 5 N over it raises it; the actuator's work then pays the spring's and the weight's
    energy (W_adjust = E_t gained + E_kin + E_loss) and the screw loses nothing."""
    p = physics.Parameters(**IDEAL, theta0=math.pi)
    load = model.spring(p, math.pi, p.Y_B0).F_q - p.m_q * G
    short, _ = run(p, [(0.0, -load - 1.0, 0.0)], 100)
    assert short.q == 0.0 and short.W_adjust == 0.0
    s, _ = run(p, [(0.0, -load + 5.0, 0.0)], 100)
    gained = (physics.outputs(p, physics.Inputs(), s).E_t
              - physics.outputs(p, physics.Inputs(), physics.initial_state(p)).E_t)
    assert s.q > 0.001 and gained > 0.0
    assert s.W_adjust == pytest.approx(gained + s.E_loss + 0.5 * p.m_q * s.q_dot ** 2, rel=1e-9)
    # no screw loss: the damper's alone, below d_q v_max^2 t with v_max = 5 N / d_q
    assert 0.0 < s.E_loss < p.d_q * (5.0 / p.d_q) ** 2 * 0.1


# ---- the screw with friction --------------------------------------------------------------

def thread_efficiencies(mu: float, lead: float, d2: float, flank: float) -> tuple[float, float]:
    """The textbook power screw (thread of lead l on the pitch diameter d2, mu' = mu / cos of
    the flank half-angle): raising a load F takes the torque F d2/2 (l + pi mu' d2) / (pi d2 -
    mu' l), a load driving it gives F d2/2 (l - pi mu' d2) / (pi d2 + mu' l); the efficiencies
    are the lossless torque F l / (2 pi) over the first and the second over it."""
    mu_n, circumference = mu / math.cos(flank), math.pi * d2
    raise_torque = d2 / 2 * (lead + mu_n * circumference) / (circumference - mu_n * lead)
    driven_torque = d2 / 2 * (lead - mu_n * circumference) / (circumference + mu_n * lead)
    lossless = lead / (2 * math.pi)
    return lossless / raise_torque, driven_torque / lossless


@pytest.mark.parametrize(("mu", "lead", "d2", "flank"), [
    (0.1, 0.002, 0.009, 15.0),    # Tr 10x2 on bronze, the default: self-locking
    (0.05, 0.004, 0.014, 15.0),   # Tr 16x4 well lubricated: back-drivable
    (0.15, 0.006, 0.021, 0.0),    # a square thread
])
def test_screw_efficiencies_are_the_power_screw_torques(mu: float, lead: float, d2: float,
                                                        flank: float) -> None:
    lead_angle = math.atan(lead / (math.pi * d2))
    expected = thread_efficiencies(mu, lead, d2, math.radians(flank))
    assert model.screw_efficiencies(mu, lead_angle, math.radians(flank)) == pytest.approx(
        expected, rel=1e-12)


def test_the_default_screw_is_a_self_locking_tr10x2_at_40_percent() -> None:
    """Tr 10x2 (lead 2 mm, d2 = 9 mm: lambda = 4.05 deg), steel on lubricated bronze
    (mu = 0.1, 15 deg flanks: rho' = 5.91 deg): eta_f = 0.403, eta_b = -0.46 (self-locking)."""
    p = physics.Parameters()
    assert math.degrees(p.lead_angle) == pytest.approx(4.046, abs=1e-3)
    assert math.degrees(model.friction_angle(p.mu, p.flank_angle)) == pytest.approx(
        5.911, abs=1e-3)
    assert (p.eta_forward, p.eta_backward) == pytest.approx(
        thread_efficiencies(0.1, 0.002, 0.009, math.radians(15.0)), rel=1e-12)
    assert p.eta_forward == pytest.approx(0.403, abs=5e-4) and p.eta_backward < 0.0
    assert p.self_locking
    lossless = physics.Parameters(mu=0.0)
    assert (lossless.eta_forward, lossless.eta_backward) == (1.0, 0.0)
    back_drivable = physics.Parameters(mu=0.0, self_locking=False)
    assert (back_drivable.eta_forward, back_drivable.eta_backward) == (1.0, 1.0)


@pytest.mark.parametrize("side", [-1.0, 1.0], ids=["just_below", "just_above"])
def test_the_screw_self_locks_exactly_when_the_friction_angle_reaches_the_lead_angle(
        side: float) -> None:
    """mu at 1e-3 either side of tan(lambda) cos(15 deg), where rho' = lambda: below, eta_b > 0
    and the hanging link's spring (160 N) pulls the carriage down with no actuator force;
    above, eta_b < 0 and the screw holds it (F_lock = -L). A self_locking that contradicts
    the friction is refused, naming it."""
    lead_angle = model.TR10X2_LEAD_ANGLE
    mu = math.tan(lead_angle) * math.cos(math.radians(15.0)) * (1.0 + 1e-3 * side)
    locking = side > 0.0
    p = physics.Parameters(mu=mu, self_locking=locking, theta0=math.pi)
    physics.validate(p)
    assert (p.eta_backward > 0.0) != locking and abs(p.eta_backward) < 0.01
    with pytest.raises(ValueError, match="^self_locking = "):
        physics.validate(physics.Parameters(mu=mu, self_locking=not locking))
    s, drift = run(p, [(0.0, 0.0, 0.0)], 100)
    load = model.spring(p, math.pi, p.Y_B0 + s.q).F_q - p.m_q * G
    assert load < -150.0 and drift < 1e-9
    if locking:
        assert s.q == 0.0 and s.q_dot == 0.0 and s.W_adjust == 0.0
        assert physics.outputs(p, physics.Inputs(), s).F_lock == -load
    else:   # the load drives it, eta_b L against the damper: q' -> eta_b L / d_q
        assert s.q < 0.0 and s.q_dot == pytest.approx(p.eta_backward * load / p.d_q, rel=0.05)


@pytest.mark.parametrize("screw", [{}, {"mu": 0.15, "lead_angle": 0.1, "flank_angle": 0.0},
                                   IDEAL], ids=["tr10x2", "square_thread", "ideal"])
def test_constant_force_raises_the_carriage_at_the_screws_efficiency(screw: dict) -> None:
    """Link hanging (theta = pi: no torque whatever B's height), no damper: a constant actuator
    force F raises the carriage against L(q) = -(k (Y_B0 + x1A + q) + m_q g) until it stops at
    q_max and the screw holds it; (M_q q'') = F + L / eta_f integrated over the rise gives
    F q_max = (dE_e + dE_p) / eta_f, so q_max = 2 (F eta_f - k (Y_B0 + x1A) - m_q g) / k,
    W_adjust = F q_max = (dE_e + dE_p) / eta_f and E_loss = (1 / eta_f - 1) (dE_e + dE_p)."""
    p = physics.Parameters(**screw, theta0=math.pi, d_q=0.0, m_drive_q=2.0)
    force = 250.0 / p.eta_forward
    q_max = 2.0 * (force * p.eta_forward - K * (p.Y_B0 + X1A) - p.m_q * G) / K
    s, drift = run(p, [(0.0, force, 0.0)], 400)
    start = physics.outputs(p, physics.Inputs(), physics.initial_state(p))
    end = physics.outputs(p, physics.Inputs(), s)
    stored = end.E_t - start.E_t
    assert s.q_dot == 0.0 and s.q == pytest.approx(q_max, rel=1e-6)
    assert s.W_adjust == pytest.approx(stored / p.eta_forward, rel=1e-6)
    assert s.E_loss == pytest.approx(stored * (1.0 / p.eta_forward - 1.0), rel=1e-6, abs=1e-6)
    assert drift < 1e-9


@pytest.mark.parametrize("screw", FRICTION_SCREWS.values(), ids=FRICTION_SCREWS.keys())
@pytest.mark.parametrize("spring", [{}, REAL_SPRING], ids=["zero_free_length", "real"])
def test_ledger_closes_on_a_screw_with_friction(spring: dict[str, float], screw: dict) -> None:
    """Payloads join and leave a swinging link while both drives push, the carriage raised
    through the screw (tens of newtons beyond load / eta_f) and lowered (tens of newtons
    beyond eta_b load): the ledger is constant to 1e-9 J and the screw's friction is in
    E_loss, beyond what the dampers dissipate. The run moves about 100 J, so the default
    ledger_accuracy (1e-9 of the throughput) would allow 1e-7 J (measured 3e-10 to 9e-10 J);
    at 1e-10 it stays within 1e-9 J (measured 1.3e-10 to 3.8e-10 J)."""
    p = physics.Parameters(**spring, **screw, omega0=0.5, q_dot0=0.02, J_drive=0.05,
                           m_drive_q=0.3, ledger_accuracy=1e-10)
    load = model.spring(p, math.pi, p.Y_B0).F_q - p.m_q * G   # the hanging link's, the most
    lift, lower = -load / p.eta_forward, -load * p.eta_backward
    schedule = [(0.05, 30.0 + lift, 0.0), (0.05, 10.0 + lift, 0.3), (-0.05, lower - 30.0, 0.1),
                (0.0, lower - 10.0, 0.1)]
    s, drift = run(p, schedule, 3000)
    assert drift < 1e-9
    assert s.W_adjust > 1.0 and s.E_loss > 0.5 * s.W_adjust and s.E_added != 0.0


def test_balanced_link_accelerates_uniformly_under_a_constant_torque() -> None:
    """Balanced (defaults, no payload) and frictionless: theta = theta0 + tau t^2 / (2 J)."""
    p = physics.Parameters(d_link=0.0, theta0=0.5)
    s, _ = run(p, [(0.02, 0.0, 0.0)], 1000)
    assert s.theta == pytest.approx(0.5 + 0.02 / (2 * 0.16), rel=1e-12)


# ---- the integrator's written-out stages ----------------------------------------------------

STAGE_CASES = [   # (parameters, inputs, state): carriage at rest, held, moving, back-drivable;
    # Tr 10x2 but where the lossless screws are named
    ({}, (0.1, 0.0, 0.5), (1.0, 0.3, 0.0, 0.0)),
    ({}, (0.1, -5.0, 0.0), (1.0, 0.3, 0.01, 0.0)),
    ({}, (-0.4, 30.0, 0.5), (0.7, -1.2, 0.02, 0.15)),
    ({**REAL_SPRING, "m_drive_q": 0.3}, (0.2, -20.0, 0.5), (2.5, 0.8, -0.01, -0.2)),
    ({**REAL_SPRING, **IDEAL, "self_locking": False}, (0.2, 3.0, 0.0), (-0.3, 0.5, 0.03, 0.1)),
    ({**IDEAL, "m_drive_q": 0.3}, (0.2, -20.0, 0.5), (2.5, 0.8, -0.01, -0.2)),
    # from rest the load breaks a back-drivable screw loose, against the actuator
    ({"mu": 0.03, "self_locking": False}, (0.1, 5.0, 0.5), (2.8, 0.3, 0.0, 0.0)),
]


@pytest.mark.parametrize(("params", "inputs", "start"), STAGE_CASES)
def test_stage_rates_are_the_spring_and_carriage_laws(params: dict, inputs: tuple,
                                                      start: tuple) -> None:
    """`derivatives` (the stages' rates written out) equals `tau_gravity` and `carriage` bit
    for bit, and `advance`'s RK4 sub-step equals `integration.rk4` over `derivatives`, at
    the case's state and at 40 angles and speeds around it (rounding shows in some)."""
    p, u = physics.Parameters(**params), physics.Inputs(*inputs)
    rates = physics._stage_rates(p, model.link_inertia(p, u.payload),
                                 model.gravity_moment(p, u.payload))
    theta0, omega0, q, q_dot = start
    direction = q_dot
    for theta, omega in [(theta0 + 0.37 * i, omega0 * (1.0 + 0.11 * i)) for i in range(40)]:
        s = physics.State(theta, omega, q, q_dot, 0.1, 0.2, 0.3, -0.0)
        Y_B = p.Y_B0 + q
        q_ddot, lock = model.carriage(
            p, u.F_adjust, model.spring(p, theta, Y_B).F_q - p.m_q * G, q_dot, direction)
        omega_dot = ((u.tau_drive + model.tau_gravity(p, u.payload, theta, Y_B)
                      - p.d_link * omega) / model.link_inertia(p, u.payload))
        loss_rate = p.d_link * omega * omega + p.d_q * q_dot * q_dot - lock * q_dot
        assert tuple(physics.derivatives(p, u, s)) == (omega, omega_dot, q_dot, q_ddot,
                                                       u.tau_drive * omega,
                                                       u.F_adjust * q_dot, loss_rate, 0.0)
        h = 0.05   # long enough for the increments to show the rounding of their sums
        reference = integration.rk4(partial(physics.derivatives, p, u, mode=(direction,)),
                                    s, h)
        step = integration.rk4_link_carriage_step(rates, u.tau_drive, u.F_adjust, s, h)
        assert type(step) is physics.State
        assert [(x, math.copysign(1.0, x)) for x in step] == [
            (x, math.copysign(1.0, x)) for x in reference]

# ---- active-design: eq. 27 ----------------------------------------------------------------

def eq27(options: dict[str, float], Y_B: float) -> float:
    """Spring moment plus gravity moment about O in the paper's frame (eqs. 17-21, 28), with
    the spring's direction from the coordinates: A = x1A (cos phi, sin phi), B = (XB, Y_B)."""
    phi = math.radians(options["phi"])
    XA, YA = options["x1A"] * math.cos(phi), options["x1A"] * math.sin(phi)
    length = math.hypot(options["XB"] - XA, Y_B - YA)
    F_s = options["Fs0"] + options["k"] * (length - options["ls0"])
    spring = (XA * (Y_B - YA) - YA * (options["XB"] - XA)) * F_s / length
    payload = options["mp"] + options["dmp"]
    return spring - (options["m1"] * options["OC1"] + payload * options["w"]) * G * math.cos(phi)


def solve(**options: float) -> active_design.Design:
    words = ["active-design", *(f"--{k}={v}" for k, v in options.items())]
    args = cli.parser("active-design").parse_args(words)
    return active_design.design(active_design.parameters(args), args.mp + args.dmp,
                                math.pi / 2 - math.radians(args.phi))


@pytest.mark.parametrize("phi", [-90.0, -60.0, -1.0, 0.0, 30.0, 89.0, 90.0])
@pytest.mark.parametrize("mp, dmp", [(0.0, 1.0), (2.0, -1.5)])
def test_design_matches_the_closed_form_at_every_angle(phi: float, mp: float,
                                                       dmp: float) -> None:
    """Zero-free-length spring, X_B = 0: Y_B' = (m1 OC1 + m_p' w) g / (k x1A) at every angle,
    the vertical (phi = +-90 deg, where eq. 27 holds for any Y_B) included."""
    d = solve(phi=phi, mp=mp, dmp=dmp, YB=0.12)
    expected = (M1 * OC1 + (mp + dmp) * W) * G / (K * X1A)
    assert d.Y_B_new == pytest.approx(expected, rel=1e-12)
    assert d.delta_Y_B == pytest.approx(expected - 0.12, rel=1e-9)
    assert d.equation == "27 / cos(phi_1)" and abs(d.residual) < 1e-12


@pytest.mark.parametrize("phi", [-70.0, 10.0, 45.0])
def test_design_with_the_frame_joint_off_the_vertical(phi: float) -> None:
    """Zero-free-length spring, X_B != 0 (paper's frame): eq. 27 gives
    k x1A (Y_B' cos(phi) - X_B sin(phi)) = M_g cos(phi), Y_B' = M_g / (k x1A) + X_B tan(phi)."""
    d = solve(phi=phi, XB=0.02, w=X1A)   # payload at A, the paper's case
    expected = (M1 * OC1 + 1.0 * X1A) * G / (K * X1A) + 0.02 * math.tan(math.radians(phi))
    assert d.Y_B_new == pytest.approx(expected, rel=1e-12)
    assert d.equation == "27"


@pytest.mark.parametrize("XB", [0.0, 0.03])
@pytest.mark.parametrize("phi", [-50.0, 20.0, 75.0])
def test_design_with_a_real_spring_solves_eq27(XB: float, phi: float) -> None:
    """A spring with free length 30 mm: eq. 27, computed here in the paper's frame, vanishes
    at the Y_B' found, and keeps one sign nearer to Y_B (the smallest adjustment)."""
    options = {**DEFAULT_OPTIONS, "Fs0": 20.0, "ls0": 0.0504, "XB": XB, "phi": phi, "dmp": 2.0}
    d = solve(**options)
    torque_scale = (M1 * OC1 + 2.0 * W) * G
    assert abs(eq27(options, d.Y_B_new)) < 1e-12 * torque_scale
    assert d.F_s > 0.0 and d.delta_Y_B > 0.0
    sign = math.copysign(1.0, eq27(options, 0.1))
    nearer = [0.1 + d.delta_Y_B * f for n in range(200) for f in (n / 200, -n / 200)]
    assert all(eq27(options, y) * sign > 0 for y in nearer)


def test_no_balancing_Y_B_exits_2_naming_the_options(capsys: pytest.CaptureFixture) -> None:
    """Vertical link, B off the vertical, zero-free-length spring: the spring's torque there
    is k x1A X_B whatever Y_B, so nothing balances."""
    assert cli.main(["active-design", "--json", "--phi", "90", "--XB", "0.02"]) == 2
    message = capsys.readouterr().err
    assert "no Y_B balances" in message and "--phi" in message and "--XB" in message


@pytest.mark.parametrize("option, value, named", [
    ("--k", "0", "option --k: k = 0.0 N/m is outside (0.0, inf)"),
    ("--x1A", "-0.1", "option --x1A"), ("--m1", "nan", "option --m1"),
    ("--mp", "-1", "option --mp"), ("--dmp", "-2", "option --dmp"),
    ("--phi", "inf", "option --phi")])
def test_bad_option_exits_2_naming_it(option: str, value: str, named: str,
                                      capsys: pytest.CaptureFixture) -> None:
    assert cli.main(["active-design", "--json", option, value]) == 2
    assert named in capsys.readouterr().err


def test_command_prints_json(capsys: pytest.CaptureFixture) -> None:
    """`active-design --json` with the defaults (Franchetti's link, 1 kg at w = 0.35 m,
    horizontal arm) moves B up by (1 kg w) g / (k x1A) = 58.3 mm."""
    assert cli.main(["active-design", "--json"]) == 0
    values = json.loads(capsys.readouterr().out)
    assert values["delta_Y_B"] == pytest.approx(W * G / (K * X1A), rel=1e-12)
    assert values["Y_B_new"] == pytest.approx(0.1 + W * G / (K * X1A), rel=1e-12)
    assert abs(values["residual"]) < 1e-12
