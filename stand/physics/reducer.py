"""The two-motor reducer stand of seed 000 §3.6.

Input motor → reducer (ratio n, efficiency η, optional backlash) → output shaft, loaded
by the output motor. The reducer output and the output shaft meet in a stiff contact
(dead zone ± ``backlash_rad``). With ``Tc`` the contact torque on the output shaft, the
input shaft carries ``Tc/(n·η)`` while the gear drives the load and ``Tc·η/n`` when the
load drives the gear, so that at steady state ``η = Kt_out·Δi_out / (n·Kt_in·Δi_in)``
(seed 000 eq. 18).
"""

from __future__ import annotations

import math

import numpy as np

from stand.physics.armature import Armature
from stand.physics.effects import Effects
from stand.physics.parts import DriveParams, MotorParams, ReducerParams, SensorParams
from stand.physics.plant import (
    Measurement,
    Sensors,
    contact_constants,
    friction_levels,
    substeps_for,
)

INPUT, OUTPUT = 0, 1


class ReducerPlant:
    """Two motors coupled by a reducer; port 0 is the input motor, port 1 the output.

    Parameters
    ----------
    motor_in, motor_out : MotorParams
        The input and the output motor.
    reducer : ReducerParams
        Ratio, efficiency and backlash.
    drive_in, drive_out : DriveParams
        Their drives (typically speed mode in, current mode out).
    sensors : SensorParams
        Sensors of both motors.
    effects_in, effects_out : Effects
        Friction on each shaft (``coulomb_friction``, ``stribeck_friction``); other
        effects are not modelled on the reducer stand.
    seed : int or None
        Seed of the sensor noise.
    """

    ports = 2

    def __init__(self, motor_in: MotorParams, motor_out: MotorParams, reducer: ReducerParams,
                 drive_in: DriveParams | None = None, drive_out: DriveParams | None = None,
                 sensors: SensorParams | None = None, effects_in: Effects | None = None,
                 effects_out: Effects | None = None, seed: int | None = None) -> None:
        self.motors = (motor_in, motor_out)
        self.reducer = reducer
        rng = np.random.default_rng(seed)
        sensors = sensors or SensorParams()
        effects = (effects_in or Effects(), effects_out or Effects())
        self.armatures = (
            Armature(motor_in, drive_in or DriveParams(mode="speed")),
            Armature(motor_out, drive_out or DriveParams(mode="current")),
        )
        self.sensors = tuple(Sensors(sensors, e, rng) for e in effects)
        self.friction = tuple(friction_levels(e)[0] for e in effects)
        n = reducer.ratio
        self.k, self.c = contact_constants(motor_in.J * n * n, motor_out.J, reducer.stiffness)
        self.theta = [0.0, 0.0]
        self.omega = [0.0, 0.0]
        #: Each armature's current averaged over the last :meth:`advance`, A.
        self.period_current = [0.0, 0.0]
        self.time_s = 0.0

    def command(self, mode: str, target: float, port: int = 0) -> None:
        """Set the mode and target of the drive on ``port`` (0 input, 1 output)."""
        self.armatures[port].command(mode, target)

    def measure(self, dt_s: float, port: int = 0) -> Measurement:
        """Read the sensors of the motor on ``port``."""
        arm = self.armatures[port]
        return self.sensors[port].read(self.theta[port], self.omega[port], arm.i, arm.v, dt_s,
                                       self.period_current[port])

    def advance(self, dt_s: float) -> None:
        """Advance the physics by ``dt_s`` seconds."""
        steps = substeps_for(dt_s)
        h = dt_s / steps
        arm_in, arm_out = self.armatures
        arm_in.prepare(h)
        arm_out.prepare(h)
        m_in, m_out = self.motors
        n, eta, gap = self.reducer.ratio, self.reducer.efficiency, self.reducer.backlash_rad
        k, c = self.k, self.c
        fr_in, fr_out = self.friction
        th_in, th_out = self.theta
        w_in, w_out = self.omega
        half = 0.5 * h
        charge_in = charge_out = 0.0
        for _ in range(steps):  # position Verlet: forces at mid-step (see plant.py)
            tm_in, tm_out = th_in + half * w_in, th_out + half * w_out
            arm_in.step(h, w_in)
            arm_out.step(h, w_out)
            charge_in += arm_in.i_mean
            charge_out += arm_out.i_mean
            twist = tm_in / n - tm_out
            rate = w_in / n - w_out
            contact = 0.0
            if twist > gap:
                contact = max(0.0, k * (twist - gap) + c * rate)
            elif twist < -gap:
                contact = min(0.0, k * (twist + gap) + c * rate)
            forward = contact * w_out >= 0.0
            load_in = contact / (n * eta) if forward else contact * eta / n
            t_in = m_in.Kt * arm_in.i_mean - m_in.D * w_in - load_in
            t_out = m_out.Kt * arm_out.i_mean - m_out.D * w_out + contact
            if fr_in and w_in:
                t_in -= math.copysign(fr_in, w_in)
            if fr_out and w_out:
                t_out -= math.copysign(fr_out, w_out)
            new_in = w_in + h * t_in / m_in.J
            new_out = w_out + h * t_out / m_out.J
            shape_in = m_in.Kt * (arm_in.i_ramp - arm_in.i_mean) / m_in.J
            shape_out = m_out.Kt * (arm_out.i_ramp - arm_out.i_mean) / m_out.J
            th_in = tm_in + half * (new_in + h * shape_in)
            th_out = tm_out + half * (new_out + h * shape_out)
            w_in, w_out = new_in, new_out
        self.theta = [th_in, th_out]
        self.omega = [w_in, w_out]
        self.period_current = [charge_in / steps, charge_out / steps]
        self.time_s += dt_s
