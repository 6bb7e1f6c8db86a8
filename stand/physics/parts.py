"""The parts of a stand: motor, drive, sensors, reducer. Parameters only, SI units."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from stand.errors import InputError

DriveMode = Literal["voltage", "current", "speed"]
DRIVE_MODES: tuple[str, ...] = ("voltage", "current", "speed")


def _positive(where: str, **values: float) -> None:
    for name, value in values.items():
        if not (math.isfinite(value) and value > 0):
            raise InputError(f"{where}.{name}: must be a finite number > 0, got {value}")


def _non_negative(where: str, **values: float) -> None:
    for name, value in values.items():
        if not (math.isfinite(value) and value >= 0):
            raise InputError(f"{where}.{name}: must be a finite number >= 0, got {value}")


@dataclass(frozen=True)
class MotorParams:
    """A brushed DC motor, seed 000 eq. 2 plus the armature circuit of seed 001 eq. 1.

    Parameters
    ----------
    R : float
        Armature resistance, Ω.
    L : float
        Armature inductance, H.
    Kt : float
        Torque constant, N·m/A (equal to the back-EMF constant, V·s/rad).
    J : float
        Rotor inertia, kg·m².
    D : float
        Viscous friction, N·m·s/rad.
    C : float
        Torsion spring constant of seed 000 eq. 2, N·m/rad (usually 0).
    """

    R: float
    L: float
    Kt: float
    J: float
    D: float = 0.0
    C: float = 0.0

    def __post_init__(self) -> None:
        _positive("motor", R=self.R, L=self.L, Kt=self.Kt, J=self.J)
        _non_negative("motor", D=self.D, C=self.C)


@dataclass(frozen=True)
class DriveParams:
    """The power stage and its control loops.

    Parameters
    ----------
    mode : {'voltage', 'current', 'speed'}
        What the command sets: terminal voltage (V), armature current (A), or speed
        (rad/s) through a PI speed loop.
    supply_V : float
        Bus voltage; the terminal voltage saturates at ± this, V.
    current_limit_A : float
        Current limit of the current and speed loops, A.
    current_tau_s : float
        Time constant of the closed current loop, s.
    speed_kp : float
        Proportional gain of the speed loop, A per rad/s.
    speed_ki : float
        Integral gain of the speed loop, A per rad.
    """

    mode: DriveMode = "current"
    supply_V: float = 24.0
    current_limit_A: float = 5.0
    current_tau_s: float = 2e-4
    speed_kp: float = 0.02
    speed_ki: float = 0.5

    def __post_init__(self) -> None:
        if self.mode not in DRIVE_MODES:
            raise InputError(
                f"drive.mode must be one of {', '.join(DRIVE_MODES)}, not {self.mode!r}"
            )
        _positive("drive", supply_V=self.supply_V, current_limit_A=self.current_limit_A,
                  current_tau_s=self.current_tau_s)
        _non_negative("drive", speed_kp=self.speed_kp, speed_ki=self.speed_ki)


@dataclass(frozen=True)
class SensorParams:
    """What the stand measures and how badly.

    Parameters
    ----------
    encoder_lines : int
        Lines per revolution of the incremental encoder, read with 4x quadrature
        (0 for an ideal, unquantized angle).
    current_noise_A : float
        Standard deviation of white current-sensor noise, A.
    velocity_noise_rad_s : float or None
        Tachometer noise, rad/s; ``None`` reports velocity as the encoder difference
        quotient, as a drive's velocity actual value.
    voltage_noise_V : float
        Standard deviation of white voltage-measurement noise, V.
    """

    encoder_lines: int = 2500
    current_noise_A: float = 0.0
    velocity_noise_rad_s: float | None = None
    voltage_noise_V: float = 0.0

    def __post_init__(self) -> None:
        if self.encoder_lines < 0:
            raise InputError(f"sensors.encoder_lines: must be >= 0, got {self.encoder_lines}")
        _non_negative("sensors", current_noise_A=self.current_noise_A,
                      voltage_noise_V=self.voltage_noise_V)
        if self.velocity_noise_rad_s is not None:
            _non_negative("sensors", velocity_noise_rad_s=self.velocity_noise_rad_s)

    @property
    def counts_per_rev(self) -> int:
        """Encoder counts per revolution (4 x lines), 0 when unquantized."""
        return 4 * self.encoder_lines


@dataclass(frozen=True)
class ReducerParams:
    """A gear reducer between an input and an output shaft (seed 000 §3.6).

    Parameters
    ----------
    ratio : float
        Reduction ratio n = ω_in / ω_out.
    efficiency : float
        Torque transmission efficiency η in (0, 1].
    backlash_rad : float
        Half width of the dead zone at the output shaft, rad.
    stiffness : float
        Torsional stiffness at the output shaft, N·m/rad; 0 picks one with a 150 Hz mode.
    """

    ratio: float
    efficiency: float
    backlash_rad: float = 0.0
    stiffness: float = 0.0

    def __post_init__(self) -> None:
        _positive("reducer", ratio=self.ratio)
        if not 0 < self.efficiency <= 1:
            raise InputError(
                f"reducer.efficiency: must be in (0, 1], got {self.efficiency}"
            )
        _non_negative("reducer", backlash_rad=self.backlash_rad, stiffness=self.stiffness)
