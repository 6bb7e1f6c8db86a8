"""The armature circuit and the drive that feeds it.

``L·di/dt = v − R·i − Kt·ω`` is stepped exactly for a voltage held over a sub-step, so
the step is stable for any sub-step length. In current and speed mode the drive brings
the current to its closed-loop target along a first-order current loop of time constant
``current_tau_s``, as long as the supply voltage suffices; when the voltage the loop asks
for exceeds the supply, the terminal voltage saturates at ± the supply and the current
follows the armature's own exponential (time constant ``L/R``).

Within a sub-step the current is therefore one exponential ``a + b·exp(−s/τ)``. Besides
its end value :meth:`Armature.step` keeps its exact mean over the sub-step and its
ramp-weighted mean ``(2/h²)·∫(h − s)·i(s)·ds``, which the mechanics need to integrate
the torque (velocity) and its integral (angle) without holding the current at one
value for the whole sub-step.
"""

from __future__ import annotations

import math

from stand.physics.parts import DriveParams, MotorParams


def _shape(h: float, tau: float) -> tuple[float, float, float]:
    """Decay over ``h`` and the mean and ramp-weighted mean of ``exp(−s/τ)`` over it."""
    x = h / tau
    decay = math.exp(-x)
    if x < 1e-6:
        return decay, 1.0 - x / 2, 1.0 - x / 3
    mean = -math.expm1(-x) / x
    return decay, mean, 2.0 * (1.0 - mean) / x


class Armature:
    """Electrical state of one motor and its drive.

    Parameters
    ----------
    motor : MotorParams
        The motor.
    drive : DriveParams
        The drive; ``mode`` may be changed later with :meth:`command`.

    Attributes
    ----------
    i : float
        Armature current at the end of the last sub-step, A.
    i_mean, i_ramp : float
        Mean and ramp-weighted mean of the current over the last sub-step, A.
    v : float
        Terminal voltage held over the last sub-step, V.
    """

    def __init__(self, motor: MotorParams, drive: DriveParams) -> None:
        self.motor = motor
        self.drive = drive
        self.mode: str = drive.mode
        self.target = 0.0
        self.i = self.i_mean = self.i_ramp = 0.0
        self.v = 0.0
        self.speed_integral_A = 0.0
        self._h = -1.0
        self._el = (0.0, 0.0, 0.0)
        self._cur = (0.0, 0.0, 0.0)

    def command(self, mode: str, target: float) -> None:
        """Set the drive mode and its target (V, A or rad/s)."""
        if mode != self.mode:
            self.speed_integral_A = self.i if mode == "speed" else 0.0
        self.mode = mode
        self.target = float(target)

    def prepare(self, h: float) -> None:
        """Precompute the exponentials for sub-steps of ``h`` seconds."""
        if h != self._h:
            self._h = h
            self._el = _shape(h, self.motor.L / self.motor.R)
            self._cur = _shape(h, self.drive.current_tau_s)

    def step(self, h: float, omega: float) -> float:
        """Advance the current by one sub-step of ``h`` s; return its end value.

        ``omega`` is the shaft speed at the middle of the sub-step, rad/s (the speed
        loop's error and the back-EMF are taken there).
        """
        m, d = self.motor, self.drive
        i = self.i
        if self.mode == "voltage":
            v = self.target
        else:
            limit = d.current_limit_A
            if self.mode == "speed":
                error = self.target - omega
                start = self.speed_integral_A
                integral = min(max(start + d.speed_ki * error * h, -limit), limit)
                self.speed_integral_A = integral
                i_cmd = d.speed_kp * error + 0.5 * (start + integral)
            else:
                i_cmd = self.target
            i_cmd = min(max(i_cmd, -limit), limit)
            decay, mean, ramp = self._cur
            i_next = i_cmd + (i - i_cmd) * decay
            e_el = self._el[0]
            v = m.R * (i_next - i * e_el) / (1.0 - e_el) + m.Kt * omega
            if abs(v) <= d.supply_V:  # the loop holds: its own exponential
                self.v = v
                self.i = i_next
                self.i_mean = i_cmd + (i - i_cmd) * mean
                self.i_ramp = i_cmd + (i - i_cmd) * ramp
                return i_next
        supply = d.supply_V
        v = min(max(v, -supply), supply)
        i_inf = (v - m.Kt * omega) / m.R
        decay, mean, ramp = self._el
        self.i = i_inf + (i - i_inf) * decay
        self.i_mean = i_inf + (i - i_inf) * mean
        self.i_ramp = i_inf + (i - i_inf) * ramp
        self.v = v
        return self.i
