"""The armature circuit and the drive that feeds it.

``L·di/dt = v − R·i − Kt·ω`` is stepped exactly for a voltage held over a sub-step, so
the step is stable for any sub-step length. In current and speed mode the drive picks
the voltage that brings the current to its closed-loop target (a first-order current
loop of time constant ``current_tau_s``), saturated at the supply voltage.
"""

from __future__ import annotations

import math

from stand.physics.parts import DriveParams, MotorParams


class Armature:
    """Electrical state of one motor and its drive.

    Parameters
    ----------
    motor : MotorParams
        The motor.
    drive : DriveParams
        The drive; ``mode`` may be changed later with :meth:`command`.
    """

    def __init__(self, motor: MotorParams, drive: DriveParams) -> None:
        self.motor = motor
        self.drive = drive
        self.mode: str = drive.mode
        self.target = 0.0
        self.i = 0.0
        self.v = 0.0
        self.speed_integral_A = 0.0
        self._h = -1.0
        self._e_el = 0.0
        self._e_cur = 0.0

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
            self._e_el = math.exp(-h * self.motor.R / self.motor.L)
            self._e_cur = math.exp(-h / self.drive.current_tau_s)

    def step(self, h: float, omega: float) -> float:
        """Advance the current by one sub-step of ``h`` s at speed ``omega``; return it."""
        m, d = self.motor, self.drive
        i = self.i
        if self.mode == "voltage":
            v = self.target
        else:
            limit = d.current_limit_A
            if self.mode == "speed":
                error = self.target - omega
                integral = self.speed_integral_A + d.speed_ki * error * h
                integral = min(max(integral, -limit), limit)
                self.speed_integral_A = integral
                i_cmd = d.speed_kp * error + integral
            else:
                i_cmd = self.target
            i_cmd = min(max(i_cmd, -limit), limit)
            i_next = i_cmd + (i - i_cmd) * self._e_cur
            i_inf = (i_next - i * self._e_el) / (1.0 - self._e_el)
            v = m.R * i_inf + m.Kt * omega
        supply = d.supply_V
        v = min(max(v, -supply), supply)
        i_inf = (v - m.Kt * omega) / m.R
        self.i = i_inf + (i - i_inf) * self._e_el
        self.v = v
        return self.i
