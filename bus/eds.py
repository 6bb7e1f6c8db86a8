"""Electronic data sheets (EDS) and the scaling of a drive's raw values to SI units.

The shipped EDS ``profiles/eds/motorstand_cia402.eds`` describes the simulated CiA 402
drive; a real drive's EDS may be given instead. Units of the raw process data:

- position actual 0x6064: encoder counts, ``counts_per_rev`` per revolution;
- velocity actual 0x606C and target velocity 0x60FF: ``velocity_unit_rad_s`` each;
- current actual 0x6078 and target torque 0x6071: per mille of rated current 0x6075 (in
  mA; the drive's rated torque 0x6076 is taken as the torque at rated current);
- voltage command 0x2000 and voltage actual 0x2001: ``voltage_unit_V`` each.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import canopen

from stand.errors import ProfileError
from stand.profiles import PROFILES_DIR

#: The EDS of the simulated drive.
DEFAULT_EDS = PROFILES_DIR / "eds" / "motorstand_cia402.eds"
#: Counts per revolution reported by a drive without an encoder (tacho-only motors).
FINE_COUNTS_PER_REV = 1 << 20
#: Unit of the velocity objects, rad/s.
VELOCITY_UNIT_RAD_S = 1e-3
#: Unit of the voltage objects, V.
VOLTAGE_UNIT_V = 1e-3
PER_MILLE = 1000.0
#: Unit of the motor rated current 0x6075: mA.
MA_PER_A = 1000.0


def load_od(path: str | Path | None, node_id: int) -> canopen.ObjectDictionary:
    """The object dictionary of ``path`` (default: the simulated drive's EDS)."""
    eds = Path(path) if path else DEFAULT_EDS
    try:
        return canopen.import_od(str(eds), node_id)
    except (OSError, ValueError, KeyError) as exc:
        raise ProfileError(f"{eds}: cannot read the EDS: {exc}") from exc


@dataclass(frozen=True)
class Scaling:
    """Raw process data ↔ SI units for one drive.

    Parameters
    ----------
    counts_per_rev : int
        Position counts per revolution of the motor shaft.
    rated_current_A : float
        Motor rated current 0x6075, A.
    velocity_unit_rad_s : float
        Unit of 0x606C / 0x60FF, rad/s.
    voltage_unit_V : float
        Unit of 0x2000 / 0x2001, V.
    current_mean_unit_A : float or None
        Unit of the drive's current averaged over each period (column ``current_mean_A``),
        A; None: that of 0x6078, per mille of the rated current (the simulated drive's 0x2002).
    """

    counts_per_rev: int = FINE_COUNTS_PER_REV
    rated_current_A: float = 1.0
    velocity_unit_rad_s: float = VELOCITY_UNIT_RAD_S
    voltage_unit_V: float = VOLTAGE_UNIT_V
    current_mean_unit_A: float | None = None

    @property
    def rad_per_count(self) -> float:
        return 2 * math.pi / self.counts_per_rev

    @property
    def amp_per_unit(self) -> float:
        return self.rated_current_A / PER_MILLE

    @property
    def mean_amp_per_unit(self) -> float:
        """A per count of the drive's period-mean current."""
        return self.amp_per_unit if self.current_mean_unit_A is None else self.current_mean_unit_A

    @property
    def rated_current_mA(self) -> int:
        """The rated current as 0x6075 holds it, mA."""
        return int(round(self.rated_current_A * MA_PER_A))

    def target_raw(self, mode: str, value: float) -> int:
        """Raw target of ``mode`` (speed rad/s, current A, voltage V)."""
        unit = {"speed": self.velocity_unit_rad_s, "current": self.amp_per_unit,
                "voltage": self.voltage_unit_V}[mode]
        return int(round(value / unit))
