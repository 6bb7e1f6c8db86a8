"""CiA 301 names: communication objects, COB-ID bases, NMT commands and states.

Object indexes as CiA 301 §7.5 names them; the CiA 402 drive objects are in
:mod:`bus.cia402`. COB-IDs are those of the predefined connection set (§7.3.5), where a
node's own object is the base plus its node id.
"""

from __future__ import annotations

# Communication profile area objects (CiA 301 §7.5.2).
DEVICE_TYPE = 0x1000
ERROR_REGISTER = 0x1001
COB_ID_SYNC = 0x1005
COMMUNICATION_CYCLE_PERIOD = 0x1006
SYNCHRONOUS_WINDOW_LENGTH = 0x1007
COB_ID_EMCY = 0x1014
PRODUCER_HEARTBEAT_TIME = 0x1017
IDENTITY = 0x1018
SYNCHRONOUS_COUNTER_OVERFLOW = 0x1019
RPDO_COMMUNICATION = 0x1400
RPDO_MAPPING = 0x1600
TPDO_COMMUNICATION = 0x1800
TPDO_MAPPING = 0x1A00
#: Sub-indexes of the identity object 0x1018.
VENDOR_ID, PRODUCT_CODE, REVISION_NUMBER, SERIAL_NUMBER = 1, 2, 3, 4
#: The device profile number in the low 16 bits of the device type 0x1000.
DEVICE_PROFILE_MASK = 0xFFFF
#: Manufacturer-specific profile area (0x2000-0x5FFF).
MANUFACTURER_FIRST, MANUFACTURER_END = 0x2000, 0x6000

# COB-IDs of the predefined connection set (§7.3.5): a node's is the base + its node id.
NMT_COB_ID = 0x000
SYNC_COB_ID = 0x080
EMCY_BASE = 0x080
TPDO_BASES = (0x180, 0x280, 0x380, 0x480)
RPDO_BASES = (0x200, 0x300, 0x400, 0x500)
SDO_RESPONSE_BASE = 0x580
SDO_REQUEST_BASE = 0x600
HEARTBEAT_BASE = 0x700

# NMT commands (§7.2.8.3.1) and states as a heartbeat carries them (§7.2.8.3.2).
NMT_START = 0x01
NMT_STOP = 0x02
NMT_ENTER_PRE_OPERATIONAL = 0x80
NMT_RESET_NODE = 0x81
NMT_RESET_COMMUNICATION = 0x82
NMT_COMMAND_NAMES = {NMT_START: "start", NMT_STOP: "stop",
                     NMT_ENTER_PRE_OPERATIONAL: "enter PRE-OPERATIONAL",
                     NMT_RESET_NODE: "reset node", NMT_RESET_COMMUNICATION: "reset communication"}
NMT_BOOT_UP, NMT_STOPPED, NMT_OPERATIONAL, NMT_PRE_OPERATIONAL = 0, 4, 5, 127
NMT_STATE_NAMES = {NMT_BOOT_UP: "BOOT-UP", NMT_STOPPED: "STOPPED", NMT_OPERATIONAL: "OPERATIONAL",
                   NMT_PRE_OPERATIONAL: "PRE-OPERATIONAL"}
#: EMCY error code of an error reset / no error (§7.2.7.1).
EMCY_ERROR_RESET = 0x0000
