"""The sizing rule: the catalogue drive a designer picks for what a task asks of a joint
(docs/drives.md).

What the task asks (`JointLoad`): the effort the mechanism needs at the joint, less what
accelerates a drive's own rotor, with the joint's speed and acceleration, at every point of
a uniform time grid, and whether the drive is on there (a drive resting while its axis holds
by itself carries nothing). For a candidate drive (`evaluate`), the motor's torque is that
effort through the transmission (its efficiency where the motor drives the joint, its
efficiency with the load driving where the joint drives the motor: `transmission_factor`),
plus its rotor's inertia at the motor's acceleration; the current is that torque over K_t,
the voltage R_a i + K_t N omega (the armature's inductance is far too fast to matter here).

The rule (`choose`): a drive is feasible when, with the margin MARGIN on every figure,
- its RMS current over the task is within the motor's nominal current (continuous torque),
- its peak current within the amplifier's peak current (catalogue.PEAK_CURRENT_FACTOR),
- the motor's peak speed within the motor's and the gearhead's input limits,
- the peak voltage within the supply,
- the gearhead's RMS and peak output torque within its continuous and intermittent ratings.
Among feasible drives the designer takes the smallest motor (the least rated power P_nom) and,
for it, the gearhead and ratio that draw the least energy from the supply over the task
(the optimality criterion). Where no drive is feasible, the one least overloaded (the least
worst figure-to-limit ratio) is taken, and its sizing says it fails.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fmu_src.units.drive.dc_motor import transmission_factor
from harness.drive.catalogue import Drive

MARGIN = 1.25  # every figure times MARGIN must be within its limit


@dataclass(frozen=True)
class JointLoad:
    """What a task asks of a joint's drive on a uniform grid of step dt [s]: the effort
    [N m or N] without the drive's rotor, the joint's speed [rad/s or m/s] and acceleration
    [rad/s^2 or m/s^2], and whether the drive is on."""

    dt: float
    effort: np.ndarray
    speed: np.ndarray
    acceleration: np.ndarray
    enabled: np.ndarray

    @property
    def duration(self) -> float:
        return self.dt * len(self.effort)


@dataclass(frozen=True)
class Sizing:
    """A drive's figures over a task, and the limits they are held to."""

    drive: Drive
    I_rms: float           # [A]
    I_peak: float          # [A]
    omega_motor_peak: float  # [rad/s]
    V_peak: float          # [V]
    T_rms: float           # gearhead output torque (the joint effort through a screw) [N m]
    T_peak: float
    E_drawn: float         # the energy drawn from the supply over the task [J]

    def loads(self) -> dict[str, float]:
        """Each figure over its limit (feasible: all at most 1 / MARGIN)."""
        motor, gear = self.drive.motor, self.drive.gear
        ratios = {"I_rms / I_nom": self.I_rms / motor.I_nom,
                  "I_peak / I_peak_max": self.I_peak / motor.I_peak_max,
                  "motor speed / limit": self.omega_motor_peak / self.drive.omega_motor_max,
                  "V_peak / V_supply": self.V_peak / motor.V_nom}
        if gear is not None:
            ratios |= {"T_rms / T_cont": self.T_rms / gear.T_cont,
                       "T_peak / T_int": self.T_peak / gear.T_int}
        return ratios

    @property
    def worst(self) -> float:
        """The largest figure-to-limit ratio."""
        return max(self.loads().values())

    @property
    def feasible(self) -> bool:
        return self.worst * MARGIN <= 1.0


def evaluate(drive: Drive, load: JointLoad) -> Sizing:
    """A drive's figures over the task (see the module docstring)."""
    p = drive.parameters()
    effort, speed = load.effort, load.speed
    # the motor torque passes the effort through the transmission (the current has the
    # effort's sign), and accelerates the rotor
    through = effort / (p.N * transmission_factor(p, effort, speed))
    torque = np.where(load.enabled, through + p.J_rotor * p.N * load.acceleration, 0.0)
    current = torque / p.K_t
    voltage = np.where(load.enabled, p.R_a * current + p.K_t * p.N * speed, 0.0)
    # gearhead output torque: the joint effort, through the screw's ratio for a prismatic
    # joint (its thread's efficiency aside)
    screw = 1.0 if drive.screw is None else drive.screw.ratio
    output = np.where(load.enabled, effort, 0.0) / screw
    return Sizing(drive, float(np.sqrt(np.mean(current ** 2))), float(np.max(np.abs(current))),
                  float(np.max(np.abs(speed[load.enabled]), initial=0.0) * p.N),
                  float(np.max(np.abs(voltage))), float(np.sqrt(np.mean(output ** 2))),
                  float(np.max(np.abs(output))),
                  float(np.sum(np.maximum(voltage * current, 0.0)) * load.dt))


def choose(candidates: list[Drive], loads: list[JointLoad]) -> Sizing:
    """The rule (module docstring) over candidates for a joint's loads (one task, or several
    tasks it must all do: each figure is its worst over them, the energy their sum)."""
    sized = [combined([evaluate(drive, load) for load in loads]) for drive in candidates]
    feasible = [s for s in sized if s.feasible]
    if not feasible:
        return min(sized, key=lambda s: s.worst)
    smallest = min(s.drive.motor.P_nom for s in feasible)
    return min((s for s in feasible if s.drive.motor.P_nom == smallest),
               key=lambda s: s.E_drawn)


def combined(sizings: list[Sizing]) -> Sizing:
    """One drive's figures over several tasks: the worst of each, the energies summed."""
    first = sizings[0]
    return Sizing(first.drive, *(max(getattr(s, name) for s in sizings) for name in
                                 ("I_rms", "I_peak", "omega_motor_peak", "V_peak", "T_rms",
                                  "T_peak")), sum(s.E_drawn for s in sizings))
