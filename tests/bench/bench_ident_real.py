"""``stand identify`` on real data: the six HSM150 runs and the EMPS benchmark.

Reads the shared data in place (``../shared/data/real/``), never a copy. Prints one
markdown row per run and model: Kt/J with its 95 % interval, D/J, the effects chosen
and the estimator, then the median of the six HSM150 runs against the rig's parameter
file (Kt/J0 = 0.0458/1.2153e-4 = 376.9 rad/(s²·A)).

    python tests/bench/bench_ident_real.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.io import loadmat

from stand.errors import StandError
from stand.ident.identify import identify_run
from stand.importer import import_run
from stand.runfile import check_columns

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


def hsm150() -> None:
    files = sorted((REAL / "hsm150").glob("idf_*.mat"))
    if not files:
        print(f"no HSM150 data under {REAL / 'hsm150'}")
        return
    print(f"HSM150 (rig: Kt/J0 = {HSM150_KT_OVER_J:.1f} rad/(s²·A), B0/J0 = 0.572 1/s)\n")
    print("| run | model | Kt/J [95 %] | D/J | effects | estimator |")
    print("|---|---|---|---|---|---|")
    found: dict[str, list[tuple[float, list[float]]]] = {m[0]: [] for m in MODELS}
    for path in files:
        data = loadmat(path)["data"]
        run = check_columns({"time_s": data[:, 0], "current_A": data[:, 6],
                             "position_rad": data[:, 2]}, "single", path.stem)
        for label, effects, estimator, half_width in MODELS:
            value = _row(path.stem, run, label, effects, estimator, half_width)
            if value is not None:
                found[label].append((value, []))
    print()
    for label, values in found.items():
        v = np.array([x for x, _ in values])
        if v.size:
            median = float(np.median(v))
            print(f"{label}: {v.size} of {len(files)} answered; median {median:.1f} "
                  f"({100 * (median / HSM150_KT_OVER_J - 1):+.1f} % of the rig's); spread "
                  f"{100 * (v.min() / median - 1):+.0f} … {100 * (v.max() / median - 1):+.0f} % "
                  "of the median")


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
    sections = {"hsm150": hsm150, "emps": emps}
    for name in argv or list(sections):
        sections[name]()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
