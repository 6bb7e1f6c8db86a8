"""Steppable plants: one motor on a shaft, with the effects of CONTRACT §3.

A plant advances by one sample period at a time (:meth:`MotorPlant.advance`) and is read
at the sample instants (:meth:`MotorPlant.measure`). The same object sits behind the
direct simulation (:mod:`stand.physics.simulate`) and behind a simulated CiA 402 drive on
the bus, so both see identical physics.

Mechanics::

    J·ω' = Kt·i·(1 + ε·sin(Nr·θ + φr)) − D·ω − C·θ − Tcog·sin(Nc·θ + φc)
           − T_friction(ω) − T_backlash

integrated in sub-steps ``h`` of at most :data:`MAX_SUBSTEP_S` so that the samples are
those of the continuous system (``python tests/bench/bench_plant.py``: within 1e-5 of the
angle's range of a 1 µs reference, second order in ``h``). Per sub-step, position Verlet:
the torques that depend on the angle and speed are taken at the predicted mid-step state;
the current is the armature's exact exponential over the sub-step (its mean drives the
speed, its ramp-weighted mean the angle, :mod:`stand.physics.armature`); viscous damping
is trapezoidal. Dry friction (Coulomb, Stribeck, Karnopp sticking): a zero crossing of the
speed is located inside the sub-step, and so is the breakaway of a sticking shaft.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from stand.physics.armature import Armature
from stand.physics.effects import Effects
from stand.physics.parts import DriveParams, MotorParams, SensorParams

#: Longest sub-step of the integration, s.
MAX_SUBSTEP_S = 1e-4
#: Contact mode of backlash and reducer couplings when no stiffness is given, Hz.
CONTACT_MODE_HZ = 150.0
#: Damping ratio of such contacts.
CONTACT_DAMPING_RATIO = 0.3


@dataclass(frozen=True)
class Measurement:
    """What a drive reports at one sample instant (SI units)."""

    position_rad: float
    current_A: float
    velocity_rad_s: float
    voltage_V: float
    #: The current averaged over the sample period that ends now, through the same
    #: sensor (its delay, offset and noise), A.
    current_mean_A: float = 0.0


def substeps_for(dt_s: float) -> int:
    """Number of sub-steps for a sample period of ``dt_s`` seconds."""
    return max(1, math.ceil(dt_s / MAX_SUBSTEP_S - 1e-9))


def contact_constants(J_a: float, J_b: float, stiffness: float) -> tuple[float, float]:
    """Stiffness (N·m/rad) and damping (N·m·s/rad) of a contact between two inertias."""
    J_eff = J_a * J_b / (J_a + J_b)
    k = stiffness or J_eff * (2 * math.pi * CONTACT_MODE_HZ) ** 2
    return k, 2 * CONTACT_DAMPING_RATIO * math.sqrt(k * J_eff)


def friction_levels(effects: Effects) -> tuple[float, float, float]:
    """Coulomb level, static excess (Ts − Tc) and Stribeck velocity of all friction."""
    coulomb = effects.coulomb_friction.Tc if effects.coulomb_friction else 0.0
    excess, ws = 0.0, 1.0
    if effects.stribeck_friction:
        s = effects.stribeck_friction
        coulomb += s.Tc
        excess, ws = s.Ts - s.Tc, s.ws
    return coulomb, excess, ws


class Sensors:
    """Encoder, current sensor and tachometer of one motor, with their noise."""

    def __init__(self, params: SensorParams, effects: Effects, rng: np.random.Generator):
        self.params = params
        self.rng = rng
        counts = params.counts_per_rev
        self.step_rad = 2 * math.pi / counts if counts else 0.0
        self.offset_A = effects.current_offset.i0 if effects.current_offset else 0.0
        delay = effects.delay.k if effects.delay else 0
        #: (sampled current, period mean) of the last ``delay + 1`` samples.
        self.current_history: deque[tuple[float, float]] = deque(maxlen=delay + 1)
        # the period mean's noise from its own stream: the sampled current's draws, and
        # so every run simulated before the period mean was recorded, stay as they were
        self.mean_rng = rng.spawn(1)[0]
        self.last_position: float | None = None

    def read(self, theta: float, omega: float, current: float, voltage: float,
             dt_s: float, current_mean: float = 0.0) -> Measurement:
        """The sensors now; ``current_mean`` is the current averaged over the period
        that ends now, A."""
        p = self.params
        position = theta
        if self.step_rad:
            position = math.floor(theta / self.step_rad) * self.step_rad
        self.current_history.append((current, current_mean))
        late_i, late_mean = self.current_history[0]  # k samples ago
        measured_i, measured_mean = late_i + self.offset_A, late_mean + self.offset_A
        if p.current_noise_A:
            measured_i += p.current_noise_A * self.rng.standard_normal()
            # as noisy as one sample: a drive's average of its current loop's samples
            # is at most that, and no quieter average is assumed
            measured_mean += p.current_noise_A * self.mean_rng.standard_normal()
        if p.velocity_noise_rad_s is not None:
            velocity = omega + p.velocity_noise_rad_s * self.rng.standard_normal()
        elif self.last_position is None:
            velocity = 0.0
        else:
            velocity = (position - self.last_position) / dt_s
        self.last_position = position
        if p.voltage_noise_V:
            voltage += p.voltage_noise_V * self.rng.standard_normal()
        return Measurement(position, measured_i, velocity, voltage, measured_mean)


class MotorPlant:
    """One motor, its drive and sensors, optionally with an attached inertia.

    Parameters
    ----------
    motor, drive, sensors : parts
        The stand's parts.
    effects : Effects
        Unmodelled effects to include.
    added_inertia : float
        Inertia rigidly attached to the shaft (seed 000 §4.2 disk), kg·m².
    seed : int or None
        Seed of the sensor noise.
    """

    ports = 1

    def __init__(self, motor: MotorParams, drive: DriveParams | None = None,
                 sensors: SensorParams | None = None, effects: Effects | None = None,
                 added_inertia: float = 0.0, seed: int | None = None) -> None:
        self.motor = motor
        self.effects = effects or Effects()
        self.armature = Armature(motor, drive or DriveParams())
        self.sensors = Sensors(sensors or SensorParams(), self.effects,
                               np.random.default_rng(seed))
        self.J = motor.J + added_inertia
        self.theta = 0.0
        self.omega = 0.0
        #: Acceleration over the last sub-step, rad/s² (predicts the mid-step speed).
        self.accel = 0.0
        self.time_s = 0.0
        #: The armature current averaged over the last :meth:`advance`, A.
        self.period_current = 0.0
        e = self.effects
        self.coulomb, self.static_excess, self.stribeck_ws = friction_levels(e)
        self.cogging = (e.cogging.Tcog, e.cogging.N, e.cogging.phi) if e.cogging else None
        self.ripple = (
            (e.torque_ripple.eps, e.torque_ripple.N, e.torque_ripple.phi)
            if e.torque_ripple else None
        )
        self.backlash = None
        #: A torque outside the effect vocabulary, N·m, of (θ rad, ω rad/s, i A, t s),
        #: opposing the motor like friction (a benchmark's effects the diagnosis does
        #: not know); None: none.
        self.extra_torque: Callable[[float, float, float, float], float] | None = None
        self.theta_load = self.omega_load = 0.0
        if e.backlash:
            k, c = contact_constants(self.J, e.backlash.J_load, e.backlash.stiffness)
            self.backlash = (e.backlash.gap, e.backlash.J_load, k, c)

    def command(self, mode: str, target: float, port: int = 0) -> None:
        """Set the drive's mode (``voltage``, ``current``, ``speed``) and target."""
        self.armature.command(mode, target)

    def measure(self, dt_s: float, port: int = 0) -> Measurement:
        """Read the sensors now; ``dt_s`` is the sample period (for the velocity)."""
        return self.sensors.read(self.theta, self.omega, self.armature.i,
                                 self.armature.v, dt_s, self.period_current)

    def advance(self, dt_s: float) -> None:
        """Advance the physics by ``dt_s`` seconds (the scheme: the module's docstring)."""
        n = substeps_for(dt_s)
        h = dt_s / n
        arm = self.armature
        arm.prepare(h)
        Kt, D, C, J = self.motor.Kt, self.motor.D, self.motor.C, self.J
        coulomb, excess, ws = self.coulomb, self.static_excess, self.stribeck_ws
        breakaway = coulomb + excess
        cogging, ripple, backlash = self.cogging, self.ripple, self.backlash
        theta, omega, accel = self.theta, self.omega, self.accel
        theta_l, omega_l = self.theta_load, self.omega_load
        extra = self.extra_torque
        damp = 0.5 * h * D / J
        charge = 0.0
        for sub in range(n):
            i_start = arm.i
            theta_m = theta + 0.5 * h * omega  # position Verlet: forces at mid-step
            omega_m = omega + 0.5 * h * accel
            arm.step(h, omega_m)
            charge += arm.i_mean
            gain = 1.0 + ripple[0] * math.sin(ripple[1] * theta_m + ripple[2]) if ripple else 1.0
            load = C * theta_m  # torques other than the motor's, viscous friction
            if extra is not None:
                load += extra(theta_m, omega_m, arm.i_mean, self.time_s + (sub + 0.5) * h)
            if cogging:
                load += cogging[0] * math.sin(cogging[1] * theta_m + cogging[2])
            if backlash:
                gap, J_load, k, c = backlash
                twist = theta_m - theta_l - 0.5 * h * omega_l
                contact = 0.0
                if twist > gap:
                    contact = max(0.0, k * (twist - gap) + c * (omega_m - omega_l))
                elif twist < -gap:
                    contact = min(0.0, k * (twist + gap) + c * (omega_m - omega_l))
                load += contact
                new_l = omega_l + h * contact / J_load
                theta_l += 0.5 * h * (omega_l + new_l)
                omega_l = new_l
            drive = Kt * gain
            if breakaway > 0.0:
                theta_new, omega_new = _friction_substep(
                    h, J, damp, theta, omega, omega_m, drive, i_start, arm, load,
                    coulomb, excess, ws, breakaway)
            else:
                theta_new, omega_new = _slide(h, J, damp, theta, omega, drive, arm,
                                              drive * arm.i_mean - load)
            accel = (omega_new - omega) / h
            theta, omega = theta_new, omega_new
        self.theta, self.omega, self.accel = theta, omega, accel
        self.period_current = charge / n
        self.theta_load, self.omega_load = theta_l, omega_l
        self.time_s += dt_s


def _slide(h: float, J: float, damp: float, theta: float, omega: float, drive: float,
           arm: Armature, force: float) -> tuple[float, float]:
    """One sub-step of a shaft that keeps moving; return the new angle and speed.

    ``force`` is the torque over the sub-step but the viscous damping (``damp`` =
    ``h·D/(2J)``, trapezoidal), the motor's at the armature's mean current: the speed
    takes it whole, the angle also the shape of the current within the sub-step (its
    ramp-weighted mean against its mean, ``drive`` N·m/A)."""
    omega_new = (omega * (1.0 - damp) + h * force / J) / (1.0 + damp)
    return (theta + 0.5 * h * (omega + omega_new)
            + 0.5 * h * h * drive * (arm.i_ramp - arm.i_mean) / J), omega_new


def _friction_substep(h: float, J: float, damp: float, theta: float, omega: float,
                      omega_m: float, drive: float, i_start: float, arm: Armature,
                      load: float, coulomb: float, excess: float, ws: float,
                      breakaway: float) -> tuple[float, float]:
    """One sub-step of a shaft with dry friction; return the new angle and speed.

    A moving shaft slides against the Coulomb (and Stribeck) level at its mid-step speed;
    where the speed would cross zero, the crossing is located in the sub-step (speed
    linear in time) and, for the rest of it, the shaft sticks unless the other torques
    exceed the breakaway level. A sticking shaft breaks away where the torque, linear
    between the sub-step's ends, reaches that level.
    """
    if omega != 0.0:
        level = coulomb
        if excess:
            level += excess * math.exp(-(omega_m / ws) ** 2)
        slid = _slide(h, J, damp, theta, omega, drive, arm,
                      drive * arm.i_mean - load - math.copysign(level, omega))
        omega_new = slid[1]
        if omega_new * omega >= 0.0:
            return slid
        part = omega / (omega - omega_new)  # share of the sub-step before zero speed
        theta += 0.5 * part * h * omega
        rest = (1.0 - part) * h
        torque = drive * arm.i - load  # at rest, at the sub-step's end
        if abs(torque) <= breakaway:
            return theta, 0.0
        omega_new = rest * (torque - math.copysign(breakaway, torque)) / J
        return theta + 0.5 * rest * omega_new, omega_new
    torque_end = drive * arm.i - load
    if abs(torque_end) <= breakaway:
        return theta, 0.0  # stuck: static friction holds the shaft
    sign = math.copysign(1.0, torque_end)
    over_start = sign * (drive * i_start - load) - breakaway
    over_end = abs(torque_end) - breakaway
    if over_start >= 0.0:
        force = sign * (drive * arm.i_mean - load) - breakaway
        omega_new = sign * h * force / J
        return theta + 0.5 * h * omega_new, omega_new
    rest = h * over_end / (over_end - over_start)  # moving after the breakaway
    return theta + sign * over_end * rest * rest / (6.0 * J), sign * over_end * rest / (2.0 * J)
