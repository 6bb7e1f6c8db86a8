"""``stand import SOURCE -o RUN.csv [--kind KIND] [--map TARGET=EXPR ...]``: a file to a run file.

SOURCE: MAT, delimited text, ASAM MDF 4 (``.mf4``) or a CAN trace (``.log``, ``.asc``,
``.blf``). Without ``--map`` every run column the file holds by name is taken as it is.

Examples::

    stand import scope.csv -o run.csv --decimal , --map time_s=t/1000 \\
        --map "position_rad=deg2rad(angle)" --map current_A=I
    stand import RUN.mf4 -o run.csv
    stand import no_load_1.log -o run.csv     # a trace of stand run: no flags needed
    stand import late.log -o run.csv --motor crouzet_82800502 --period 0.001
    stand import bus.blf --dbc drive.dbc --list

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
import logging
from typing import Any, cast

import numpy as np

from stand.cli import options
from stand.delimited import TableFormat
from stand.errors import InputError
from stand.idim import DEFAULT_BANDWIDTH_HZ, idim_run
from stand.importer import import_run, load_variables, parse_mapping
from stand.jsonable import to_jsonable
from stand.runfile import COLUMNS, write_run
from stand.sources import ReadOptions

log = logging.getLogger("stand")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("source", type=options.input_file,
                        help="file to import: .mat, .csv/.txt, .mf4, .log/.asc/.blf")
    parser.add_argument("-o", "--output", type=options.output_file, help="run file to write (CSV)")
    parser.add_argument("--kind", choices=list(COLUMNS), default="single", help="kind of run")
    parser.add_argument("--map", action="append", default=[], metavar="TARGET=EXPR",
                        help="run column from a variable, e.g. current_A=vir*gtau, "
                             "position_rad=data[:,2], time_s=t (repeatable)")
    parser.add_argument("--period", type=options.period,
                        help="sample period, s, to make time_s when it is not mapped; for a CAN "
                             "trace without 0x1006, its SYNC period")
    parser.add_argument("--decimal", choices=[".", ","], default=".",
                        help="text files: decimal mark (',' for many scope exports)")
    parser.add_argument("--skip-rows", type=options.whole(0, 10**6), default=0, metavar="N",
                        help="text files: lines to skip before the header (a units row under "
                             "the header is detected)")
    parser.add_argument("--motor", help="CAN traces: motor profile giving encoder counts per "
                                        "revolution and rated current (default: the trace's "
                                        "0x608F and 0x6075)")
    parser.add_argument("--eds", help="CAN traces: the drives' EDS (default: motorstand's)")
    parser.add_argument("--node", type=options.whole(1, 127), help="CAN traces: decode this node only")
    parser.add_argument("--dbc", help="CAN traces: decode the signals of this DBC instead of "
                                      "CANopen PDOs (then --map the signals)")
    parser.add_argument("--list", action="store_true",
                        help="only list the file's variables and their shapes")
    parser.add_argument("--idim", action="store_true",
                        help="also run IDIM-LS (M, Fv, Fc, offset) on the imported single run")
    parser.add_argument("--kt", type=options.positive, default=1.0,
                        help="--idim: force or torque per unit of current_A (default 1)")
    parser.add_argument("--bandwidth", type=options.positive, default=DEFAULT_BANDWIDTH_HZ,
                        help="--idim: closed-loop bandwidth, Hz (sets filter and decimation)")
    parser.add_argument("--friction", choices=["symmetric", "asymmetric"], default="symmetric",
                        help="--idim: friction model")


def _variables(source: str, options: ReadOptions) -> dict[str, Any]:
    return {name: {"shape": list(np.shape(value)), "dtype": str(np.asarray(value).dtype)}
            for name, value in sorted(load_variables(source, options).items())}


def _options(args: argparse.Namespace) -> ReadOptions:
    return ReadOptions(TableFormat(args.decimal, args.skip_rows), args.kind, motor=args.motor,
                       eds=args.eds, node=args.node, period_s=args.period, dbc=args.dbc)


def run(args: argparse.Namespace) -> dict[str, Any]:
    logging.getLogger("numexpr").setLevel(logging.WARNING)  # asammdf's import announces threads
    options = _options(args)
    if args.list:
        return {"source": args.source, "variables": _variables(args.source, options)}
    if not args.output:
        raise InputError("-o/--output is required (or use --list to see the variables)")
    if args.idim and args.kind != "single":
        raise InputError(f"--idim needs --kind single, not {args.kind}")
    mapping = [parse_mapping(text) for text in args.map]
    imported = import_run(args.source, mapping, args.kind, args.period, options)
    path = write_run(args.output, imported.columns)
    for warning in cast(list[str], imported.meta["warnings"]):
        log.warning("warning: %s", warning)
    result: dict[str, Any] = {
        "path": str(path), "source": args.source, "kind": args.kind,
        "samples": len(imported), "dt_s": imported.dt_s, "columns": list(imported.columns),
        "mapping": imported.meta["mapping"], "file_meta": imported.meta["file_meta"],
        "notes": imported.meta["notes"], "warnings": imported.meta["warnings"],
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
