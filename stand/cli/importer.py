"""``stand import SOURCE -o RUN.csv --kind KIND --map TARGET=EXPR ...``: MAT/CSV to a run file.

Examples::

    stand import DATA_EMPS.mat -o emps.csv --map time_s=t --map position_rad=qm \\
        --map current_A=vir*gtau --idim
    stand import idf_neg_0.04_1.mat -o hsm.csv --map time_s=data[:,0] \\
        --map position_rad=data[:,2] --map current_A=data[:,6]
    stand import SOURCE --list            # the file's variables and their shapes

``--idim`` also runs the IDIM-LS recipe (:mod:`stand.idim`) on the imported single-motor
run, reading ``current_A`` as force (or torque) times ``--kt``.
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from stand.errors import InputError
from stand.idim import DEFAULT_BANDWIDTH_HZ, idim_run
from stand.importer import import_run, load_variables, parse_mapping
from stand.jsonable import to_jsonable
from stand.runfile import COLUMNS, write_run


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("source", help="MAT or CSV file to import")
    parser.add_argument("-o", "--output", help="run file to write (CSV)")
    parser.add_argument("--kind", choices=list(COLUMNS), default="single", help="kind of run")
    parser.add_argument("--map", action="append", default=[], metavar="TARGET=EXPR",
                        help="run column from a variable, e.g. current_A=vir*gtau, "
                             "position_rad=data[:,2], time_s=t (repeatable)")
    parser.add_argument("--period", type=float,
                        help="sample period, s, to make time_s when it is not mapped")
    parser.add_argument("--list", action="store_true",
                        help="only list the file's variables and their shapes")
    parser.add_argument("--idim", action="store_true",
                        help="also run IDIM-LS (M, Fv, Fc, offset) on the imported single run")
    parser.add_argument("--kt", type=float, default=1.0,
                        help="--idim: force or torque per unit of current_A (default 1)")
    parser.add_argument("--bandwidth", type=float, default=DEFAULT_BANDWIDTH_HZ,
                        help="--idim: closed-loop bandwidth, Hz (sets filter and decimation)")
    parser.add_argument("--friction", choices=["symmetric", "asymmetric"], default="symmetric",
                        help="--idim: friction model")


def _variables(source: str) -> dict[str, Any]:
    return {name: {"shape": list(np.shape(value)), "dtype": str(np.asarray(value).dtype)}
            for name, value in sorted(load_variables(source).items())}


def run(args: argparse.Namespace) -> dict[str, Any]:
    if args.list:
        return {"source": args.source, "variables": _variables(args.source)}
    if not args.output:
        raise InputError("-o/--output is required (or use --list to see the variables)")
    if not args.map:
        raise InputError("give at least one --map TARGET=EXPR (see --list for the variables)")
    if args.idim and args.kind != "single":
        raise InputError(f"--idim needs --kind single, not {args.kind}")
    mapping = [parse_mapping(text) for text in args.map]
    imported = import_run(args.source, mapping, args.kind, args.period)
    path = write_run(args.output, imported.columns)
    result: dict[str, Any] = {
        "path": str(path), "source": args.source, "kind": args.kind,
        "samples": len(imported), "dt_s": imported.dt_s, "columns": list(imported.columns),
        "mapping": dict(mapping),
    }
    if args.idim:
        result["idim"] = to_jsonable(idim_run(imported, Kt=args.kt, bandwidth_hz=args.bandwidth,
                                              friction=args.friction))
    return result


def summarize(result: dict[str, Any]) -> str:
    if "variables" in result:
        return "\n".join(f"{name}: {info['dtype']} {'x'.join(map(str, info['shape'])) or 'scalar'}"
                         for name, info in result["variables"].items())
    lines = [f"wrote {result['samples']} samples at {1 / result['dt_s']:.4g} Hz to {result['path']} "
             f"({result['kind']}: {', '.join(result['columns'])})"]
    if "idim" in result:
        idim = result["idim"]
        lines.append(idim["message"])
        lines += [f"  {name} = {value:.6g} ± {idim['std'][name]:.3g}"
                  for name, value in idim["params"].items()]
        lines.append(f"  condition number {idim['condition_number']:.4g}, "
                     f"error std {idim['error_std']:.4g}")
    return "\n".join(lines)
