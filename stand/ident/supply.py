"""What a user knows of a drive's electrical side: its supply, its current limit and the
motor's armature.

A drive in speed (or current) mode sets the voltage that brings the current to its
command, but never more than its supply: when the needed voltage ``R·i + L·i' + Ke·ω``
(``Ke = Kt`` in SI units) exceeds the supply, the current follows the armature's own
dynamics ``L·i' = ±V − R·i − Kt·ω`` instead. A fast speed loop asks for that on every
large change of its target. The output-error refinement of a speed-loop run
(:mod:`stand.ident.closed_loop`) models it when it is told the supply; ``R``, ``L`` and
``Kt`` are start values there (a profile's, or a datasheet's), refitted from the run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from stand.errors import InputError


@dataclass(frozen=True)
class DriveSupply:
    """A drive's supply and current limit and its motor's armature.

    Attributes
    ----------
    supply_V : float
        Supply (bus) voltage the drive can apply at most, V.
    R : float
        Armature resistance, Ω (start value).
    L : float
        Armature inductance, H (start value).
    Kt : float
        Torque constant, N·m/A, equal to the back-EMF constant in V·s/rad (start value).
    current_limit_A : float
        The drive's current limit, A (start value; infinite: none known).
    speed_kp, speed_ki : float or None
        The drive's speed-loop gains, A per rad/s and A per rad (start values of a
        second start where the fit from the law's gains misses the run; None: not
        known).
    """

    supply_V: float
    R: float
    L: float
    Kt: float
    current_limit_A: float = math.inf
    speed_kp: float | None = None
    speed_ki: float | None = None

    def __post_init__(self) -> None:
        optional = [name for name in ("speed_kp", "speed_ki") if getattr(self, name) is not None]
        for name in ("supply_V", "R", "L", "Kt", "current_limit_A", *optional):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and value > 0 and not math.isnan(value)):
                raise InputError(f"drive supply: {name} must be a number > 0, got {value!r}")
        for name in ("supply_V", "R", "L", "Kt", *optional):
            if math.isinf(getattr(self, name)):
                raise InputError(f"drive supply: {name} must be finite, got inf")


def motor_supply(name_or_path: str | None) -> DriveSupply | None:
    """The supply, current limit and speed-loop gains of motor profile
    ``name_or_path``'s drive, and its motor's ``R``, ``L``, ``Kt``
    (:func:`stand.profiles.load_motor`); None for None."""
    if name_or_path is None:
        return None
    from stand.profiles import load_motor

    profile = load_motor(name_or_path)
    drive = profile.drive
    return DriveSupply(drive.supply_V, profile.motor.R, profile.motor.L, profile.motor.Kt,
                       drive.current_limit_A, drive.speed_kp or None, drive.speed_ki or None)
