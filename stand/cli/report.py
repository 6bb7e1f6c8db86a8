"""``stand report RESULT.json|DIR ... -o report.html [--limits NAME]``: one HTML report.

RESULT.json is a command's ``--json`` output. A DIR contributes every ``*.json`` result,
every ``*.png`` figure (``stand diagnose --plot DIR``) and every run file ``*.csv`` in it
(drawn with the results). ``--run`` adds run files to draw. ``--limits`` checks the results
against an end-of-line limits profile (``profiles/limits``); the exit code stays 0 and the
report and the JSON say PASS or FAIL.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from stand.errors import InputError
from stand.report import check_limits, load_limits, operation_of, render_report, section_for
from stand.runfile import Run, RunFileError, read_run


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("inputs", nargs="+", help="result JSON files or folders")
    parser.add_argument("-o", "--output", required=True, help="HTML file to write")
    parser.add_argument("--limits", help="end-of-line limits profile (name or path)")
    parser.add_argument("--run", action="append", default=[], metavar="RUN.csv",
                        help="run file to draw with the results (repeatable)")
    parser.add_argument("--title", default="motorstand report", help="the report's title")


def _any_run(path: Path) -> Run:
    """A run file of whichever kind its columns make it."""
    errors = []
    for kind in ("reducer", "single", "step"):
        try:
            return read_run(path, kind)
        except RunFileError as exc:
            errors.append(str(exc))
    raise InputError(f"{path}: not a run file of any kind ({errors[1]})")


def _result(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a readable result JSON ({exc})") from exc
    if not isinstance(data, dict):
        raise InputError(f"{path}: a result must be a JSON object, got {type(data).__name__}")
    return data


def _collect(args: argparse.Namespace) -> tuple[list[tuple[Path, dict[str, Any]]], dict[str, Run],
                                                list[tuple[str, bytes]]]:
    results, runs, pngs = [], {}, []
    for text in args.inputs:
        path = Path(text)
        if path.is_dir():
            results += [(p, _result(p)) for p in sorted(path.glob("*.json"))]
            pngs += [(p.stem.replace("_", " "), p.read_bytes()) for p in sorted(path.glob("*.png"))]
            runs.update({p.name: _any_run(p) for p in sorted(path.glob("*.csv"))})
        elif path.is_file():
            results.append((path, _result(path)))
        else:
            raise InputError(f"{path}: no such file or folder")
    runs.update({Path(p).name: _any_run(Path(p)) for p in args.run})
    if not results:
        raise InputError(f"no result JSON in {', '.join(args.inputs)}; save one with "
                         "stand COMMAND --json > result.json")
    return results, runs, pngs


def run(args: argparse.Namespace) -> dict[str, Any]:
    results, runs, pngs = _collect(args)
    limits = load_limits(args.limits) if args.limits else None
    sections = []
    for n, (path, result) in enumerate(results):
        title = f"{operation_of(result)}: {path.name}"
        # The runs and figures go with the first result (one analysis per report is usual).
        sections.append(section_for(title, result, runs if n == 0 else None, pngs if n == 0 else ()))
    output = Path(args.output)
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(render_report(sections, args.title, limits), encoding="utf-8")
    out: dict[str, Any] = {"path": str(output), "results": [str(p) for p, _ in results],
                           "figures": sum(len(s.figures) for s in sections)}
    if limits is not None:
        checks = check_limits([(s.title, s.result) for s in sections], limits)
        out["limits"] = limits.name
        out["passed"] = all(c.passed for c in checks)
        out["checks"] = [{"field": c.field, "value": c.value, "min": c.bound.min,
                          "max": c.bound.max, "passed": c.passed} for c in checks]
    return out


def summarize(result: dict[str, Any]) -> str:
    line = f"wrote {result['path']}: {len(result['results'])} result(s), {result['figures']} figure(s)"
    if "passed" in result:
        failed = [c["field"] for c in result["checks"] if not c["passed"]]
        line += f"; {result['limits']}: " + ("PASS" if result["passed"] else f"FAIL ({', '.join(failed)})")
    return line
