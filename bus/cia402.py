"""CiA 402 device profile: controlword, statusword, the drive state machine, modes.

State machine (CiA 402 §6.3; "power" states in capitals)::

    SWITCH ON DISABLED --shutdown--> READY TO SWITCH ON --switch on--> SWITCHED ON
        --enable operation--> OPERATION ENABLED --quick stop--> QUICK STOP ACTIVE
    any --fault--> FAULT --fault reset--> SWITCH ON DISABLED
"""

from __future__ import annotations

from enum import Enum

# Controlword commands (bits 0-3 and 7).
CW_SHUTDOWN = 0x0006
CW_SWITCH_ON = 0x0007
CW_ENABLE_OPERATION = 0x000F
CW_DISABLE_VOLTAGE = 0x0000
CW_QUICK_STOP = 0x0002
CW_FAULT_RESET = 0x0080

# Modes of operation 0x6060 (negative values are manufacturer specific).
MODE_NONE = 0
MODE_CSV = 9
MODE_CST = 10
MODE_VOLTAGE = -1
#: Target objects of cyclic synchronous velocity and torque mode.
TARGET_VELOCITY = 0x60FF
TARGET_TORQUE = 0x6071
#: Stand drive mode to CiA 402 mode of operation and its target object.
MODES = {"speed": MODE_CSV, "current": MODE_CST, "voltage": MODE_VOLTAGE}
TARGET_OBJECT = {"speed": (TARGET_VELOCITY, "i", 32), "current": (TARGET_TORQUE, "h", 16),
                 "voltage": (0x2000, "h", 16)}

# Object indices used by the stand.
CONTROLWORD = 0x6040
STATUSWORD = 0x6041
MODES_OF_OPERATION = 0x6060
MODES_DISPLAY = 0x6061
POSITION_ACTUAL = 0x6064
VELOCITY_ACTUAL = 0x606C
TORQUE_ACTUAL = 0x6077
CURRENT_ACTUAL = 0x6078
VOLTAGE_ACTUAL = 0x2001
#: Current actual averaged over the communication cycle period that ends at the SYNC
#: (manufacturer-specific, the simulated drive's; per mille of 0x6075 like 0x6078).
CURRENT_MEAN = 0x2002
ERROR_CODE = 0x603F
QUICK_STOP_OPTION = 0x605A
MAX_CURRENT = 0x6073
RATED_CURRENT = 0x6075
#: Position encoder resolution: encoder increments (sub 1) per motor revolutions (sub 2).
POSITION_ENCODER_RESOLUTION = 0x608F
ENCODER_INCREMENTS, MOTOR_REVOLUTIONS = 1, 2
ADDED_INERTIA = 0x2100

# EMCY error codes (CiA 301 / 402).
EMCY_OVER_CURRENT = 0x2310
EMCY_FOLLOWING_ERROR = 0x8611


class State(Enum):
    NOT_READY_TO_SWITCH_ON = 0x0000
    SWITCH_ON_DISABLED = 0x0040
    READY_TO_SWITCH_ON = 0x0021
    SWITCHED_ON = 0x0023
    OPERATION_ENABLED = 0x0027
    QUICK_STOP_ACTIVE = 0x0007
    FAULT_REACTION_ACTIVE = 0x000F
    FAULT = 0x0008


#: (mask, value) of the statusword for each state.
_STATUS_MASKS = (
    (0x004F, 0x0000, State.NOT_READY_TO_SWITCH_ON),
    (0x004F, 0x0040, State.SWITCH_ON_DISABLED),
    (0x006F, 0x0021, State.READY_TO_SWITCH_ON),
    (0x006F, 0x0023, State.SWITCHED_ON),
    (0x006F, 0x0027, State.OPERATION_ENABLED),
    (0x006F, 0x0007, State.QUICK_STOP_ACTIVE),
    (0x004F, 0x000F, State.FAULT_REACTION_ACTIVE),
    (0x004F, 0x0008, State.FAULT),
)


def state_of(statusword: int) -> State:
    """The state that ``statusword`` reports."""
    for mask, value, state in _STATUS_MASKS:
        if statusword & mask == value:
            return state
    return State.NOT_READY_TO_SWITCH_ON


class StateMachine:
    """The drive side of the CiA 402 state machine (quick stop option: stay stopped).

    Commands are told apart by the bits CiA 402 Table 34 gives them (bit 7 clear):
    disable voltage ``xxxx xx0x``, quick stop ``xxxx x01x``, shutdown ``xxxx x110``, switch
    on / disable operation ``xxxx 0111``, enable operation ``xxxx 1111``; fault reset is
    the rising edge of bit 7.
    """

    def __init__(self) -> None:
        self.state = State.SWITCH_ON_DISABLED
        self._last_word = 0

    @property
    def statusword(self) -> int:
        """Statusword bits 0-6 of the state, with bit 4 'voltage enabled' and 9 'remote'."""
        word = self.state.value | 0x0200
        if self.state in (State.SWITCHED_ON, State.OPERATION_ENABLED, State.QUICK_STOP_ACTIVE):
            word |= 0x0010
        return word

    @property
    def enabled(self) -> bool:
        """True when the drive follows its target."""
        return self.state is State.OPERATION_ENABLED

    def fault(self) -> None:
        self.state = State.FAULT

    def on_controlword(self, word: int) -> State:
        """Apply a controlword; return the new state."""
        S = State
        s = self.state
        reset_edge = bool(word & CW_FAULT_RESET) and not self._last_word & CW_FAULT_RESET
        self._last_word = word
        if s is S.FAULT:
            if reset_edge:
                self.state = S.SWITCH_ON_DISABLED
            return self.state
        if word & CW_FAULT_RESET:  # a fault reset outside FAULT commands nothing
            return s
        if word & 0x0002 == 0:  # disable voltage
            self.state = S.SWITCH_ON_DISABLED
        elif word & 0x0006 == 0x0002:  # quick stop
            self.state = (S.QUICK_STOP_ACTIVE if s in (S.OPERATION_ENABLED, S.QUICK_STOP_ACTIVE)
                          else S.SWITCH_ON_DISABLED)
        elif word & 0x0007 == CW_SHUTDOWN:
            if s is not S.QUICK_STOP_ACTIVE:
                self.state = S.READY_TO_SWITCH_ON
        elif word & 0x000F == CW_SWITCH_ON:  # switch on, or disable operation
            if s in (S.READY_TO_SWITCH_ON, S.OPERATION_ENABLED):
                self.state = S.SWITCHED_ON
        elif word & 0x000F == CW_ENABLE_OPERATION and s in (
                S.READY_TO_SWITCH_ON, S.SWITCHED_ON, S.OPERATION_ENABLED):
            self.state = S.OPERATION_ENABLED  # from READY TO SWITCH ON: transitions 3 + 4
        return self.state
