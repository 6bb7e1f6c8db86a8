"""Identification of seed 000: the Q-matrix equation-error method, torque constant, efficiency.

Modules, one concept each:

- :mod:`stand.ident.qmatrix`: the sums Q1, Q2, Q11, Q12, Q22 of eq. 10 and their solution,
  batched and streaming.
- :mod:`stand.ident.derivatives`: state derivatives from sampled (quantized) position.
- :mod:`stand.ident.identify`: one single-motor run to A, B and the physical ratios.
- :mod:`stand.ident.columns`: the effect regressors and their instruments.
- :mod:`stand.ident.select`: which effects the model holds (``--effects``).
- :mod:`stand.ident.estimate`: IV / bias-compensated LS, block-sandwich intervals.
- :mod:`stand.ident.checks`: effect parameters and the warnings.
- :mod:`stand.ident.torque_constant`: Kt from no-load and added-inertia runs (eqs. 11-17).
- :mod:`stand.ident.efficiency`: reducer efficiency from a two-motor run (eq. 18).
"""
