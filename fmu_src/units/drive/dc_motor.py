"""DC motor with gearbox: the one definition of the drive model (standard library only).

Armature: L_a di/dt = V - R_a i - K_e N omega, written once in `armature_voltage` and
`armature_rate`, from which the state-space matrices, the zero-order-hold step and the
steady state derive. Joint-side effort (`transmitted_effort`, docs/drive_and_controller.md):
N K_t i passed on by a lossy transmission, eta N K_t i when the motor drives the joint (i
omega > 0), N K_t i / eta_back when the joint drives the motor (i omega < 0), as Modelica's
LossyGear does, blended to N K_t i at standstill (`STUCK_SPEED`). The drive's energies
(E_in, E_drawn, E_copper, E_gear, E_mech, W_link) are defined once too, as powers in
`drive_powers` and over a zero-order-hold step in `step_energies`, for the FMU, the
harness's metrics and CSV columns and the monolithic reference alike; both work elementwise
on floats and on numpy arrays. The drive's own energy account closes: E_in = E_copper +
E_gear + the work it passes to the joint + the change of the armature's magnetic energy.
Inputs (V, omega), outputs (tau_drive, i), state i. N is the transmission ratio, motor
radians per joint radian (a gearbox) or per joint metre (a lead screw, N = 2 pi / lead): the
same equations then give a force and a reflected mass.

Used by the harness (which builds the python-control model from `armature_matrices` and
discretises it with c2d) and by the `DcMotorDrive` FMU (which uses the closed-form zero-order
hold of `zoh_coefficients`); the tests check that both discretisations agree.

Default motor (the `legacy` drive configuration; the harness picks each joint's drive from
its catalogue, harness/drive/catalogue.toml): one coherent small geared DC motor, a 60 W
class 24 V graphite-brush motor with a 3-stage planetary gearhead (the data of the maxon RE
30 / 24 V datasheet, #310007: R_a = 0.611 Ohm, L = 0.119 mH, K_t = 25.9 mN m/A, rotor
inertia 33.5 g cm^2, nominal current 3.44 A; gear ratio 111:1). At the link that gives 2.87
N m/A, 9.9 N m at the motor's nominal current (the unbalanced Franchetti link with 1 kg
needs up to 9.3 N m), a no-load speed of 8.3 rad/s at 24 V (the task peaks at 0.4 rad/s),
and J_drive = J_rotor N^2 = 0.0413 kg m^2.

Enable: a drive switched off (`enabled` false: its amplifier's bridge open) carries no
current and applies no effort; the magnetic energy its armature held when it was switched off
is dissipated (booked in E_copper, the armature's losses). The default transmission is
lossless (eta = eta_back = 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, NamedTuple

from fmu_src.parameters import MAGNITUDE_LIMIT, check_ranges, parameter


@dataclass(frozen=True)
class MotorParameters:
    """Geared DC motor, SI units."""

    R_a: float = parameter(0.611, "Ohm", "Armature resistance", min=0.0, min_exclusive=True)
    L_a: float = parameter(0.119e-3, "H", "Armature inductance", min=0.0, min_exclusive=True)
    K_t: float = parameter(0.0259, "N.m/A", "Torque constant (= back-EMF constant, V s/rad)",
                           min=0.0, min_exclusive=True)
    J_rotor: float = parameter(33.5e-7, "kg.m2", "Rotor inertia", min=0.0)
    N: float = parameter(111.0, "1", "Transmission ratio, motor rad per joint rad (or per m)",
                         min=0.0, min_exclusive=True)
    eta: float = parameter(1.0, "1", "Transmission efficiency when the motor drives the joint "
                           "(i omega > 0)", min=0.0, max=1.0, min_exclusive=True)
    eta_back: float = parameter(1.0, "1", "Transmission efficiency when the joint drives the "
                                "motor (i omega < 0)", min=0.0, max=1.0, min_exclusive=True)
    V_supply: float = parameter(24.0, "V", "Supply voltage: |V| <= V_supply", min=0.0,
                                min_exclusive=True)

    def __post_init__(self) -> None:
        check_ranges(self)

    @property
    def J_drive(self) -> float:
        """Rotor inertia reflected to the joint, J_rotor N^2 [kg m^2, or kg for a screw]."""
        return self.J_rotor * self.N ** 2

    @property
    def torque_per_amp(self) -> float:
        """Joint-side effort per armature ampere while the motor drives the joint, eta N K_t
        [N m/A or N/A]: the plant gain the controller is designed for."""
        return self.eta * self.N * self.K_t

    @property
    def standstill_torque_per_amp(self) -> float:
        """Joint-side effort per armature ampere at standstill, N K_t [N m/A or N/A]: what
        holds a static load."""
        return self.N * self.K_t

    @property
    def blend_speed(self) -> float:
        """The joint speed below which the transmission blends into its stuck mode,
        STUCK_SPEED / N [rad/s or m/s]."""
        return STUCK_SPEED / self.N

    @property
    def back_emf_per_link_speed(self) -> float:
        """Armature back-EMF per joint speed, K_e N [V s/rad]."""
        return self.K_t * self.N


def armature_voltage(p: MotorParameters, current: Any, omega: Any) -> Any:
    """The armature's resistive drop plus its back-EMF, R_a i + K_e N omega [V], at current
    i [A] and joint speed omega [rad/s or m/s]: the voltage that holds i steady."""
    return p.R_a * current + p.back_emf_per_link_speed * omega


# The motor speed [rad/s] above which the transmission's efficiency applies in full: below
# it the efficiency blends linearly to lossless at standstill, a regularised stuck mode
# (docs/drive_and_controller.md). A lossy gear at standstill passes any torque between its
# two efficiencies' values, set by the load; a co-simulation step hands the mechanism one
# held value, so a sharp switch at zero speed would make a holding joint chatter between the
# two. 1 rad/s is about 10 rpm, a thousandth of the catalogue motors' speeds.
STUCK_SPEED = 1.0


def transmission_factor(p: MotorParameters, current: Any, omega: Any) -> Any:
    """The effort the transmission passes on per N K_t i [1]: eta where the motor drives the
    joint (i omega > 0), 1 / eta_back where the joint drives the motor (i omega < 0), blended
    linearly to 1 below the motor speed STUCK_SPEED. Elementwise on floats and numpy arrays."""
    sign = (current > 0.0) * 1.0 - (current < 0.0) * 1.0
    drive = sign * omega * p.N / STUCK_SPEED   # > 0: the motor drives; full at 1
    forward, backward = positive_part(drive), positive_part(-drive)
    forward = forward - positive_part(forward - 1.0)
    backward = backward - positive_part(backward - 1.0)
    return 1.0 + forward * (p.eta - 1.0) + backward * (1.0 / p.eta_back - 1.0)


def transmitted_effort(p: MotorParameters, current: Any, omega: Any) -> Any:
    """The effort [N m or N] the transmission applies to the joint at armature current i [A]
    and joint speed omega [rad/s or m/s]: N K_t i times `transmission_factor`."""
    return p.N * p.K_t * current * transmission_factor(p, current, omega)


def stuck_damping(p: MotorParameters, current: float, omega: float) -> float:
    """The regularised stuck mode's damping, -d(transmitted_effort)/d(omega) at (i, omega)
    [N m s/rad or N s/m]: N K_t |i| N / STUCK_SPEED times the direction's loss, 1 - eta where
    the motor drives the joint and 1/eta_back - 1 where the joint drives it (the larger at
    standstill), inside the blend (motor speed below STUCK_SPEED); 0 outside it."""
    edge = p.blend_speed
    if not -edge < omega < edge:
        return 0.0
    forward, backward = 1.0 - p.eta, 1.0 / p.eta_back - 1.0
    drive = omega * current
    loss = forward if drive > 0.0 else backward if drive < 0.0 else max(forward, backward)
    return p.standstill_torque_per_amp * abs(current) * p.N / STUCK_SPEED * loss


def held_effort(p: MotorParameters, current: float, omega: float, effort: float,
                inertia: float, dt: float, load: float) -> float:
    """The effort [N m or N] a drive holds over a step of dt [s] in a co-simulation: the
    transmission's effort at the joint's speed at the step's end rather than at its start.

    Inside the blend of the stuck mode the effort falls steeply with the speed (damping c,
    `stuck_damping`); held at the start speed omega, it makes the loop unstable once c dt /
    inertia > 2, and the joint then chatters through standstill at a rate set by the step
    (docs/drives.md). Linearly implicit instead: from effort, transmitted_effort(i, omega),
    with the joint's inertia [kg m^2 or kg] and the other efforts on it, load [N m or N] (as
    estimated from the last step), the speed at the step's end is omega + dt (load + E) /
    inertia, and the held effort is

        E = (effort - r load) / (1 + r),   r = c dt / inertia,

    kept within what the gear can pass at that speed: between its lossless value N K_t i and
    its value at full efficiency in omega's direction, or between its two efficiencies'
    values at standstill, so that its loss (N K_t i - effort) omega is never negative.
    Outside the blend, or with a lossless transmission, it is effort; as dt goes to 0 it
    tends to it, so the scheme converges to the same model."""
    damping = stuck_damping(p, current, omega)
    if damping == 0.0:
        return effort
    ratio = damping * dt / inertia
    implicit = (effort - ratio * load) / (1.0 + ratio)
    lossless = p.standstill_torque_per_amp * current
    if omega == 0.0:
        ends = (lossless * p.eta, lossless / p.eta_back)
    else:
        ends = (lossless, lossless * (p.eta if current * omega > 0.0 else 1.0 / p.eta_back))
    return min(max(implicit, min(ends)), max(ends))


def stuck_mode_effort(p: MotorParameters, current: float, omega: float, effort: float,
                      inertia: float, dt: float,
                      previous: tuple[float, float, float] | None) -> float:
    """The effort [N m or N] a drive holds over a step of dt [s] in a co-simulation, given
    the effort at the step's start speed: the linearly implicit `held_effort` (the effort
    given outside the stuck mode's blend), with the joint's inertia [kg m^2 or kg] and the
    other efforts on the joint estimated from the step before, the acceleration they and its
    held effort gave: load = inertia (omega - omega_before) / dt_before - effort_before.
    previous: (omega_before, effort_before, dt_before) of the step before, None when the
    drive was off over it or there was none (the effort is then the one given)."""
    if previous is None:
        return effort
    omega_before, effort_before, dt_before = previous
    load = inertia * (omega - omega_before) / dt_before - effort_before
    return flushed(held_effort(p, current, omega, effort, inertia, dt, load))


def armature_rate(p: MotorParameters, voltage: Any, current: Any, omega: Any) -> Any:
    """The armature equation, di/dt = (V - R_a i - K_e N omega) / L_a [A/s]."""
    return (voltage - armature_voltage(p, current, omega)) / p.L_a


def steady_current(p: MotorParameters, voltage: Any, omega: Any) -> Any:
    """The current [A] the armature settles at with V [V] and omega held: di/dt = 0."""
    return (voltage - armature_voltage(p, 0.0, omega)) / p.R_a


def armature_matrices(p: MotorParameters) -> tuple[list, list, list, list]:
    """(A, B, C, D) of the motor: state i; inputs (V, omega); outputs (tau_drive, i)."""
    A = [[armature_rate(p, 0.0, 1.0, 0.0)]]
    B = [[armature_rate(p, 1.0, 0.0, 0.0), armature_rate(p, 0.0, 0.0, 1.0)]]
    C = [[p.torque_per_amp], [1.0]]
    D = [[0.0, 0.0], [0.0, 0.0]]
    return A, B, C, D


class StepCoefficients(NamedTuple):
    """Zero-order-hold step of dt [s] of the armature, i[k+1] = a i + b_v V + b_w omega, and
    the step-average current i_avg = avg_a i + avg_b_v V + avg_b_w omega."""

    a: float
    b_v: float
    b_w: float
    avg_a: float
    avg_b_v: float
    avg_b_w: float
    dt: float

    def start_current(self, average: Any, voltage: Any, omega: Any) -> Any:
        """The current [A] at the start of a step from its average [A] and the V [V] and
        omega held over it (elementwise on numpy arrays): the inverse of the average."""
        return (average - self.avg_b_v * voltage - self.avg_b_w * omega) / self.avg_a


def zoh_coefficients(p: MotorParameters, dt: float) -> StepCoefficients:
    """Exact zero-order-hold discretisation of the armature over dt [s], in closed form.

    Written with expm1 and the series of `relaxation_integrals`, so that it keeps full
    precision down to steps far shorter than L_a/R_a (1e-16 s and below).
    """
    x = p.R_a / p.L_a * dt
    rise, _ = relaxation_integrals(x)        # step-average of 1 - exp(-t R_a/L_a)
    settle = -math.expm1(-x)                  # 1 - exp(-dt R_a/L_a)
    per_volt, per_speed = steady_current(p, 1.0, 0.0), steady_current(p, 0.0, 1.0)
    return StepCoefficients(math.exp(-x), settle * per_volt, settle * per_speed, 1.0 - rise,
                            rise * per_volt, rise * per_speed, dt)


@lru_cache(maxsize=8)  # one step size at a time, in practice
def relaxation_integrals(x: float) -> tuple[float, float]:
    """Step averages of psi = 1 - exp(-t/tau) and of psi^2 over a step of x = dt/tau.

    g = 1 - (1 - e^-x)/x and q = 1 - 2 (1 - e^-x)/x + (1 - e^-2x)/(2x). Both vanish like x
    (g ~ x/2, q ~ x^2/3) and their closed forms cancel catastrophically for small x, so
    below x = 1 they are summed from their Taylor series, g = sum (-1)^(n+1) x^n/(n+1)! and
    q = sum_(n>=2) (-1)^n (2^n - 2) x^n/(n+1)! (30 terms: below 1e-19 relative at x = 1).
    """
    if x >= 1.0:
        mean, mean_double = -math.expm1(-x) / x, -math.expm1(-2.0 * x) / (2.0 * x)
        return 1.0 - mean, 1.0 - 2.0 * mean + mean_double
    g = q = 0.0
    power, factorial = 1.0, 1.0
    for n in range(1, 31):
        power *= -x                    # (-x)^n
        factorial *= n + 1             # (n+1)!
        g -= power / factorial
        q += power * (2.0 ** n - 2.0) / factorial
    return g, q


class SampledMotor:
    """The motor under zero-order-hold inputs, stepped one communication interval at a time.

    The armature time constant L/R_a (0.19 ms by default) is shorter than a 1 ms step, so
    the current moves within a step: the effort applied over the step is that of the
    step-average current, and V i_avg dt is the exact electrical energy of the step.
    """

    def __init__(self, motor: MotorParameters, coefficients: StepCoefficients,
                 current: float = 0.0) -> None:
        self.motor = motor
        self.coefficients = coefficients
        self.current = current

    def step(self, voltage: float, omega: float, enabled: bool = True) -> tuple[float, float]:
        """Advance one step with V [V] and omega held; returns (average current [A], effort).
        Switched off (enabled false), the armature carries no current from the step's start
        and the effort is 0."""
        if not enabled:
            self.current = 0.0
            return 0.0, 0.0
        a, b_v, b_w, avg_a, avg_b_v, avg_b_w, _ = self.coefficients
        i0 = self.current
        average = flushed(avg_a * i0 + avg_b_v * voltage + avg_b_w * omega)
        self.current = flushed(a * i0 + b_v * voltage + b_w * omega)
        return average, flushed(transmitted_effort(self.motor, average, omega))


def flushed(value: float) -> float:
    """value, or 0 where its magnitude is below 1 / MAGNITUDE_LIMIT, the smallest non-zero
    input the mechanism FMUs take (docs/robustness.md): a current that decays geometrically
    through a long hold at rest (no voltage, no speed) reaches it, and the effort it drives
    is nothing then (below 1e-50 A, 1e-100 J)."""
    return 0.0 if -1.0 / MAGNITUDE_LIMIT < value < 1.0 / MAGNITUDE_LIMIT else value


def copper_energy(p: MotorParameters, dt: float, voltage: Any, omega: Any, i_start: Any) -> Any:
    """Armature copper loss R_a * integral of i^2 dt [J] over one zero-order-hold step of dt [s]
    (elementwise over steps given as numpy arrays).

    Exact for the step's solution i(t) = i_start + (i_end_of_settling - i_start) psi(t), with
    psi = 1 - exp(-t R_a/L_a), V [V] and omega [rad/s] held: the integral of i^2 is
    dt (i0^2 + 2 i0 delta g + delta^2 q) with g, q the step averages of psi and psi^2
    (`relaxation_integrals`), a sum of non-negative terms where the energy balance over the
    step would cancel catastrophically for steps far below L_a/R_a.
    """
    delta = steady_current(p, voltage, omega) - i_start
    g, q = relaxation_integrals(p.R_a / p.L_a * dt)
    return p.R_a * dt * positive_part(i_start * i_start + 2.0 * i_start * delta * g
                                      + delta * delta * q)


def inductor_energy(p: MotorParameters, current: Any) -> Any:
    """Magnetic energy of the armature at current i [A], L_a i^2 / 2 [J]."""
    return 0.5 * p.L_a * current * current


def positive_part(x: Any) -> Any:
    """max(x, 0), elementwise on floats and numpy arrays alike: (x + |x|) / 2."""
    return (x + abs(x)) * 0.5


class DriveEnergies(NamedTuple):
    """A drive's energies [J] (as returned by `step_energies`), or their rates [W] (as
    returned by `drive_powers`); floats or numpy arrays."""

    E_in: Any       # net electrical energy, V i (regeneration credited)
    E_drawn: Any    # from a supply that cannot take energy back, max(V i, 0)
    E_copper: Any   # armature copper loss, R_a i^2
    E_gear: Any     # transmission loss, (N K_t i - tau) omega
    E_mech: Any     # mechanical work in either direction, |tau omega|
    W_link: Any     # net mechanical work of the drive on the joint, tau omega


def drive_powers(p: MotorParameters, voltage: Any, current: Any, effort: Any,
                 speed: Any) -> DriveEnergies:
    """The definition of the drive's energies, as their rates [W]: at voltage V [V], armature
    current i [A], effort tau [N m or N] and joint speed omega [rad/s or m/s], V i,
    max(V i, 0), R_a i^2, (N K_t i - tau) omega, |tau omega| and tau omega."""
    electrical, mechanical = voltage * current, effort * speed
    return DriveEnergies(electrical, positive_part(electrical), p.R_a * current * current,
                         (p.standstill_torque_per_amp * current - effort) * speed,
                         abs(mechanical), mechanical)


def step_energies(p: MotorParameters, dt: float, voltage: Any, omega: Any, i_start: Any,
                  i_average: Any, effort: Any, travel: Any, enabled: Any = True) -> DriveEnergies:
    """The energies [J] of zero-order-hold steps of dt [s]: `drive_powers` integrated over
    each step in which V [V], omega [rad/s or m/s] and the effort [N m or N] are held, the
    armature current starts at i_start [A] and averages i_average [A], and the joint travels
    `travel` [rad or m].

    V i and tau omega are linear in the step's averages, so their integrals E_in and W_link
    are exact; E_copper, quadratic in the current, is the exact `copper_energy`; E_gear is the
    motor's shaft work K_t N omega i_average dt less what the transmission passes on at the
    held speed, exact as both are linear in the current; E_drawn and E_mech are exact while
    V i and tau omega keep their signs within the step. A step with the drive switched off
    (enabled false: no current, no effort) dissipates the armature's magnetic energy at its
    start, L_a i_start^2 / 2, in E_copper.
    """
    on = enabled * 1.0
    powers = drive_powers(p, voltage, i_average, effort, travel / dt)
    copper = (on * copper_energy(p, dt, voltage, omega, i_start)
              + (1.0 - on) * inductor_energy(p, i_start))
    gear = (p.standstill_torque_per_amp * i_average - effort) * omega * dt
    return DriveEnergies(powers.E_in * dt, powers.E_drawn * dt, copper, gear,
                         powers.E_mech * dt, powers.W_link * dt)


# The drive of a prismatic joint: the default motor (same RE 30 data, one motor type for both
# drives of an arm) coupled directly to a ball screw of lead 40 mm (a high-lead screw), so
# N = 2 pi / lead = 157.08 motor rad per joint metre, K = N K_t = 4.07 N/A, reflected mass
# J_rotor N^2 = 0.083 kg (a sixth of demian2022's 0.5 kg slider: the joint's dynamics stay
# the arm's). Capacity: 14.0 N at the nominal current against the 3.16 N of m2 g sin q1 that
# the uncompensated demian2022 arm needs at q1 = 0.7 rad (3.37 N for the back-drivable
# variant's worst residual), plus about 0.1 N to accelerate slider and rotor; 5.9 m/s no-load
# speed at 24 V against the task's 0.19 m/s. Why so long a lead: the armature's back-EMF
# damping of the joint, alpha = (N K_t)^2 / (R_a (m2 + J_rotor N^2)), grows with N towards
# K_t^2 / (R_a J_rotor) = 328 1/s; at 40 mm it is 46 1/s, below the 3 omega_c = 75 1/s that
# the default PID design places (harness.drive.controller), where a short lead (e.g. 5 mm: 299 1/s)
# would need a negative derivative gain. Efficiency: a ball screw is back-drivable at about
# 0.9 both ways, but this linear model would make eta < 1 return more than it takes when the
# drive regenerates (see the module docstring): eta = 1, losses left to the joint's friction.
LEAD_SCREW_MOTOR = MotorParameters(N=2.0 * math.pi / 0.040)


# The drive of a joint that must hold a load without power: the default motor (RE 30 data)
# coupled directly to a self-locking trapezoidal screw Tr 10x2 (lead 2 mm), so N = 2 pi /
# lead = 3141.6 motor rad per joint metre, K = N K_t = 81.4 N/A, reflected mass J_rotor N^2 =
# 33.1 kg. Its effort is the force on the screw; the screw's thread friction is the mechanism
# FMU's (ActiveSpringBalancer: forward efficiency 0.403 on a bronze nut), so eta = 1 here as
# for the other drives (see the module docstring) and the motor's energies include the
# screw's loss. Sized for the pull of franchetti2021's spring on its relocated frame joint
# (k = 981 N/m): with the link hanging (theta = 180 deg) the carriage carries k (Y_B + x1A) +
# m_q g, 162 N at the start and 219 N after relocating for 1 kg (Y_B = 0.158 m), which the
# motor meets through the screw with up to 544 N, 6.7 A: twice the 3.44 A nominal current,
# for the 3 s of regulation; 1110 N (13.7 A) for 5 kg, the end of the regulation sweep.
# Speed: 0.295 m/s no-load at 24 V against 0.036 m/s at the peak of the 3 s quintic to 58 mm
# (0.18 m/s for 5 kg). Why a screw of this lead: its lead angle atan(lead / (pi d2)) = 4.05
# deg (d2 = 9 mm) is below the friction angle of a lubricated steel-on-bronze thread (5.91
# deg at mu = 0.1 with 15 deg flanks), so the load cannot back-drive it and the carriage
# stays where it is put without current; the 2 mm lead is also the reduction the force
# needs, so no gearhead. The reflected mass dominates the joint (33.1 kg against the 0.5 kg
# carriage), so the armature's back-EMF damps it at K_t^2 / (R_a J_rotor) = 326 1/s, above
# 3 omega_c: the PID design then drops the derivative term (harness.drive.controller).
TRAPEZOIDAL_SCREW_MOTOR = MotorParameters(N=2.0 * math.pi / 0.002)
