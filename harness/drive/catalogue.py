"""The drive catalogue (catalogue.toml beside this file): real DC motors, planetary gearheads
and lead screws with their data-sheet values, and `Drive`, a joint's drive made of them.

A drive is a motor, optionally a gearhead at one of its ratios, and for a prismatic joint its
lead screw. Its model is a `MotorParameters` (fmu_src.units.drive.dc_motor): the transmission
ratio N = gear ratio x 2 pi / lead (motor radians per joint radian or metre), and the
transmission's efficiencies, the gearhead's (and the screw's unless the mechanism models its
thread). The catalogue gives a gearhead's efficiency with the motor driving, eta; with the
load driving, each stage's mesh friction, the same force on the reversed power flow, passes
2 - 1/eta_stage of it (eta_stage = eta^(1/stages)), docs/drives.md.
"""

from __future__ import annotations

import functools
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

from fmu_src.units.drive.dc_motor import MotorParameters
from harness.drive.motor import JointDrive
from harness.errors import UserError

CATALOGUE = Path(__file__).resolve().parent / "catalogue.toml"
RPM = 2.0 * math.pi / 60.0  # rad/s per rpm
# the drive amplifier's peak current, as a multiple of the motor's nominal current: a common
# setting for the short accelerations of a positioning task, far below the stall current
PEAK_CURRENT_FACTOR = 3.0


@dataclass(frozen=True)
class Motor:
    """A DC motor's data sheet, SI units (speeds in rad/s)."""

    name: str
    label: str
    part: str
    R_a: float
    L_a: float
    K_t: float
    J_rotor: float
    I_nom: float
    I_stall: float
    omega_0: float      # no-load speed at V_nom [rad/s]
    omega_max: float    # max. permissible speed [rad/s]
    V_nom: float
    P_nom: float
    gearheads: tuple[str, ...]

    @property
    def I_peak_max(self) -> float:
        """The largest current the drive's amplifier gives for short times [A]."""
        return min(PEAK_CURRENT_FACTOR * self.I_nom, self.I_stall)


@dataclass(frozen=True)
class GearStage:
    """A gearhead's variant of a number of stages, its ratios and ratings."""

    stages: int
    ratio: float
    eta: float          # efficiency with the motor driving
    T_cont: float       # max. continuous output torque [N m]
    T_int: float        # max. intermittent output torque [N m]

    @property
    def eta_back(self) -> float:
        """Efficiency with the load driving: 2 - 1/eta per stage (docs/drives.md)."""
        per_stage = self.eta ** (1.0 / self.stages)
        return (2.0 - 1.0 / per_stage) ** self.stages


@dataclass(frozen=True)
class Gearhead:
    name: str
    label: str
    omega_in_max: float  # max. input speed [rad/s]
    variants: tuple[GearStage, ...]


@dataclass(frozen=True)
class Screw:
    name: str
    label: str
    lead: float          # [m per turn]
    eta: float           # efficiency both ways (1 where the mechanism models the thread)
    in_mechanism: bool

    @property
    def ratio(self) -> float:
        """Screw radians per metre of travel, 2 pi / lead."""
        return 2.0 * math.pi / self.lead


@dataclass(frozen=True)
class Drive:
    """A joint's drive: a motor, a gearhead variant (None: the motor drives directly) and,
    for a prismatic joint, its screw."""

    motor: Motor
    gear: GearStage | None = None
    gearhead: Gearhead | None = None
    screw: Screw | None = None

    @property
    def gear_ratio(self) -> float:
        """The gearhead's reduction (1 without one)."""
        return 1.0 if self.gear is None else self.gear.ratio

    @property
    def N(self) -> float:
        """Transmission ratio, motor rad per joint rad (or per joint m through a screw)."""
        return self.gear_ratio * (1.0 if self.screw is None else self.screw.ratio)

    @property
    def eta(self) -> float:
        """The transmission's efficiency with the motor driving."""
        gear = 1.0 if self.gear is None else self.gear.eta
        return gear * (1.0 if self.screw is None or self.screw.in_mechanism else self.screw.eta)

    @property
    def eta_back(self) -> float:
        """The transmission's efficiency with the joint driving (docs/drives.md)."""
        gear = 1.0 if self.gear is None else self.gear.eta_back
        screw = (1.0 if self.screw is None or self.screw.in_mechanism
                 else 2.0 - 1.0 / self.screw.eta)
        return gear * screw

    @property
    def omega_motor_max(self) -> float:
        """The motor shaft's speed limit [rad/s]: the motor's, and the gearhead's input's."""
        limit = self.motor.omega_max
        return limit if self.gearhead is None else min(limit, self.gearhead.omega_in_max)

    def pin(self) -> dict[str, str | float]:
        """The drive as a scenario pins it (`pinned`): motor, and gearhead and ratio."""
        return {"motor": self.motor.name} | (
            {} if self.gearhead is None else {"gearhead": self.gearhead.name,
                                              "ratio": self.gear.ratio})

    @property
    def label(self) -> str:
        """E.g. 'maxon RE 30 60 W + maxon GP 32 C 111:1 + ball screw ...'."""
        parts = [self.motor.label]
        if self.gear is not None:
            parts.append(f"{self.gearhead.label} {self.gear.ratio:g}:1")
        if self.screw is not None:
            parts.append(self.screw.label)
        return " + ".join(parts)

    def joint_drive(self, lossless: bool = False) -> JointDrive:
        """The drive as a run puts it on a joint (lossless: its transmission's efficiencies
        1, as in the ideal loss set)."""
        return JointDrive(self.parameters(lossless), self.label, self.gear_ratio,
                          self.motor.I_nom, self.motor.P_nom)

    def parameters(self, lossless: bool = False, V_supply: float | None = None
                   ) -> MotorParameters:
        """The drive's model: the catalogue's efficiencies, or 1 (lossless); the supply at
        the motor's nominal voltage unless given."""
        m = self.motor
        return MotorParameters(R_a=m.R_a, L_a=m.L_a, K_t=m.K_t, J_rotor=m.J_rotor, N=self.N,
                               eta=1.0 if lossless else self.eta,
                               eta_back=1.0 if lossless else self.eta_back,
                               V_supply=m.V_nom if V_supply is None else V_supply)


@functools.cache
def catalogue(path: Path = CATALOGUE) -> tuple[dict[str, Motor], dict[str, Gearhead],
                                                dict[str, Screw]]:
    """The catalogue's motors, gearheads and screws by name, in file order."""
    data = tomllib.loads(path.read_text())
    motors = {name: Motor(name, d["label"], d["part"], d["R_a"], d["L_a"], d["K_t"],
                          d["J_rotor"], d["I_nom"], d["I_stall"], d["n_0"] * RPM,
                          d["n_max"] * RPM, d["V_nom"], d["P_nom"], tuple(d["gearheads"]))
              for name, d in data["motors"].items()}
    gearheads = {name: Gearhead(name, d["label"], d["n_in_max"] * RPM, tuple(
        GearStage(int(stages), ratio, s["eta"], s["T_cont"], s["T_int"])
        for stages, s in d["stages"].items() for ratio in s["ratios"]))
        for name, d in data["gearheads"].items()}
    screws = {name: Screw(name, d["label"], d["lead"], d.get("eta", 1.0), d["in_mechanism"])
              for name, d in data["screws"].items()}
    return motors, gearheads, screws


def drives(screw: str | None = None) -> list[Drive]:
    """Every drive the catalogue can build for a joint (with the named screw for a
    prismatic one): each motor direct and with each variant of each gearhead it mounts."""
    motors, gearheads, _ = catalogue()
    found = []
    for motor in motors.values():
        found.append(Drive(motor, screw=find_screw(screw)))
        for name in motor.gearheads:
            found += [Drive(motor, gear, gearheads[name], find_screw(screw))
                      for gear in gearheads[name].variants]
    return found


def find_screw(name: str | None) -> Screw | None:
    """The named screw (None for None); UserError naming the catalogue's screws."""
    if name is None:
        return None
    screws = catalogue()[2]
    if name not in screws:
        raise UserError(f"screw = {name!r} is not in the drive catalogue; choose from "
                        f"{', '.join(screws)}")
    return screws[name]


def pinned(spec: dict[str, object], screw: str | None, where: str) -> Drive:
    """The drive a scenario pins for a joint: {motor = ..., gearhead = ..., ratio = ...}
    (gearhead and ratio left out: the motor drives directly); UserError naming what the
    catalogue does not have."""
    motors, gearheads, _ = catalogue()
    unknown = sorted(set(spec) - {"motor", "gearhead", "ratio"})
    if unknown:
        raise UserError(f"{where}: drive key(s) {', '.join(unknown)} unknown; allowed: motor, "
                        "gearhead, ratio")
    motor = motors.get(str(spec.get("motor")))
    if motor is None:
        raise UserError(f"{where}: drive motor = {spec.get('motor')!r} is not in the "
                        f"catalogue; choose from {', '.join(motors)}")
    if "gearhead" not in spec:
        return Drive(motor, screw=find_screw(screw))
    name = str(spec["gearhead"])
    if name not in motor.gearheads:
        raise UserError(f"{where}: gearhead = {name!r} does not mount on {motor.name}; "
                        f"choose from {', '.join(motor.gearheads)}")
    gear = next((g for g in gearheads[name].variants if g.ratio == spec.get("ratio")), None)
    if gear is None:
        ratios = ", ".join(f"{g.ratio:g}" for g in gearheads[name].variants)
        raise UserError(f"{where}: ratio = {spec.get('ratio')!r} is not one of {name}'s "
                        f"({ratios})")
    return Drive(motor, gear, gearheads[name], find_screw(screw))
