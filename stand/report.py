"""One self-contained HTML report of analysis results: parameters with units and intervals,
the figures (embedded PNGs), the diagnosis's verdict, and pass/fail against the limits of
an end-of-line profile (``profiles/limits/*.yaml``).

A limits profile names result fields and their bounds::

    name: crouzet_82800502_eol
    description: ...
    limits:
      Kt: {min: 0.0501, max: 0.0553}
      no_load_current_A: {max: 0.2}

A field is looked up in the result, then in its ``params`` and ``model``. A limit whose
field no result carries fails: an end-of-line test must measure what it promises.
"""

from __future__ import annotations

import base64
import html
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, model_validator

from stand.errors import InputError
from stand.profiles import read_profile, resolve, validate

#: Units of result fields (CONTRACT §2), SI.
UNITS = {
    "Kt": "N·m/A", "Kt_std": "N·m/A", "J": "kg·m²", "D": "N·m·s/rad", "C": "N·m/rad",
    "Kt_over_J": "rad/(s²·A)", "D_over_J": "1/s", "C_over_J": "1/s²", "fit_percent": "%",
    "gap_percent": "%", "verdict_gap_percent": "%", "condition_number": "", "samples": "",
    "no_load_current_A": "A", "delta_i_in_A": "A", "delta_i_out_A": "A", "efficiency": "",
    "efficiency_std": "", "R": "Ω", "L": "H", "K": "V·s/rad", "Kf": "N·m·s/rad",
    "repeats": "", "dt_s": "s",
}
#: Result fields that are bookkeeping, not parameters.
SKIPPED = {"result_id", "inputs", "message", "warnings", "effects", "where", "residual_where",
           "verdict", "model", "params", "identifiable", "transfer_function", "A", "B",
           "effect_params", "operation"}


class Bound(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    min: float | None = None
    max: float | None = None

    @model_validator(mode="after")
    def _ordered(self) -> Bound:
        if self.min is None and self.max is None:
            raise ValueError("give min, max or both")
        if self.min is not None and self.max is not None and self.min > self.max:
            raise ValueError(f"min {self.min} > max {self.max}")
        return self


class LimitsProfile(BaseModel):
    """End-of-line limits: result field → bounds."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    name: str
    description: str = ""
    limits: dict[str, Bound] = Field(min_length=1)


def load_limits(name_or_path: str | Path) -> LimitsProfile:
    """Load a limits profile by name (``profiles/limits/NAME.yaml``) or path.

    Raises
    ------
    NotFoundError
        No such profile.
    ProfileError
        A profile that does not validate (the message names the field).
    """
    path = resolve(name_or_path, "limits")
    return validate(LimitsProfile, read_profile(path), path)


@dataclass(frozen=True)
class Check:
    """One limit against one measured value."""

    field: str
    value: float | None
    bound: Bound
    source: str

    @property
    def passed(self) -> bool:
        if self.value is None or not math.isfinite(self.value):
            return False
        low = self.bound.min if self.bound.min is not None else -math.inf
        high = self.bound.max if self.bound.max is not None else math.inf
        return low <= self.value <= high


def _lookup(result: Mapping[str, Any], name: str) -> float | None:
    for where in (result, result.get("params") or {}, result.get("model") or {}):
        value = where.get(name) if isinstance(where, Mapping) else None
        if isinstance(value, int | float) and not isinstance(value, bool):
            return float(value)
    return None


def check_limits(results: Sequence[tuple[str, Mapping[str, Any]]],
                 limits: LimitsProfile) -> list[Check]:
    """Each limit checked against the first of ``results`` (title, fields) that carries it."""
    checks = []
    for name, bound in limits.limits.items():
        found = next(((title, v) for title, r in results if (v := _lookup(r, name)) is not None),
                     ("not measured", None))
        checks.append(Check(name, found[1], bound, found[0]))
    return checks


@dataclass
class Section:
    """One result in the report: its title, fields, and figures (PNG bytes with captions)."""

    title: str
    result: Mapping[str, Any]
    figures: list[tuple[str, bytes]] = field(default_factory=list)


def operation_of(result: Mapping[str, Any]) -> str:
    """The analysis a result came from, by its fields (CONTRACT §2)."""
    if "operation" in result:
        return str(result["operation"])
    for key, name in (("verdict", "diagnose"), ("transfer_function", "step-identify"),
                      ("efficiency", "efficiency"), ("Kt", "torque-constant"),
                      ("Kt_over_J", "identify")):
        if key in result:
            return name
    return "result"


def summary_line(result: Mapping[str, Any]) -> str:
    """The result's main numbers, for a figure."""
    parts = []
    for name in ("Kt", "J", "efficiency", "Kt_over_J", "D_over_J", "fit_percent", "gap_percent"):
        value = _lookup(result, name)
        if value is not None:
            ci = result.get(f"{name}_ci95")
            interval = f" [{ci[0]:.4g}, {ci[1]:.4g}]" if isinstance(ci, list) and len(ci) == 2 else ""
            parts.append(f"{name} = {value:.5g}{interval} {UNITS.get(name, '')}".rstrip())
    if "verdict" in result:
        parts.append(f"verdict: {result['verdict']}")
    return "; ".join(parts)


def _number(value: Any) -> str:
    return f"{value:.6g}" if isinstance(value, float) else html.escape(str(value))


def _parameters(result: Mapping[str, Any]) -> str:
    rows = []
    flat = {**{k: v for k, v in result.items() if k not in SKIPPED},
            **(result.get("params") or {})}
    for name, value in flat.items():
        if name.endswith(("_ci95", "_std", "_se")) or not isinstance(value, int | float | None):
            continue
        ci = result.get(f"{name}_ci95")
        std = result.get(f"{name}_std", result.get(f"{name}_se"))
        rows.append(f"<tr><td>{html.escape(name)}</td><td class=num>{_number(value)}</td>"
                    f"<td>{html.escape(UNITS.get(name, ''))}</td>"
                    f"<td class=num>{'' if std is None else _number(std)}</td>"
                    f"<td class=num>{' … '.join(map(_number, ci)) if isinstance(ci, list) else ''}"
                    "</td></tr>")
    return ("<table><tr><th>parameter</th><th>value</th><th>unit</th><th>std or s.e.</th>"
            "<th>95 % interval</th></tr>" + "".join(rows) + "</table>")


def _diagnosis(result: Mapping[str, Any]) -> str:
    if "verdict" not in result:
        return ""
    rows = "".join(
        f"<tr><td>{html.escape(str(e['effect']))}</td><td class=num>{e['gap_percent']:.3g}</td>"
        f"<td class=num>{e['shrink']:.3g}</td><td>{'yes' if e.get('significant') else 'no'}</td></tr>"
        for e in result.get("effects", []))
    where = html.escape(str(result.get("where", "")))
    return (f"<p class=verdict>Verdict: <b>{html.escape(str(result['verdict']))}</b> "
            f"(nominal gap {result['gap_percent']:.3g} %; where: {where})</p>"
            "<table><tr><th>effect</th><th>gap, %</th><th>shrink</th><th>significant</th></tr>"
            f"{rows}</table>")


def _checks(checks: Sequence[Check], limits: LimitsProfile) -> str:
    verdict = all(c.passed for c in checks)
    rows = "".join(
        f"<tr class={'pass' if c.passed else 'fail'}><td>{html.escape(c.field)}</td>"
        f"<td class=num>{'—' if c.value is None else _number(c.value)}</td>"
        f"<td>{html.escape(UNITS.get(c.field, ''))}</td>"
        f"<td class=num>{'' if c.bound.min is None else _number(c.bound.min)}</td>"
        f"<td class=num>{'' if c.bound.max is None else _number(c.bound.max)}</td>"
        f"<td>{html.escape(c.source)}</td><td>{'PASS' if c.passed else 'FAIL'}</td></tr>"
        for c in checks)
    return (f"<h2>End-of-line test: <span id=eol class={'pass' if verdict else 'fail'}>"
            f"{'PASS' if verdict else 'FAIL'}</span></h2>"
            f"<p>Limits {html.escape(limits.name)}: {html.escape(limits.description)}</p>"
            "<table><tr><th>field</th><th>value</th><th>unit</th><th>min</th><th>max</th>"
            f"<th>from</th><th>result</th></tr>{rows}</table>")


_STYLE = """body{font-family:system-ui,sans-serif;margin:1.5em 2em;color:#222;max-width:70em}
table{border-collapse:collapse;margin:.5em 0 1em}th,td{padding:.2em .7em;border-bottom:1px solid #ddd;
text-align:left}td.num{text-align:right;font-variant-numeric:tabular-nums}.pass{color:#1b5e20}
.fail{color:#b71c1c;font-weight:bold}figure{margin:1em 0}img{max-width:100%}.warn{color:#8d6e00}"""


def render_report(sections: Sequence[Section], title: str = "motorstand report",
                  limits: LimitsProfile | None = None) -> str:
    """The report as one HTML document; figures are embedded as ``data:`` PNGs, so the file
    opens anywhere, offline, on its own."""
    if not sections:
        raise InputError("a report needs at least one result")
    parts = [f"<!DOCTYPE html><html lang=en><head><meta charset=utf-8><title>{html.escape(title)}"
             f"</title><style>{_STYLE}</style></head><body><h1>{html.escape(title)}</h1>",
             f"<p>Made {time.strftime('%Y-%m-%d %H:%M:%S %Z')} by motorstand.</p>"]
    if limits is not None:
        parts.append(_checks(check_limits([(s.title, s.result) for s in sections], limits), limits))
    for section in sections:
        parts.append(f"<section><h2>{html.escape(section.title)}</h2>")
        parts.append(_diagnosis(section.result))
        parts.append(_parameters(section.result))
        for warning in section.result.get("warnings") or []:
            parts.append(f"<p class=warn>warning: {html.escape(str(warning))}</p>")
        for caption, png in section.figures:
            data = base64.b64encode(png).decode("ascii")
            parts.append(f"<figure><img alt='{html.escape(caption)}' src='data:image/png;base64,"
                         f"{data}'><figcaption>{html.escape(caption)}</figcaption></figure>")
        parts.append("</section>")
    parts.append("</body></html>")
    return "\n".join(parts)


def section_for(title: str, result: Mapping[str, Any], runs: Mapping[str, Any] | None = None,
                pngs: Sequence[tuple[str, bytes]] = ()) -> Section:
    """A section with its figures: each run the analysis used (the result on the figure),
    the candidate effects of a diagnosis, and any ready-made ``pngs``."""
    from stand.figures import effects_figure, run_figure

    figures = [(f"{name}: the run, with the result", run_figure(run, f"{title}: {name}",
                                                                  summary_line(result)))
               for name, run in (runs or {}).items()]
    if result.get("effects") and "gap_percent" in result:
        figures.append(("holdout gap of each candidate effect", effects_figure(result)))
    return Section(title, result, [*figures, *pngs])
