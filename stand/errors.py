"""The one exception root of motorstand.

Every error the project raises on purpose derives from :class:`StandError`. Where a
built-in exception has the same meaning, the subclass inherits it too, so callers may
catch either::

    StandError
    ├── InputError (ValueError)          bad input: a file, a field, a parameter
    │   ├── RunFileError                 a run file that breaks CONTRACT §1
    │   ├── ProfileError                 a profile that does not validate
    │   └── NotExcitedError              data that cannot determine the model
    ├── NotFoundError (LookupError)      an unknown run id, profile or node
    ├── LimitError                       a command outside the profile's limits
    ├── SolverError (ArithmeticError)    a numerical method that failed to converge
    ├── StorageError (OSError)           the run database cannot be written (disk full, I/O)
    │   └── DataDirLocked                another process owns the data directory
    ├── BusError                         CAN / CANopen trouble
    │   ├── BusTimeout (TimeoutError)    an SDO, boot-up or PDO that did not come
    │   ├── DriveFault                   a drive that reported a fault (EMCY)
    │   ├── HeartbeatLost                a node whose heartbeat stopped
    │   ├── NodeNotOperational           a drive that left NMT OPERATIONAL mid-run
    │   ├── ForeignSync                  SYNC frames another producer sent
    │   └── DeviceMismatch               a device that is not the one its EDS describes
    └── RunAborted                       a run stopped before its end (samples kept)

Messages say what was found, what was expected, and what to do about it.
"""

from __future__ import annotations


class StandError(Exception):
    """Root of every error motorstand raises on purpose."""


class InputError(StandError, ValueError):
    """Bad input: a file, a field or a parameter that is not what it must be."""


class RunFileError(InputError):
    """A run file (CSV) that does not follow CONTRACT §1."""


class ProfileError(InputError):
    """A motor, drive, stand or experiment profile that does not validate."""


class NotExcitedError(InputError):
    """Data that do not excite the model enough to identify it."""


class NotFoundError(StandError, LookupError):
    """An unknown run id, profile name, node or object."""


class LimitError(StandError):
    """A command that would exceed a limit of the profile; nothing was sent."""


class SolverError(StandError, ArithmeticError):
    """A numerical method that did not converge or met a singular problem."""


class StorageError(StandError, OSError):
    """The run database could not be read or written (disk full, I/O error)."""


class DataDirLocked(StorageError):
    """Another process owns the data directory (a second ``stand serve`` on it)."""


class BusError(StandError):
    """Trouble on the CAN bus or in the CANopen protocol."""


class BusTimeout(BusError, TimeoutError):
    """An SDO answer, boot-up, heartbeat or PDO that did not arrive in time."""


class DriveFault(BusError):
    """A drive that reported a fault (EMCY or statusword fault bit)."""


class HeartbeatLost(BusError):
    """A node whose heartbeat stopped arriving within its consumer time."""


class NodeNotOperational(BusError):
    """A drive that left NMT OPERATIONAL during a run (its heartbeat or a foreign NMT command)."""


class ForeignSync(BusError):
    """SYNC frames on the bus that the master did not send (a second SYNC producer)."""


class DeviceMismatch(BusError):
    """A device whose device type (0x1000) or identity (0x1018) is not what its EDS says."""


class RunAborted(StandError):
    """A run that stopped before its end; the samples recorded so far are kept."""
