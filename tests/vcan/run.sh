#!/usr/bin/env bash
# Run the real-SocketCAN suite inside User-Mode Linux (the host kernel has no CAN).
#
#   bash tests/vcan/run.sh [PYTEST ARGS ...]
#
# Boots /usr/bin/linux.uml with the host's own file system as root (hostfs), where
# tests/vcan/uml_init.sh loads the CAN modules, creates vcan0 and runs
#   pytest tests/vcan tests/integration/test_bus_*.py -k "not virtual" [PYTEST ARGS]
# (an argument naming a test path replaces the default paths and drops the -k, as does a
# -k of the caller's; the bus cases' virtual variants run on the host), then
# tests/vcan/bench.py (frames/s, SYNC jitter) and tests/bench/bench_bus.py on vcan0, and
# writes the tests' exit status to a file this script reads. The guest's console (the test
# output) is this script's stdout; this script's own messages go to stderr.
#
# Exit status: the suite's status; 1 when UML is missing, fails to boot, exceeds its time
# limit or leaves no status file.
#
# Environment (all optional):
#   VCAN_BOOT_TIMEOUT_S  seconds from start until vcan0 must be up       (default 90)
#   VCAN_TIMEOUT_S       seconds for the whole run, boot included         (default 600)
#   VCAN_TEST_TIMEOUT_S  seconds one test may take (pytest-timeout)       (default 120)
#   VCAN_MEM             guest memory                                     (default 1G)
#   VCAN_BENCH=0         skip the benchmark (frames/s, SYNC jitter)
#   VCAN_PYTEST=0        skip the tests (only the benchmark)
#   VCAN_BUS_BENCH_ARGS  options of tests/bench/bench_bus.py   (default --duration 2 --realtime-s 2)
#   STAND_*, PYTEST_ADDOPTS, VCAN_*  are passed into the guest.
set -uo pipefail

here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
uml=${VCAN_UML:-/usr/bin/linux.uml}
boot_timeout_s=${VCAN_BOOT_TIMEOUT_S:-90}
timeout_s=${VCAN_TIMEOUT_S:-600}
mem=${VCAN_MEM:-1G}
POLL_PERIOD_S=0.2

say() { echo "vcan/run.sh: $*" >&2; }

if [ ! -x "$uml" ]; then
    say "$uml missing; install the Debian package user-mode-linux (and kmod, can-utils, iproute2)"
    exit 1
fi
modules=$(ls -d /usr/lib/uml/modules/*/ 2>/dev/null | sort -V | tail -n 1)
if [ -z "$modules" ]; then
    say "no kernel modules under /usr/lib/uml/modules/; reinstall user-mode-linux"
    exit 1
fi
for tool in candump cangen ip insmod; do
    if ! PATH="$PATH:/usr/sbin:/sbin" command -v "$tool" >/dev/null; then
        say "'$tool' missing; install can-utils, iproute2 and kmod"
        exit 1
    fi
done

# The project's Python, as an absolute path the guest can run without a shell profile
# (a pyenv shim or a venv activation script needs variables the guest does not have).
if [ -x "$repo/.venv/bin/python" ]; then
    py="$repo/.venv/bin/python"
else
    py=$(python3 -c 'import sys; print(sys.executable)') || { say "python3 not found"; exit 1; }
fi

work=$(mktemp -d "${TMPDIR:-/tmp}/motorstand-vcan.XXXXXX") || { say "mktemp failed"; exit 1; }
uml_pid=""
cleanup() {
    if [ -n "$uml_pid" ] && kill -0 "$uml_pid" 2>/dev/null; then
        kill -TERM -- "-$uml_pid" 2>/dev/null
        sleep 1
        kill -KILL -- "-$uml_pid" 2>/dev/null
    fi
    rm -rf "$work"
}
trap cleanup EXIT
trap 'say "interrupted"; exit 130' INT TERM

# Everything the guest needs, in a file it sources (its environment starts nearly empty).
{
    printf 'export VCAN_REPO=%q\n' "$repo"
    printf 'export VCAN_PY=%q\n' "$py"
    printf 'export VCAN_MODULES=%q\n' "${modules%/}"
    printf 'export VCAN_WORK=%q\n' "$work"
    printf 'export HOME=%q\n' "${HOME:-/root}"
    printf 'export VCAN_HOST_PATH=%q\n' "$PATH"
    env | grep -E '^(STAND_|PYTEST_ADDOPTS=|VCAN_)' | grep -vE '^VCAN_(REPO|PY|MODULES|WORK)=' |
        while IFS='=' read -r name value; do printf 'export %s=%q\n' "$name" "$value"; done
    printf 'set --'
    for arg in "$@"; do printf ' %q' "$arg"; done
    printf '\n'
} >"$work/env.sh"

say "booting User-Mode Linux ($uml, mem=$mem, modules ${modules%/}, python $py)"
start=$(date +%s.%N)
# setsid: the guest and its helper processes form one process group we can end together.
setsid "$uml" mem="$mem" root=/dev/root rootfstype=hostfs rootflags=/ rw loglevel=3 \
    con=null con0=null,fd:1 ssl=null init="$here/uml_init.sh" VCAN_ENV="$work/env.sh" \
    </dev/null 2>"$work/uml.stderr" &
uml_pid=$!

booted=0
while kill -0 "$uml_pid" 2>/dev/null; do
    now=$(date +%s.%N)
    if [ "$booted" = 0 ] && [ -e "$work/booted" ]; then
        booted=1
        say "vcan0 up after $(awk -v a="$start" -v b="$now" 'BEGIN{printf "%.1f", b-a}') s"
    fi
    if [ "$booted" = 0 ] && awk -v a="$start" -v b="$now" -v t="$boot_timeout_s" 'BEGIN{exit !(b-a>t)}'; then
        say "UML did not bring up vcan0 within $boot_timeout_s s (VCAN_BOOT_TIMEOUT_S); stopping it"
        [ -s "$work/uml.stderr" ] && tail -n 20 "$work/uml.stderr" >&2
        exit 1
    fi
    if awk -v a="$start" -v b="$now" -v t="$timeout_s" 'BEGIN{exit !(b-a>t)}'; then
        say "the vcan suite exceeded $timeout_s s (VCAN_TIMEOUT_S); stopping UML"
        exit 1
    fi
    sleep "$POLL_PERIOD_S"
done
wait "$uml_pid"
uml_status=$?
uml_pid=""
elapsed=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN{printf "%.1f", b-a}')

if [ ! -e "$work/booted" ]; then
    say "UML exited (status $uml_status) before vcan0 was up; its stderr:"
    tail -n 30 "$work/uml.stderr" >&2
    exit 1
fi
if [ ! -s "$work/status" ]; then
    say "UML exited (status $uml_status) after $elapsed s without writing a status file: the guest crashed"
    tail -n 30 "$work/uml.stderr" >&2
    exit 1
fi
status=$(cat "$work/status")
case "$status" in
    ''|*[!0-9]*) say "unreadable status '$status'"; exit 1 ;;
esac
say "done in $elapsed s, suite status $status"
exit "$status"
