"""``stand identify`` on real data: the six HSM150 runs and the EMPS benchmark.

Reads the shared data in place (``../shared/data/real/``), never a copy. Prints one
markdown row per run and model: Kt/J with its 95 % interval, D/J, the effects chosen
and the estimator, then the median of the six HSM150 runs against the rig's parameter
file (Kt/J0 = 0.0458/1.2153e-4 = 376.9 rad/(s²·A)).

The ``pooled`` section fits the six HSM150 runs jointly: one Kt/J, D/J and current
timing for the motor and its drive, each run's own friction level (never reversing, each
run's friction and any offset are one constant), with the noise compensation of ``bc``
and the block sandwich over all runs' blocks. It then asks whether the six runs'
estimates agree with that one value within their own intervals (a chi-square over the
runs), and how often six runs with these standard errors would all fall within 10 % of
their median.

    python tests/bench/bench_ident_real.py [hsm150] [pooled] [emps]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.io import loadmat
from scipy.stats import chi2
from scipy.stats import t as student_t

from stand.diagnosis.signals import prepare
from stand.errors import StandError
from stand.ident.columns import Design
from stand.ident.derivatives import auto_half_width
from stand.ident.estimate import solve_blocks
from stand.ident.identify import INSTRUMENT_MARGIN, identify_run
from stand.ident.noise import noise_sigma
from stand.ident.select import Fitter, select
from stand.importer import import_run
from stand.runfile import Run, check_columns

REAL = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "real"
#: Rig reference of HSM150 (its README: Cu/J0), rad/(s²·A).
HSM150_KT_OVER_J = 0.0458 / 1.2153e-4
#: Models shown: (label, effects, estimator, half width).
MODELS = (("auto", "auto", None, None), ("coulomb, ls", "coulomb_friction", "ls", None),
          ("coulomb, auto", "coulomb_friction", None, None))


def _row(name: str, run, label: str, effects: str, estimator: str | None,
         half_width: int | None) -> float | None:
    try:
        r = identify_run(run, effects=effects, estimator=estimator, half_width=half_width)
    except StandError as exc:
        print(f"| {name} | {label} | refused: {str(exc).split(': ', 1)[-1][:90]} | | | |")
        return None
    low, high = r.Kt_over_J_ci95
    print(f"| {name} | {label} | {r.Kt_over_J:.4g} [{low:.4g}, {high:.4g}] | "
          f"{r.D_over_J:.3f} | {', '.join(r.effects) or '—'} | {r.estimator} h={r.half_width} |")
    return r.Kt_over_J


def _hsm150_runs() -> list[Run]:
    """The six HSM150 runs: time, the measured current (column 7), the angle (column 3)."""
    runs = []
    for path in sorted((REAL / "hsm150").glob("idf_*.mat")):
        data = loadmat(path)["data"]
        runs.append(check_columns({"time_s": data[:, 0], "current_A": data[:, 6],
                                   "position_rad": data[:, 2]}, "single", path.stem))
    return runs


def hsm150() -> None:
    runs = _hsm150_runs()
    if not runs:
        print(f"no HSM150 data under {REAL / 'hsm150'}")
        return
    print(f"HSM150 (rig: Kt/J0 = {HSM150_KT_OVER_J:.1f} rad/(s²·A), B0/J0 = 0.572 1/s)\n")
    print("| run | model | Kt/J [95 %] | D/J | effects | estimator |")
    print("|---|---|---|---|---|---|")
    found: dict[str, list[tuple[float, list[float]]]] = {m[0]: [] for m in MODELS}
    for run in runs:
        for label, effects, estimator, half_width in MODELS:
            value = _row(run.source, run, label, effects, estimator, half_width)
            if value is not None:
                found[label].append((value, []))
    print()
    for label, values in found.items():
        v = np.array([x for x, _ in values])
        if v.size:
            median = float(np.median(v))
            print(f"{label}: {v.size} of {len(runs)} answered; median {median:.1f} "
                  f"({100 * (median / HSM150_KT_OVER_J - 1):+.1f} % of the rig's); spread "
                  f"{100 * (v.min() / median - 1):+.0f} … {100 * (v.max() / median - 1):+.0f} % "
                  "of the median")


#: Columns the pooled fit shares between the runs (one motor, one drive).
SHARED = ("omega", "current", "current_step")


def _run_rows(run: Run, estimator: str) -> tuple[list[str], np.ndarray, np.ndarray,
                                                  np.ndarray, int, float]:
    """One run's rows of the Coulomb-friction model (as ``--effects coulomb_friction``
    fits it): names, output, regressors, what the current noise adds to ``XᵀX``, the
    run's blocks and the noise level's relative uncertainty."""
    sig = prepare(run)
    h = auto_half_width(sig.current, noise_sigma(sig.current))
    design = Design.build(sig, h, 2 * h + 1 + INSTRUMENT_MARGIN)
    fitter = Fitter(design, estimator, run.source)
    spec = select(fitter, ["coulomb_friction"]).spec
    names, y, X, _ = design.matrices(spec, False, fitter.timing)
    noise = np.zeros((len(names), len(names)))
    if estimator == "bc":
        noise = design.noise_gram(spec, names, design.rows(spec, False))
    return names, y, X, noise, fitter.blocks, design.filtered_noise(spec.input_weight)[1]


def _pooled_fit(runs: list[Run], estimator: str) -> tuple[float, float, int, float]:
    """Kt/J of all runs at once, its variance, degrees of freedom, and the noise
    level's relative uncertainty (the largest of the runs')."""
    parts = [_run_rows(run, estimator) for run in runs]
    names = list(SHARED) + [f"{n}@{k}" for k, part in enumerate(parts)
                            for n in part[0] if n not in SHARED]
    rows = sum(len(part[1]) for part in parts)
    X = np.zeros((rows, len(names)))
    noise = np.zeros((len(names), len(names)))
    start = 0
    for k, (own, y, x, gram, _, _) in enumerate(parts):
        where = [names.index(n if n in SHARED else f"{n}@{k}") for n in own]
        X[start:start + len(y), where] = x
        noise[np.ix_(where, where)] += gram
        start += len(y)
    y = np.concatenate([part[1] for part in parts])
    blocks = sum(part[4] for part in parts)
    est = solve_blocks(names, y, X, X, blocks, "HSM150", noise)
    k = names.index("current")
    return float(est.beta[k]), float(est.cov[k, k]), est.dof, max(p[5] for p in parts)


def pooled() -> None:
    """The six HSM150 runs fitted jointly, against each run's own estimate."""
    runs = _hsm150_runs()
    if not runs:
        print(f"no HSM150 data under {REAL / 'hsm150'}")
        return
    bc, var, dof, noise_rel = _pooled_fit(runs, "bc")
    ls, _, _, _ = _pooled_fit(runs, "ls")
    # bc's compensation is as good as the noise level it subtracts (as identify adds it)
    var += ((bc - ls) * noise_rel) ** 2
    half = float(student_t.ppf(0.975, dof)) * np.sqrt(var)
    print(f"\nHSM150 pooled (Coulomb friction per run; one Kt/J, D/J, timing): Kt/J = "
          f"{bc:.1f} [{bc - half:.1f}, {bc + half:.1f}] (bc; least squares {ls:.1f}); "
          f"{100 * (bc / HSM150_KT_OVER_J - 1):+.1f} % of the rig's {HSM150_KT_OVER_J:.1f}\n")
    print("| run | Kt/J [95 %] | standard error | interval holds the pooled value | (b − pooled)/se |")
    print("|---|---|---|---|---|")
    values, errors = [], []
    for run in runs:
        r = identify_run(run, effects="coulomb_friction")
        low, high = r.Kt_over_J_ci95
        values.append(r.Kt_over_J)
        errors.append(r.Kt_over_J_se)
        print(f"| {run.source} | {r.Kt_over_J:.1f} [{low:.1f}, {high:.1f}] | "
              f"{r.Kt_over_J_se:.1f} ({100 * r.Kt_over_J_se / r.Kt_over_J:.0f} %) | "
              f"{'yes' if low <= bc <= high else 'no'} | {(r.Kt_over_J - bc) / r.Kt_over_J_se:+.2f} |")
    v, se = np.array(values), np.array(errors)
    stat = float(np.sum(((v - bc) / se) ** 2))
    print(f"\nagreement of the six with one Kt/J: chi-square {stat:.2f} on {len(v) - 1} "
          f"degrees of freedom, p = {chi2.sf(stat, len(v) - 1):.2f}")
    # six runs with these standard errors about one true value: how often are all six
    # within 10 % of their median?
    rng = np.random.default_rng(0)
    draws = bc + se * rng.standard_normal((100_000, len(se)))
    median = np.median(draws, axis=1, keepdims=True)
    within = np.mean(np.all(np.abs(draws / median - 1) <= 0.10, axis=1))
    print(f"six runs with these standard errors about one value fall all within 10 % of "
          f"their median in {100 * within:.2g} % of draws (100 000 draws)")
    for rel in (0.03, 0.035, 0.04, 0.05, 0.12):
        draws = 1.0 + rel * rng.standard_normal((100_000, len(se)))
        median = np.median(draws, axis=1, keepdims=True)
        within = np.mean(np.all(np.abs(draws / median - 1) <= 0.10, axis=1))
        print(f"  with a standard error of {100 * rel:.1f} % each: {100 * within:.3g} %")


def emps() -> None:
    path = REAL / "emps" / "DATA_EMPS.mat"
    if not path.is_file():
        print(f"no EMPS data under {path.parent}")
        return
    run = import_run(path, [("time_s", "t"), ("position_rad", "qm"),
                            ("current_A", "vir*gtau")], "single")
    print("\nEMPS (force in N, Kt = 1: Kt/J = 1/M; published IDIM M = 95.1089 kg, "
          "Fv/M = 2.1397 1/s, Fc = 20.3935 N, offset −3.1648 N)\n")
    print("| run | model | 1/M [95 %] | Fv/M | effects | estimator |")
    print("|---|---|---|---|---|---|")
    for label, effects, estimator, half_width in (("auto", "auto", None, None),
                                                  ("none", "none", None, None)):
        _row("DATA_EMPS", run, label, effects, estimator, half_width)
    r = identify_run(run)
    low, high = 1 / r.Kt_over_J_ci95[1], 1 / r.Kt_over_J_ci95[0]
    print(f"\nauto: M = {1 / r.Kt_over_J:.3f} kg [{low:.3f}, {high:.3f}]; "
          f"effect parameters {r.effect_params}")


def main(argv: list[str]) -> int:
    sections = {"hsm150": hsm150, "pooled": pooled, "emps": emps}
    for name in argv or list(sections):
        sections[name]()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
