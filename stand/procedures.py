"""The experiments of seed 000 as data: command sequences a stand executes.

A :class:`Procedure` is what to command on each drive port, one value a sample, and at
which sample period. The same object is run by direct simulation
(:func:`simulate_procedure`) and by the bus controller, so a simulated and a bus run of a
procedure are the same experiment.

- :func:`torque_constant_procedures`: the no-load run and the added-inertia run of §4.2,
  repeated (5 times in the seed), the motor turning forward only (§4.1, to keep the
  no-load current of §5.1 one-signed).
- :func:`diagnosis_procedures`: runs for the sim-to-real diagnosis (CONTRACT §3), the
  speed command crossing zero so that the shaft turns both ways.
- :func:`efficiency_procedure`: the two-motor run of §3.6: the input motor held at a
  constant speed while the output motor applies load steps.

The identification excitation is the seed's "white noise" (§4.1) limited to a band the
drive's speed loop follows and the sample rate resolves: a random-phase multisine with a
flat spectrum up to ``band_hz``. A zero-order-held random command (PRBS) makes the speed
loop's current spikes last a few milliseconds, which a 15 ms sample period cannot resolve
(see docs/results/core.md for the measured difference).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from stand.errors import InputError
from stand.physics.effects import Effects
from stand.physics.plant import MotorPlant
from stand.physics.reducer import ReducerPlant
from stand.physics.simulate import simulate_motor, simulate_reducer
from stand.profiles import MotorProfile, StandProfile
from stand.runfile import Run

#: Inertia of the seed's disk load (§4.2), kg·m².
SEED_ADDED_INERTIA_KGM2 = 1.007e-5
#: Repeats of each run in the seed (§4.2).
SEED_REPEATS = 5
#: The seed's sample period (§4.1), s, and samples a run (§4.2).
SEED_PERIOD_S = 0.015
SEED_SAMPLES = 100
#: Default experiment: the bus's 1 kHz SYNC period, s, and the run length, s.
DEFAULT_PERIOD_S = 1e-3
DEFAULT_DURATION_S = 10.0
#: Mean speed and excursion of the identification command, as fractions of the speed limit.
SPEED_LEVEL_FRACTION = 0.5
SPEED_EXCURSION_FRACTION = 0.25
#: Excursion of the diagnosis command around zero speed, as a fraction of the speed limit.
REVERSING_EXCURSION_FRACTION = 0.5
#: Runs of a diagnosis: one to identify on (TRAIN), one to score on (HOLDOUT).
DIAGNOSIS_REPEATS = 2
#: Highest frequency of the excitation at 1 kHz, Hz (below the ≈30 Hz speed loop).
DEFAULT_BAND_HZ = 10.0
#: Highest frequency of the excitation as a fraction of the Nyquist frequency.
BAND_NYQUIST_FRACTION = 0.2
#: Efficiency run: speed of the input motor as a fraction of its limit, and the plateaus.
EFFICIENCY_SPEED_FRACTION = 0.4
EFFICIENCY_PLATEAUS = 10
EFFICIENCY_SETTLE_PLATEAUS = 2
#: The seed's speed step (§4.3: about 330 rad/s at a 20 V command), rad/s.
SEED_STEP_SPEED_RAD_S = 330.0
#: Bandwidth of the seed driver's (JW-143-2) analog speed loop, Hz: its step responses
#: (Figs. 4-6) settle in about 300 ms, a first-order loop of about 2 Hz.
SEED_SPEED_LOOP_HZ = 2.0
#: Zero of that PI loop as a fraction of its bandwidth.
SEED_PI_ZERO_FRACTION = 0.25


@dataclass(frozen=True)
class PortCommand:
    """What one drive port is commanded: its mode and one target a sample."""

    mode: str
    values: np.ndarray


@dataclass(frozen=True)
class Procedure:
    """One experiment run.

    Attributes
    ----------
    name : str
        ``no_load``, ``added_inertia`` or ``efficiency``, with a repeat suffix.
    sample_period_s : float
        Sample (SYNC) period, s.
    commands : tuple of PortCommand
        One per port (one for a single motor; input then output for the reducer stand).
    added_inertia_kgm2 : float
        Inertia to mount on the shaft before the run, kg·m².
    kind : str
        Run-file kind the run produces (``single`` or ``reducer``).
    description : str
        What the operator does.
    """

    name: str
    sample_period_s: float
    commands: tuple[PortCommand, ...]
    added_inertia_kgm2: float = 0.0
    kind: str = "single"
    description: str = ""
    meta: dict[str, float] = field(default_factory=dict)

    @property
    def samples(self) -> int:
        """Samples of the run."""
        return len(self.commands[0].values)


def multisine(samples: int, dt_s: float, level: float, amplitude: float, band_hz: float,
              seed: int | None = None) -> np.ndarray:
    """Band-limited white command: ``level`` plus a random-phase multisine.

    Equal amplitudes at every frequency bin of the record from its lowest up to
    ``band_hz``, scaled so the command stays within ``level ± amplitude``.
    """
    if samples < 4 or not dt_s > 0:
        raise InputError(f"multisine: need >= 4 samples and dt_s > 0, got {samples}, {dt_s}")
    bins = int(band_hz * samples * dt_s)
    if bins < 1:
        raise InputError(
            f"multisine: a {samples * dt_s:.3g} s record has no frequency bin below "
            f"{band_hz} Hz; record longer or raise the band"
        )
    rng = np.random.default_rng(seed)
    spectrum = np.zeros(samples // 2 + 1, dtype=complex)
    spectrum[1:bins + 1] = np.exp(2j * np.pi * rng.random(bins))
    wave = np.fft.irfft(spectrum, samples)
    return np.asarray(level + amplitude * wave / np.max(np.abs(wave)))


def _band_hz(dt_s: float) -> float:
    return min(DEFAULT_BAND_HZ, BAND_NYQUIST_FRACTION * 0.5 / dt_s)


def torque_constant_procedures(profile: MotorProfile, repeats: int = SEED_REPEATS,
                               period_s: float = DEFAULT_PERIOD_S,
                               duration_s: float = DEFAULT_DURATION_S,
                               added_inertia_kgm2: float = SEED_ADDED_INERTIA_KGM2,
                               seed: int = 0) -> tuple[list[Procedure], list[Procedure]]:
    """No-load and added-inertia runs of seed 000 §4.2, ``repeats`` of each.

    Parameters
    ----------
    profile : MotorProfile
        The motor (its speed limit sets the command).
    repeats : int
        Repeats of each run.
    period_s : float
        Sample period, s (the seed: 0.015 with 100 samples; default 1 kHz for 10 s).
    duration_s : float
        Length of each run, s.
    added_inertia_kgm2 : float
        Inertia of the disk of the loaded runs, kg·m².
    seed : int
        Seed of the excitation; each run gets its own.

    Returns
    -------
    (no_load, loaded) : two lists of Procedure
    """
    if repeats < 1:
        raise InputError(f"repeats must be >= 1, got {repeats}")
    if not added_inertia_kgm2 > 0:
        raise InputError(f"added inertia must be > 0 kg·m², got {added_inertia_kgm2}")
    samples = int(round(duration_s / period_s))
    limit = profile.limits.speed_rad_s
    level, amplitude = SPEED_LEVEL_FRACTION * limit, SPEED_EXCURSION_FRACTION * limit
    runs: dict[str, list[Procedure]] = {"no_load": [], "added_inertia": []}
    for k in range(repeats):
        for j, (name, inertia) in enumerate((("no_load", 0.0),
                                             ("added_inertia", added_inertia_kgm2))):
            command = multisine(samples, period_s, level, amplitude, _band_hz(period_s),
                                seed=seed * 1000 + 2 * k + j)
            load = f"disk of {inertia:.4g} kg·m² mounted" if inertia else "no load"
            runs[name].append(Procedure(
                f"{name}_{k + 1}", period_s, (PortCommand("speed", command),), inertia,
                description=(f"speed command {level:.0f} ± {amplitude:.0f} rad/s band-limited "
                             f"noise, forward only; {load}"),
            ))
    return runs["no_load"], runs["added_inertia"]


def diagnosis_procedures(profile: MotorProfile, repeats: int = DIAGNOSIS_REPEATS,
                         period_s: float = DEFAULT_PERIOD_S,
                         duration_s: float = DEFAULT_DURATION_S, seed: int = 0
                         ) -> list[Procedure]:
    """Runs for the sim-to-real diagnosis (CONTRACT §3): ``repeats`` no-load runs under a
    band-limited noise speed command around zero, ``±REVERSING_EXCURSION_FRACTION`` of
    the speed limit, each with its own excitation.

    The shaft turns both ways, so that ``sign(ω)`` is not a constant: Coulomb friction
    and a current offset are then separate torques. On the forward-only runs of
    :func:`torque_constant_procedures` they are one constant, and a diagnosis can only
    name the pair. The first run is TRAIN, the second HOLDOUT.
    """
    if repeats < 1:
        raise InputError(f"repeats must be >= 1, got {repeats}")
    samples = int(round(duration_s / period_s))
    amplitude = REVERSING_EXCURSION_FRACTION * profile.limits.speed_rad_s
    return [Procedure(f"diagnosis_{k + 1}", period_s,
                      (PortCommand("speed", multisine(samples, period_s, 0.0, amplitude,
                                                      _band_hz(period_s),
                                                      seed=seed * 1000 + 500 + k)),),
                      description=(f"speed command 0 ± {amplitude:.0f} rad/s band-limited "
                                   "noise, both ways; no load"))
            for k in range(repeats)]


def seed_driver(profile: MotorProfile) -> MotorProfile:
    """``profile`` with the seed's slow speed loop (``SEED_SPEED_LOOP_HZ``) in its drive.

    A PI speed loop around ``J·ω' = Kt·i`` has a bandwidth of about ``kp·Kt/(2π·J)``, so
    ``kp = 2π·f·J/Kt``; the integral gain puts the PI zero at ``SEED_PI_ZERO_FRACTION·f``.
    """
    m = profile.motor
    kp = 2 * np.pi * SEED_SPEED_LOOP_HZ * m.J / m.Kt
    ki = kp * 2 * np.pi * SEED_PI_ZERO_FRACTION * SEED_SPEED_LOOP_HZ
    drive = profile.drive.model_copy(update={"speed_kp": kp, "speed_ki": ki})
    return profile.model_copy(update={"drive": drive})


def seed_procedures(repeats: int = SEED_REPEATS,
                    added_inertia_kgm2: float = SEED_ADDED_INERTIA_KGM2
                    ) -> tuple[list[Procedure], list[Procedure]]:
    """The seed's own runs (§4.1-4.2): a speed step from rest, 100 samples at 15 ms.

    Run them on :func:`seed_driver` (the seed's slow speed loop) to reproduce the seed.
    """
    command = np.full(SEED_SAMPLES, SEED_STEP_SPEED_RAD_S)
    runs: dict[str, list[Procedure]] = {"no_load": [], "added_inertia": []}
    for k in range(repeats):
        for name, inertia in (("no_load", 0.0), ("added_inertia", added_inertia_kgm2)):
            runs[name].append(Procedure(
                f"seed_{name}_{k + 1}", SEED_PERIOD_S, (PortCommand("speed", command),),
                inertia, description=f"speed step from rest to {SEED_STEP_SPEED_RAD_S} rad/s"))
    return runs["no_load"], runs["added_inertia"]


def efficiency_procedure(stand: StandProfile, motor_in: MotorProfile, load_current_A: float,
                         duration_s: float = 10.0, period_s: float | None = None) -> Procedure:
    """The two-motor run of §3.6: constant input speed, output load steps.

    The output motor (current mode) alternates between 0 A and ``−|load_current_A|`` on
    equal plateaus after ``EFFICIENCY_SETTLE_PLATEAUS`` settling plateaus.
    """
    dt = period_s or stand.sample_period_s
    samples = int(round(duration_s / dt))
    speed = EFFICIENCY_SPEED_FRACTION * motor_in.limits.speed_rad_s
    plateau = np.arange(samples) * EFFICIENCY_PLATEAUS // samples
    load = np.where((plateau >= EFFICIENCY_SETTLE_PLATEAUS) & (plateau % 2 == 1),
                    -abs(load_current_A), 0.0)
    return Procedure("efficiency", dt, (PortCommand("speed", np.full(samples, speed)),
                                        PortCommand("current", load)), kind="reducer",
                     description=f"input at {speed:.0f} rad/s, output load steps of "
                                 f"{abs(load_current_A)} A")


def simulate_procedure(procedure: Procedure, profile: MotorProfile,
                       effects: Effects | None = None, seed: int | None = None,
                       current_mean: bool = False) -> Run:
    """Run a single-motor procedure on the simulated motor of ``profile``;
    ``current_mean``: also the column ``current_mean_A``, as the simulated drive on the
    bus reports it (0x2002)."""
    if procedure.kind != "single":
        raise InputError(f"procedure {procedure.name} is a {procedure.kind} run; "
                         "use simulate_stand_procedure")
    (port,) = procedure.commands
    plant = MotorPlant(profile.motor_params(), profile.drive_params(port.mode),
                       profile.sensor_params(),
                       profile.effect_set() if effects is None else effects,
                       added_inertia=procedure.added_inertia_kgm2, seed=seed)
    return simulate_motor(plant, port.mode, port.values, procedure.sample_period_s,
                          current_mean=current_mean)


def simulate_stand_procedure(procedure: Procedure, stand: StandProfile, motor_in: MotorProfile,
                             motor_out: MotorProfile, seed: int | None = None,
                             efficiency: float | None = None) -> Run:
    """Run the reducer procedure on the simulated two-motor stand."""
    reducer = stand.reducer_params()
    if efficiency is not None:
        reducer = replace(reducer, efficiency=efficiency)
    port_in, port_out = procedure.commands
    plant = ReducerPlant(
        motor_in.motor_params(), motor_out.motor_params(), reducer,
        motor_in.drive_params(port_in.mode), motor_out.drive_params(port_out.mode),
        motor_in.sensor_params(), motor_in.effect_set(), motor_out.effect_set(), seed=seed)
    return simulate_reducer(plant, [(port_in.mode, port_in.values),
                                    (port_out.mode, port_out.values)],
                            procedure.sample_period_s)
