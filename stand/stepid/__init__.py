"""Voltage-step identification of a DC motor (seed 001): R, L, K, J and viscous friction.

Modules, one concept each:

- :mod:`stand.stepid.model`: the seed 001 model as transfer-function coefficients, and its
  exact zero-order-hold response to a measured voltage.
- :mod:`stand.stepid.equation_error`: the linear least-squares start (integral form).
- :mod:`stand.stepid.search`: the minimizers of seed 001's comparison (trf, lm, gradient
  descent, pattern search).
- :mod:`stand.stepid.physical`: physical parameters and identifiability from the
  coefficients and known values.
- :mod:`stand.stepid.stats`: fit %, residual whiteness, confidence intervals.
- :mod:`stand.stepid.identify`: :func:`identify_steps`, the front door.
- :mod:`stand.stepid.simulated`: simulated step runs from a motor profile.
"""

from stand.stepid.identify import StepResult, identify_steps, simulated_response
from stand.stepid.model import PARAM_NAMES, coefficients
from stand.stepid.search import METHODS

__all__ = ["METHODS", "PARAM_NAMES", "StepResult", "coefficients", "identify_steps",
           "simulated_response"]
