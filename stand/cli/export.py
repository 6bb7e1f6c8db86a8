"""``stand export RUN.csv -o RUN.mf4``: a run file to ASAM MDF 4, with units and metadata.

Each run column becomes a channel with the unit its name carries, ``time_s`` the master
channel; ``--profile``, ``--motor``, ``--seed`` and any ``--meta KEY=VALUE`` go into the
file header's properties, where MDF tools show them. ``stand import RUN.mf4`` reads it back.
"""

from __future__ import annotations

import argparse
import logging
from typing import Any

from stand.errors import InputError
from stand.mdf import unit_of, write_mdf
from stand.runfile import COLUMNS, read_run


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_file", help="run file (CSV, CONTRACT §1)")
    parser.add_argument("-o", "--output", required=True, help="MDF 4 file to write (.mf4)")
    parser.add_argument("--kind", choices=list(COLUMNS), default="single", help="kind of run")
    parser.add_argument("--profile", help="experiment or stand profile the run came from")
    parser.add_argument("--motor", help="motor profile of the run")
    parser.add_argument("--seed", type=int, help="seed of the simulated run")
    parser.add_argument("--meta", action="append", default=[], metavar="KEY=VALUE",
                        help="more metadata for the file header (repeatable)")


def _meta(args: argparse.Namespace) -> dict[str, Any]:
    meta: dict[str, Any] = {"source": args.run_file, "kind": args.kind}
    meta.update({k: v for k in ("profile", "motor", "seed") if (v := getattr(args, k)) is not None})
    for text in args.meta:
        key, sep, value = text.partition("=")
        if not sep or not key.strip():
            raise InputError(f"--meta {text!r}: expected KEY=VALUE, e.g. --meta operator=kim")
        meta[key.strip()] = value.strip()
    return meta


def run(args: argparse.Namespace) -> dict[str, Any]:
    logging.getLogger("numexpr").setLevel(logging.WARNING)  # asammdf's import announces threads
    run_ = read_run(args.run_file, args.kind)
    meta = _meta(args)
    path = write_mdf(args.output, run_.columns, meta)
    return {"path": str(path), "source": args.run_file, "samples": len(run_),
            "channels": {name: unit_of(name) for name in run_.columns}, "meta": meta}


def summarize(result: dict[str, Any]) -> str:
    channels = ", ".join(f"{name} [{unit}]" for name, unit in result["channels"].items())
    return f"wrote {result['samples']} samples to {result['path']}: {channels}"
