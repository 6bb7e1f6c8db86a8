#!/usr/bin/env bash
# The project's test command (README): lint, types, the installed wheel run from outside
# the checkout (tests/installed.sh), unit + integration tests, then the
# real-SocketCAN suite inside User-Mode Linux (skipped with a note where UML is missing,
# unless STAND_REQUIRE_VCAN=1).
set -euo pipefail
cd "$(dirname "$0")/.."
py=.venv/bin/python
[ -x "$py" ] || py=python3
"$py" -m ruff check stand bus api tests
"$py" -m mypy
bash tests/installed.sh
"$py" -m pytest "$@"
if [ -x /usr/bin/linux.uml ]; then
    bash tests/vcan/run.sh
elif [ "${STAND_REQUIRE_VCAN:-0}" = 1 ]; then
    echo "tests/run.sh: /usr/bin/linux.uml missing; install user-mode-linux" >&2
    exit 1
else
    echo "tests/run.sh: vcan suite skipped (no user-mode-linux here)" >&2
fi
