#!/usr/bin/env bash
# What a user installs: build the wheel, install it (not editable) into a fresh venv
# outside the checkout, and run `stand simulate`, `stand demo` and the README's Python
# example from another directory, where no source tree is on the path.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
py="$root/.venv/bin/python"
[ -x "$py" ] || py=python3
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
quiet() {  # run "$@", showing its output only when it fails
    "$@" > "$work/log" 2>&1 || { cat "$work/log" >&2; return 1; }
}
quiet "$py" -m pip wheel -q --no-deps -w "$work/dist" "$root"
quiet python3 -m venv "$work/venv"
quiet "$work/venv/bin/pip" install -q "$work"/dist/*.whl
cd "$work"
"$py" - "$root/README.md" > example.py <<'PY'
import re, sys
text = open(sys.argv[1], encoding="utf-8").read()
section = text.split("## Python API", 1)[1]
print(re.search(r"```python\n(.*?)```", section, re.S).group(1))
PY
"$work/venv/bin/stand" simulate crouzet_82800502 -o run.csv --duration 2 --seed 1 --json
MPLBACKEND=Agg "$work/venv/bin/stand" demo --json > demo.json 2> demo.log \
    || { cat demo.log >&2; exit 1; }
"$work/venv/bin/python" - <<'PY'
import json
demo = json.load(open("demo.json"))
assert abs(demo["Kt"] / demo["Kt_profile"] - 1) < 0.02, demo["Kt"]
print(f"installed demo: Kt {demo['Kt']:.5g} N·m/A (profile {demo['Kt_profile']}), "
      f"efficiency {demo['efficiency']:.4f} (profile {demo['efficiency_profile']})")
PY
"$work/venv/bin/python" example.py
echo "tests/installed.sh: the installed wheel runs outside the checkout" >&2
