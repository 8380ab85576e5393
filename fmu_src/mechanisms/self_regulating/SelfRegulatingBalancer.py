"""FMI 2.0 Co-Simulation slave of the self-regulating spring balancer (README.md).

A thin layer over `fmu_src.mechanisms.self_regulating.physics`: it maps FMI variables to the
physics, integrates it over each communication step, and reports misuse through the FMU log. """

from __future__ import annotations

import math
from typing import Any

from fmu_src.fmi.mechanism_slave import MechanismSlave
from fmu_src.fmi.vocabulary import DefaultExperiment
from fmu_src.mechanism import ANGULAR, Port, Registration, Run, one_link_panels, rest_to_rest_move
from fmu_src.mechanisms.self_regulating import design, equilibrium, model, physics
from fmu_src.parameters import DomainError

# How far from theta = pi (the reference configuration, paper Section 3) regulation warns.
REGULATION_ANGLE_TOLERANCE = 0.5 * model.DEG
# RMS residual torque over a full turn, as a fraction of the link's gravity moment
# (m c + payload w) g, above which a finished regulation warns that the design cannot balance.
BALANCE_TOLERANCE = 0.01


class SelfRegulatingBalancer(MechanismSlave):
    """1-DOF link balanced by a zero-free-length spring on a lockable slider, regulated by
    a pulley-counterweight (Franchetti et al. 2021)."""

    physics = physics
    hidden_state = (*MechanismSlave.hidden_state, "stop_reported", "off_angle_reported")
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=35.0, step_size=1e-3)
    calculated_parameters = (
        ("M0", "kg", "Counterweight mass holding the slider at b_design at theta = pi: eq. 10 "
         "for an ideal spring, a massless slider and a balancing b0"),
        ("b_design", "m", "Slider position M0 holds at theta = pi: least mean-square residual "
         "torque over a full turn and the payload range once regulated (b0 for Table 1)"),
        ("payload_max", "kg", "Payload capacity: regulation at theta = pi keeps the slider "
         "within b_max (eq. 16 for Table 1)"),
    )

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = ("Self-regulating gravity balancer (Franchetti, Boschetti, Lenzo "
                            "2021): 1-DOF link, zero-free-length spring on a lockable slider, "
                            "pulley-counterweight regulation")
        self.stop_reported = False
        self.off_angle_reported = False     # once per regulation (slider and pulley free)

    def initialise(self, params: physics.Parameters) -> None:
        self.stop_reported = self.off_angle_reported = False
        super().initialise(params)

    def step(self, dt: float) -> None:
        p, u = self.params, self.inputs()
        self.check_inputs(u)
        self.step_with(u, dt)
        at_stop = self.output_values.slider_at_stop
        if at_stop and not self.stop_reported:
            stop = "b_min" if self.state.b <= p.b_min else "b_max"
            self.warn(f"slider reached its end stop {stop} = {self.state.b:.4f} m: "
                      f"balance_error = {self.output_values.balance_error:.4g} N m")
        self.stop_reported = at_stop

    def check_inputs(self, u: physics.Inputs) -> None:
        """A DomainError (a refused step, an event's fmi2Error) for a counterweight lighter
        than nothing."""
        p = self.params
        if u.counterweight_added < -p.M0:
            raise DomainError(f"input counterweight_added = {u.counterweight_added} kg is "
                              f"outside [-M0, inf) = [{-p.M0:.6g}, inf)")

    def switch_inputs(self, u: physics.Inputs) -> None:
        self.report_misuse(self.params, u)
        super().switch_inputs(u)

    def report_misuse(self, p: physics.Parameters, u: physics.Inputs) -> None:
        """Warn, at the communication point where inputs change, about misuse the model allows."""
        before = self.previous_inputs
        released = before.slider_locked and not u.slider_locked
        if released and u.pulley_locked:
            self.warn("slider released with the pulley locked: nothing holds it against the "
                      f"spring, which pulls it towards b_min = {p.b_min} m")
        regulating = not u.slider_locked and not u.pulley_locked
        if not regulating:
            self.off_angle_reported = False
        elif not self.off_angle_reported:
            theta = self.state.theta
            off = abs(math.remainder(theta - math.pi, 2.0 * math.pi))
            if off > REGULATION_ANGLE_TOLERANCE:
                b_end = equilibrium.regulated_slider_position(p, u, theta)
                self.warn(f"regulating at theta = {math.degrees(theta):.2f} deg instead of 180 "
                          f"deg: the slider settles away from the balancing position (at "
                          f"b = {b_end:.4f} m for payload = {u.payload} kg)")
                self.off_angle_reported = True
        if regulating and u.payload > p.payload_max >= before.payload:
            self.warn(f"payload = {u.payload} kg exceeds payload_max = {p.payload_max:.4f} kg: "
                      "the slider will stop at b_max")
        if not before.slider_locked and u.slider_locked and not before.pulley_locked:
            self.check_balance(p, u.payload)
        if u.counterweight_added != before.counterweight_added and u.pulley_locked:
            self.warn("counterweight_added changed with the pulley locked: it acts only once "
                      "the pulley is released")

    def check_balance(self, p: physics.Parameters, payload: float) -> None:
        """Warn when the slider, just locked after a regulation, leaves the link unbalanced
        beyond BALANCE_TOLERANCE, naming the best position (and whether even that leaves
        more) and the counterweight that reaches it."""
        b = self.state.b
        residual = design.residual_torque_rms(p, payload, b)
        moment = (p.m * p.c + payload * p.w) * p.g
        if residual <= BALANCE_TOLERANCE * moment:
            return
        best = design.balancing_slider_position(p, payload)
        least = design.residual_torque_rms(p, payload, best)
        where = (f"the design cannot balance it: the least, {least:.3g} N m RMS, is at "
                 f"b = {best:.4f} m" if least > BALANCE_TOLERANCE * moment
                 else f"it balances at b = {best:.4f} m")
        self.warn(f"regulation left the link unbalanced with payload = {payload} kg: the "
                  f"slider was locked at b = {b:.4f} m, where the residual torque is "
                  f"{residual:.3g} N m RMS over a full turn ({100 * residual / moment:.1f} % "
                  f"of the gravity moment); {where} (regulation at 180 deg reaches it with "
                  f"counterweight_added = {design.counterweight_for(p, best):.4f} kg)")

    def restore_hidden_state(self, hidden: dict[str, Any]) -> None:
        super().restore_hidden_state(hidden)
        self.stop_reported = bool(hidden["stop_reported"])
        self.off_angle_reported = bool(hidden["off_angle_reported"])


REGISTRATION = Registration(
    physics=physics,
    ports=(Port(ANGULAR, "joint", "tau_drive", "omega", "theta"),),
    ledger={"E_t": 1, "E_cw": 1, "E_kin": 1, "E_loss": 1, "W_drive": -1, "E_added": -1},
    reference_run=rest_to_rest_move(
        {"tau_drive": (0.1, "N m")},
        {"payload": 0.0, "counterweight_added": 0.0, "slider_locked": 1.0, "pulley_locked": 1.0},
        ("theta", "omega", "b", "tau_gravity", "balance_error", "E_p", "E_e", "E_t", "E_kin",
         "slider_at_stop"), "; no payload, slider and pulley locked"),
    moving_run=Run({"k": 0.0}, duration=2.0),  # unbalanced link swinging from 60 deg
    dependency_probes=(
        # regulating away from theta = pi with the link driven: link, slider and
        # counterweight move (E_kin and E_cw feel the counterweight and the locks)
        Run({}, {"tau_drive": 2.0, "payload": 0.5, "counterweight_added": 0.8,
                 "slider_locked": False, "pulley_locked": False}, 0.3),
        # slider released with the pulley locked at theta = pi: the spring pulls it onto b_min
        Run({"theta0": math.pi}, {"tau_drive": 1.0, "slider_locked": False}, 1.0),
    ),
    initial_parameters={"omega0": 0.5},
    plot_panels=one_link_panels(("E_p", "E_e", "E_t"), ("delta_b",), ("x",)),
)
