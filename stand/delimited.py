"""Delimited text tables as labs export them: scopes, loggers, spreadsheets.

Handles a header row or none, a units row under the header (``s;A;rad``, ``[s]``,
``(mA)``: any row whose cells are not numbers), rows to skip before the header (a scope's
preamble), ``,`` or ``.`` as the decimal mark, and ``,``, ``;``, tab or blanks between
cells (sniffed). Lines starting with ``#`` and blank lines are ignored.
"""

from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stand.errors import InputError
from stand.runfile import read_text

#: The 2-D variable that holds a whole table.
TABLE_VARIABLE = "data"
DECIMAL_MARKS = (".", ",")

NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_SPECIAL = ("nan", "inf", "-inf", "+inf")


@dataclass(frozen=True)
class TableFormat:
    """How a delimited file is written.

    Parameters
    ----------
    decimal : {'.', ','}
        Decimal mark of the numbers.
    skip_rows : int
        Lines to drop before the header (or the first data row), counted after blank and
        ``#`` lines are removed.
    """

    decimal: str = "."
    skip_rows: int = 0

    def __post_init__(self) -> None:
        if self.decimal not in DECIMAL_MARKS:
            raise InputError(f"decimal must be '.' or ',', not {self.decimal!r}")
        if self.skip_rows < 0:
            raise InputError(f"skip_rows must be >= 0, got {self.skip_rows}")


def _is_number(cell: str, decimal: str) -> bool:
    text = cell.replace(decimal, ".") if decimal != "." else cell
    return bool(NUMBER.match(text)) or text.lower() in _SPECIAL


def _delimiter(lines: list[str], decimal: str) -> str:
    candidates = ";\t " if decimal == "," else ",;\t "
    try:
        return csv.Sniffer().sniff("\n".join(lines[:6]), candidates).delimiter
    except csv.Error:
        return ";" if decimal == "," else ","


#: Longest line of a delimited file, characters: thousands of columns of numbers, and far
#: below what makes the csv module choke (its field limit is 131 072).
MAX_LINE_CHARS = 100_000


def read_table(path: Path, fmt: TableFormat = TableFormat()) -> tuple[dict[str, np.ndarray], list[str]]:
    """The columns of a delimited file by header name, the whole table as ``data``, and
    notes on what was detected (a units row).

    Raises
    ------
    InputError
        No data rows, a row with a different number of cells, a cell that is not a number
        (naming the row and the column), or a comma decimal mark with comma delimiters.
    """
    text = read_text(path)
    lines = [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    lines = lines[fmt.skip_rows:]
    if not lines:
        skipped = f" after skipping {fmt.skip_rows}" if fmt.skip_rows else ""
        raise InputError(f"{path}: no data rows{skipped}")
    longest = max(range(len(lines)), key=lambda k: len(lines[k]))
    if len(lines[longest]) > MAX_LINE_CHARS:
        raise InputError(f"{path}: line {longest + 1} is {len(lines[longest])} characters long, "
                         f"more than {MAX_LINE_CHARS}; expected one sample a line")
    delimiter = _delimiter(lines, fmt.decimal)
    if delimiter == "," and fmt.decimal == ",":
        raise InputError(f"{path}: ',' is both the decimal mark and the delimiter; such a file "
                         "cannot be read unambiguously (export with ';' between cells)")
    rows = [[cell.strip() for cell in row if cell.strip() or delimiter != " "]
            for row in csv.reader(io.StringIO("\n".join(lines)), delimiter=delimiter,
                                  skipinitialspace=True)]
    notes: list[str] = []
    has_header = not all(_is_number(cell, fmt.decimal) for cell in rows[0])
    header = rows[0] if has_header else [str(k) for k in range(len(rows[0]))]
    first = 1 if has_header else 0
    # A second non-numeric row under the header is its units row (s, A, [rad], (mA)).
    if has_header and len(rows) > 1 and not any(_is_number(c, fmt.decimal) for c in rows[1]):
        notes.append(f"line {fmt.skip_rows + 2} read as a units row: {', '.join(rows[1])}")
        first = 2
    body = rows[first:]
    if not body:
        raise InputError(f"{path}: a header but no data rows")
    table = np.empty((len(body), len(header)))
    for k, row in enumerate(body):
        line = fmt.skip_rows + first + k + 1
        if len(row) != len(header):
            raise InputError(f"{path}: row {line} has {len(row)} cells; the header has {len(header)}")
        for col, cell in enumerate(row):
            try:
                table[k, col] = float(cell.replace(fmt.decimal, ".") if fmt.decimal != "." else cell)
            except ValueError:
                hint = (" (a decimal comma? give --decimal ,)" if fmt.decimal == "." and "," in cell
                        else "")
                raise InputError(
                    f"{path}: row {line}, column {header[col]!r}: {cell!r} is not a number{hint}"
                ) from None
    variables = {name: table[:, k] for k, name in enumerate(header)} if has_header else {}
    variables.setdefault(TABLE_VARIABLE, table)
    return variables, notes
