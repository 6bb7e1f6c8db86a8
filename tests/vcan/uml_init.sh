#!/bin/sh
# init (PID 1) of the User-Mode Linux guest started by tests/vcan/run.sh.
#
# The root file system is the host's (hostfs), so the repository, the Python and its
# packages are at the same paths as on the host. We mount only guest-private file systems
# (/proc, /sys, /dev/shm); /tmp stays the host's so that the status file reaches the host.
# Whatever happens, the guest ends with `halt -f` (PID 1 must never exit).

PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
export PATH
status=1
finish() {
    [ -n "${VCAN_WORK:-}" ] && echo "$status" >"$VCAN_WORK/status"
    sync
    halt -f
}
trap finish EXIT
fail() { echo "uml_init: $*" >&2; exit 1; }

mount -t proc proc /proc || fail "cannot mount /proc"
mount -t sysfs sys /sys || fail "cannot mount /sys"
[ -d /dev/shm ] || mkdir -p /dev/shm
mount -t tmpfs -o mode=1777 shm /dev/shm || fail "cannot mount /dev/shm"

# VCAN_ENV is passed on the kernel command line; the file sets VCAN_*, HOME, STAND_* and
# the pytest arguments ("$@").
[ -n "${VCAN_ENV:-}" ] && [ -r "$VCAN_ENV" ] || fail "VCAN_ENV file '${VCAN_ENV:-}' not readable"
. "$VCAN_ENV"
export LANG=C.UTF-8 LC_ALL=C.UTF-8 TERM=dumb PYTHONUNBUFFERED=1 VCAN_IN_UML=1
export PYTHONPATH="$VCAN_REPO${PYTHONPATH:+:$PYTHONPATH}"
export STAND_BUS_INTERFACE="${STAND_BUS_INTERFACE:-socketcan}" STAND_BUS_CHANNEL="${STAND_BUS_CHANNEL:-vcan0}"
hostname vcan-guest 2>/dev/null
ip link set up lo 2>/dev/null

for ko in net/can/can.ko net/can/can-raw.ko net/can/can-bcm.ko drivers/net/can/dev/can-dev.ko drivers/net/can/vcan.ko; do
    insmod "$VCAN_MODULES/kernel/$ko" || fail "insmod $ko failed"
done
ip link add dev vcan0 type vcan || fail "cannot create vcan0"
# A deeper transmit queue than the default 1000 frames would hide overload; keep the default.
ip link set up vcan0 || fail "cannot bring up vcan0"
[ -e /sys/class/net/vcan0 ] || fail "/sys/class/net/vcan0 missing after creation"
date +%s.%N >"$VCAN_WORK/booted"
echo "uml_init: vcan0 up ($(uname -r), $(nproc) CPU), python $VCAN_PY"

cd "$VCAN_REPO" || fail "cannot cd to $VCAN_REPO"
suite_start=$(date +%s)
# The default targets, unless an argument names a test path (tests/vcan/run.sh FILE -k X).
targets="tests/vcan $(ls tests/integration/test_bus_*.py 2>/dev/null | tr '\n' ' ')"
own_k=0
for arg in "$@"; do
    case "$arg" in -k*) own_k=1 ;; -*) ;; *) [ -e "${arg%%::*}" ] && targets="" ;; esac
done
# With the default targets and no -k of the caller's: the bus cases on socketcan only.
# Their [virtual] variants already ran on the host (tests/run.sh); skipping them here keeps
# the suite under 5 minutes on the guest's one CPU.
[ -n "$targets" ] && [ "$own_k" = 0 ] && set -- -k "not virtual" "$@"
# -vv (pyproject's addopts has -q) names each test as it starts, so a hang shows where;
# --timeout ends a hung test with a traceback well before run.sh's limit ends the guest.
# --basetemp: the guest's temporary test files live in run.sh's work directory, apart from
# the host's own pytest runs in /tmp/pytest-of-$USER.
opts="-p no:cacheprovider -vv --durations=8 --timeout=${VCAN_TEST_TIMEOUT_S:-120} --basetemp=$VCAN_WORK/pytest"
if [ "${VCAN_PYTEST:-1}" != 0 ]; then
    echo "uml_init: pytest $opts $targets$*"
    # shellcheck disable=SC2086  # word splitting of the option and target lists is intended
    "$VCAN_PY" -m pytest $opts $targets "$@"
    status=$?
    echo "uml_init: pytest exit status $status after $(( $(date +%s) - suite_start )) s"
else
    status=0
fi

# The benchmark prints figures; its timing depends on the host's load, so a failure there
# is reported but does not fail the suite.
if [ "${VCAN_BENCH:-1}" != 0 ]; then
    "$VCAN_PY" -m tests.vcan.bench || echo "uml_init: WARNING: the vcan benchmark failed (status $?)"
    # The bus benchmark (owner "bus") on vcan0, shortened to fit the 5-minute budget.
    if grep -q -- '--interface' tests/bench/bench_bus.py 2>/dev/null; then
        echo "uml_init: python tests/bench/bench_bus.py --interface socketcan --channel vcan0 ${VCAN_BUS_BENCH_ARGS:=--duration 2 --realtime-s 2}"
        # shellcheck disable=SC2086  # the arguments are split on purpose
        "$VCAN_PY" tests/bench/bench_bus.py --interface socketcan --channel vcan0 $VCAN_BUS_BENCH_ARGS ||
            echo "uml_init: WARNING: tests/bench/bench_bus.py failed (status $?)"
    fi
fi
exit "$status"
