"""Which device answers at a node id: device type 0x1000 and identity 0x1018 (CiA 301 §7.5.2).

Before it writes anything to a node, the master reads both and compares them with what the
node's EDS (or DCF) says: a node that is no CiA 402 drive, or a drive other than the one
the EDS describes, is refused with a message naming both. The identity also tells a
simulated drive (the shipped EDS's vendor id and product code) from a real one: only a
simulated drive is given the objects that only the simulation has (0x2000-0x2100).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import canopen

from bus.cia301 import (
    DEVICE_PROFILE_MASK,
    DEVICE_TYPE,
    IDENTITY,
    PRODUCT_CODE,
    REVISION_NUMBER,
    VENDOR_ID,
)
from bus.eds import DEFAULT_EDS, load_od

#: CiA device profile numbers (low 16 bits of 0x1000) a stand may meet.
CIA402_PROFILE = 402
PROFILE_NAMES = {0: "no standard profile", 401: "CiA 401 generic I/O", 402: "CiA 402 drive",
                 404: "CiA 404 measuring device", 406: "CiA 406 encoder"}


@dataclass(frozen=True)
class DeviceIdentity:
    """What a node says it is.

    Attributes
    ----------
    device_type : int
        Object 0x1000 (profile number in the low 16 bits, its additional information above).
    vendor_id, product_code : int
        Object 0x1018 sub 1 and 2.
    revision : int or None
        Object 0x1018 sub 3, where present.
    """

    device_type: int
    vendor_id: int
    product_code: int
    revision: int | None = None

    @property
    def profile(self) -> int:
        return self.device_type & DEVICE_PROFILE_MASK

    @property
    def profile_name(self) -> str:
        return PROFILE_NAMES.get(self.profile, f"CiA {self.profile}")

    def describe(self) -> str:
        return (f"device type 0x{self.device_type:08X} ({self.profile_name}), vendor id "
                f"0x{self.vendor_id:08X}, product code 0x{self.product_code:08X}")


def _default(od: canopen.ObjectDictionary, index: int, subindex: int | None = None) -> int | None:
    """The value a DCF gives (ParameterValue), else the EDS's default, else None."""
    try:
        obj: Any = od[index]
        if subindex is not None:
            obj = obj[subindex]
    except (KeyError, TypeError):
        return None
    value = getattr(obj, "value", None)
    if value is None:
        value = getattr(obj, "default", None)
    return int(value) if value is not None else None


def eds_identity(od: canopen.ObjectDictionary) -> DeviceIdentity | None:
    """The identity an EDS or DCF describes (its 0x1000 and 0x1018 values), or None when it
    gives no device type or no vendor id and product code."""
    device_type = _default(od, DEVICE_TYPE)
    vendor = _default(od, IDENTITY, VENDOR_ID)
    product = _default(od, IDENTITY, PRODUCT_CODE)
    if device_type is None or vendor is None or product is None:
        return None
    return DeviceIdentity(device_type, vendor, product, _default(od, IDENTITY, REVISION_NUMBER))


@lru_cache(maxsize=1)
def simulated_identity() -> DeviceIdentity:
    """The identity of motorstand's simulated drive (the shipped EDS's)."""
    identity = eds_identity(load_od(DEFAULT_EDS, 1))
    assert identity is not None, f"{DEFAULT_EDS} gives 0x1000 and 0x1018"
    return identity


def is_simulated(identity: DeviceIdentity) -> bool:
    """True when ``identity`` is motorstand's simulated drive (vendor id and product code)."""
    sim = simulated_identity()
    return (identity.vendor_id, identity.product_code) == (sim.vendor_id, sim.product_code)
