"""The inputs of a batch: files, globs and stored runs, as numbered items with a group.

An INPUT of the command line (or of ``POST /batch``) is one of

``PATH`` or ``GLOB``
    run files (CONTRACT §1); a glob expands in sorted order, one item per file;
``run:ID``
    a run stored by the service (:mod:`stand.storage`);
``query:KEY=VALUE[,KEY=VALUE ...]``
    every stored run matching all of ``kind``, ``state``, ``profile``, ``origin``
    (oldest first), at most ``limit`` of them;
``FIRST,SECOND``
    for operations that take two runs an item (``diagnose``: TRAIN and HOLDOUT;
    ``torque-constant``: no-load and loaded run): each side a path, a glob or ``run:ID``;
    two globs pair their files one to one in sorted order.

Each item carries the refs a worker resolves (absolute paths or ``run:ID``) and its
*group*, the fleet it is pooled with: for ``auto`` the profile of a stored run, or the
folder a file is in.
"""

from __future__ import annotations

import glob
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from stand.errors import InputError
from stand.storage import RunRecord, Storage

#: Prefixes of stored-run inputs.
RUN_PREFIX = "run:"
QUERY_PREFIX = "query:"
#: Fields a query may filter on, and its size limit.
QUERY_FIELDS = ("kind", "state", "profile", "origin")
DEFAULT_QUERY_LIMIT = 100_000
#: Runs read from the database per page while expanding a query.
QUERY_PAGE = 1000
#: Ways of forming the pooled groups (or ``re:REGEX``, the first capture group of the input).
POOL_KEYS = ("auto", "all", "none", "dir", "profile")
#: Group name of runs whose group key is unknown (a stored run without a profile).
UNKNOWN_GROUP = "(unknown)"


@dataclass(frozen=True)
class Item:
    """One unit of work of a batch.

    Attributes
    ----------
    index : int
        Position in the batch (the output row).
    input : str
        What the user gave for it (a path, ``run:ID``, or ``FIRST,SECOND``).
    refs : tuple of str
        The runs a worker reads: absolute paths or ``run:ID``.
    group : str
        The fleet it is pooled with ("" with pooling ``none``).
    """

    index: int
    input: str
    refs: tuple[str, ...]
    group: str


@dataclass(frozen=True)
class _Ref:
    ref: str
    group_dir: str
    profile: str | None


def expand_inputs(inputs: Sequence[str], runs_per_item: int, *, database: Path | None = None,
                  pool: str = "auto") -> list[Item]:
    """Expand INPUTS into items.

    Parameters
    ----------
    inputs : sequence of str
        Paths, globs, ``run:ID``, ``query:...``, or ``FIRST,SECOND`` pairs.
    runs_per_item : {1, 2}
        Runs an item of the operation takes.
    database : Path, optional
        The service's SQLite file, needed for ``run:`` and ``query:`` inputs.
    pool : str
        How items are grouped: one of :data:`POOL_KEYS` or ``re:REGEX``.

    Raises
    ------
    InputError
        An input that matches nothing, a pair with unequal counts, a malformed query or
        pool key, or a stored run asked for without a database.
    """
    check_pool(pool)
    if not inputs:
        raise InputError("no INPUTS: give run files, globs, run:ID or query:KEY=VALUE")
    storage = Storage(database) if database is not None and _uses_storage(inputs) else None
    try:
        items: list[Item] = []
        for text in inputs:
            sides = text.split(",") if runs_per_item == 2 else [text]
            if len(sides) != runs_per_item:
                raise InputError(
                    f"input {text!r}: this operation takes two runs an item, given as "
                    "FIRST,SECOND (e.g. 'runs/*_train.csv,runs/*_holdout.csv')")
            expanded = [_expand(side.strip(), storage, runs_per_item == 2) for side in sides]
            if len({len(e) for e in expanded}) != 1:
                counts = " and ".join(f"{len(e)} for {side.strip()!r}"
                                      for e, side in zip(expanded, sides, strict=True))
                raise InputError(f"input {text!r}: the two sides must match as many runs, got {counts}")
            for refs in zip(*expanded, strict=True):
                label = text if len(expanded[0]) == 1 else ",".join(r.ref for r in refs)
                items.append(Item(len(items), label, tuple(r.ref for r in refs),
                                  _group(refs[0], label, pool)))
        return items
    finally:
        if storage is not None:
            storage.close()


def check_pool(pool: str) -> None:
    """Refuse a pool key that is not one of :data:`POOL_KEYS` or a valid ``re:REGEX``."""
    if pool.startswith("re:"):
        try:
            pattern = re.compile(pool[3:])
        except re.error as exc:
            raise InputError(f"pool {pool!r}: not a regular expression ({exc})") from None
        if pattern.groups < 1:
            raise InputError(f"pool {pool!r}: the expression needs a capture group, the group name")
    elif pool not in POOL_KEYS:
        raise InputError(f"pool must be one of {', '.join(POOL_KEYS)} or re:REGEX, not {pool!r}")


def _uses_storage(inputs: Sequence[str]) -> bool:
    return any(RUN_PREFIX in text or QUERY_PREFIX in text for text in inputs)


def _expand(text: str, storage: Storage | None, in_pair: bool) -> list[_Ref]:
    if text.startswith((RUN_PREFIX, QUERY_PREFIX)):
        if storage is None:
            raise InputError(f"input {text!r}: stored runs need the service's database "
                             "(--db PATH, or STAND_DATA_DIR / STAND_DB_PATH)")
        if text.startswith(RUN_PREFIX):
            record = storage.get_run(text[len(RUN_PREFIX):])
            return [_Ref(RUN_PREFIX + record.id, "", record.profile)]
        if in_pair:
            raise InputError(f"input {text!r}: a query cannot be one side of a pair; give "
                             "run:ID on each side, or files or globs")
        return [_Ref(RUN_PREFIX + r.id, "", r.profile) for r in _query(storage, text)]
    matches = sorted(glob.glob(text)) if glob.has_magic(text) else [text]
    if not matches:
        raise InputError(f"input {text!r}: the glob matches no file")
    paths = [Path(m).resolve() for m in matches]
    for path in paths:
        if not path.is_file():
            raise InputError(f"input {text!r}: {path} is not a file")
    return [_Ref(str(p), p.parent.name, None) for p in paths]


def _query(storage: Storage, text: str) -> list[RunRecord]:
    wanted: dict[str, str] = {}
    limit = DEFAULT_QUERY_LIMIT
    for part in filter(None, (p.strip() for p in text[len(QUERY_PREFIX):].split(","))):
        key, sep, value = part.partition("=")
        if not sep or key not in (*QUERY_FIELDS, "limit"):
            raise InputError(f"input {text!r}: {part!r} must be KEY=VALUE with KEY one of "
                             f"{', '.join(QUERY_FIELDS)}, limit")
        if key == "limit":
            if not value.isdigit() or int(value) < 1:
                raise InputError(f"input {text!r}: limit must be an integer >= 1, not {value!r}")
            limit = int(value)
        else:
            wanted[key] = value
    found: list[RunRecord] = []
    offset = 0
    while True:
        page = storage.list_runs(QUERY_PAGE, offset, wanted.get("state"))
        found += [r for r in page if all(str(getattr(r, k)) == v for k, v in wanted.items())]
        if len(page) < QUERY_PAGE:
            break
        offset += QUERY_PAGE
    found.sort(key=lambda r: (r.created_s, r.id))  # oldest first: a stable batch order
    if not found:
        raise InputError(f"input {text!r}: no stored run matches")
    return found[:limit]


def _group(ref: _Ref, label: str, pool: str) -> str:
    if pool == "none":
        return ""
    if pool == "all":
        return "all"
    if pool.startswith("re:"):
        match = re.search(pool[3:], label)
        return match.group(1) if match and match.group(1) is not None else UNKNOWN_GROUP
    if pool == "profile" or (pool == "auto" and ref.ref.startswith(RUN_PREFIX)):
        return ref.profile or UNKNOWN_GROUP
    return ref.group_dir or UNKNOWN_GROUP
