"""The profiles motorstand ships: data, not code.

Installed as the package ``stand.profile_data`` and read with :mod:`importlib.resources`
(:mod:`stand.profiles`), so an installed ``stand`` finds them from any directory:
``motors/``, ``stands/``, ``experiments/``, ``limits/`` (end-of-line limits of reports;
YAML) and ``eds/`` (object dictionaries).
"""
