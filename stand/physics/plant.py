"""Steppable plants: one motor on a shaft, with the effects of CONTRACT §3.

A plant advances by one sample period at a time (:meth:`MotorPlant.advance`) and is read
at the sample instants (:meth:`MotorPlant.measure`). The same object sits behind the
direct simulation (:mod:`stand.physics.simulate`) and behind a simulated CiA 402 drive on
the bus, so both see identical physics.

Mechanics, per sub-step ``h`` (semi-implicit Euler; friction with Karnopp sticking)::

    J·ω' = Kt·i·(1 + ε·sin(Nr·θ + φr)) − D·ω − C·θ − Tcog·sin(Nc·θ + φc)
           − T_friction(ω) − T_backlash
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
        self.current_history: deque[float] = deque(maxlen=delay + 1)
        self.last_position: float | None = None

    def read(self, theta: float, omega: float, current: float, voltage: float,
             dt_s: float) -> Measurement:
        p = self.params
        position = theta
        if self.step_rad:
            position = math.floor(theta / self.step_rad) * self.step_rad
        self.current_history.append(current)
        measured_i = self.current_history[0] + self.offset_A  # k samples ago
        if p.current_noise_A:
            measured_i += p.current_noise_A * self.rng.standard_normal()
        if p.velocity_noise_rad_s is not None:
            velocity = omega + p.velocity_noise_rad_s * self.rng.standard_normal()
        elif self.last_position is None:
            velocity = 0.0
        else:
            velocity = (position - self.last_position) / dt_s
        self.last_position = position
        if p.voltage_noise_V:
            voltage += p.voltage_noise_V * self.rng.standard_normal()
        return Measurement(position, measured_i, velocity, voltage)


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
        self.time_s = 0.0
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
                                 self.armature.v, dt_s)

    def advance(self, dt_s: float) -> None:
        """Advance the physics by ``dt_s`` seconds."""
        n = substeps_for(dt_s)
        h = dt_s / n
        arm = self.armature
        arm.prepare(h)
        Kt, D, C, J = self.motor.Kt, self.motor.D, self.motor.C, self.J
        coulomb, excess, ws = self.coulomb, self.static_excess, self.stribeck_ws
        breakaway = coulomb + excess
        cogging, ripple, backlash = self.cogging, self.ripple, self.backlash
        theta, omega = self.theta, self.omega
        theta_l, omega_l = self.theta_load, self.omega_load
        extra = self.extra_torque
        for sub in range(n):
            i = arm.step(h, omega)
            gain = 1.0 + ripple[0] * math.sin(ripple[1] * theta + ripple[2]) if ripple else 1.0
            torque = Kt * i * gain - D * omega - C * theta
            if extra is not None:
                torque -= extra(theta, omega, i, self.time_s + sub * h)
            if cogging:
                torque -= cogging[0] * math.sin(cogging[1] * theta + cogging[2])
            if backlash:
                gap, J_load, k, c = backlash
                twist = theta - theta_l
                contact = 0.0
                if twist > gap:
                    contact = max(0.0, k * (twist - gap) + c * (omega - omega_l))
                elif twist < -gap:
                    contact = min(0.0, k * (twist + gap) + c * (omega - omega_l))
                torque -= contact
                omega_l += h * contact / J_load
                theta_l += h * omega_l
            if breakaway > 0.0:
                if omega == 0.0:
                    if abs(torque) <= breakaway:
                        continue  # stuck: static friction holds the shaft
                    torque -= math.copysign(breakaway, torque)
                    new_omega = omega + h * torque / J
                else:
                    level = coulomb
                    if excess:
                        level += excess * math.exp(-(omega / ws) ** 2)
                    new_omega = omega + h * (torque - math.copysign(level, omega)) / J
                    if new_omega * omega < 0.0:
                        new_omega = 0.0  # crossed zero: friction may hold it there
                omega = new_omega
            else:
                omega += h * torque / J
            theta += h * omega
        self.theta, self.omega = theta, omega
        self.theta_load, self.omega_load = theta_l, omega_l
        self.time_s += dt_s
