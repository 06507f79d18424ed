"""Identification of the hydrodynamic coefficients (report section 2) by linear least squares.

Modules, one concern each:

* :mod:`~auv_ident.identify.equations`: the five regressions (surge, heave, pitch, sway, yaw),
  their coefficients and what excites each;
* :mod:`~auv_ident.identify.records`: the force records (force topic or forces from motion)
  and how sensor noise propagates into them;
* :mod:`~auv_ident.identify.regressors`: regressor columns, the model's own hydrodynamic terms
  (:func:`auv_sim.model.hydro_basis`) for unit coefficients;
* :mod:`~auv_ident.identify.regression`: ``b = A theta`` pooled over records, identifiability,
  the least-squares solve and the report's Nelder-Mead for comparison;
* :mod:`~auv_ident.identify.covariance`: the four covariance estimators (``hac``, ``ess``,
  ``jackknife``, ``iid``);
* :mod:`~auv_ident.identify.results`: results, 95 % intervals and the JSON summary;
* :mod:`~auv_ident.identify.fit`: :func:`fit_equation` and :func:`identify`.
"""
from auv_ident.identify.covariance import (
    ERROR_METHODS,
    correlation_time,
    flat_top_lag,
    sensor_noise_meat,
)
from auv_ident.identify.equations import (
    AXES,
    EQUATIONS,
    EXCITATION,
    NU_NAMES,
    SIGN_BOUNDS,
    Equation,
    Excitation,
    excitation_amplitude,
)
from auv_ident.identify.fit import compare_nelder_mead, fit_equation, identify
from auv_ident.identify.records import ForceRecord, LoggedRun, NoisePropagation, check_record
from auv_ident.identify.regression import (
    COND_MAX,
    LinearSystem,
    build_system,
    check_identifiable,
    nelder_mead,
    solve,
)
from auv_ident.identify.regressors import regressor_columns
from auv_ident.identify.results import (
    CoefficientEstimate,
    EquationFit,
    Identification,
    summary,
)

__all__ = [
    'AXES', 'COND_MAX', 'EQUATIONS', 'ERROR_METHODS', 'EXCITATION', 'NU_NAMES', 'SIGN_BOUNDS',
    'CoefficientEstimate', 'Equation', 'EquationFit', 'Excitation', 'ForceRecord',
    'Identification', 'LinearSystem', 'LoggedRun', 'NoisePropagation', 'build_system',
    'check_identifiable', 'check_record', 'compare_nelder_mead', 'correlation_time',
    'excitation_amplitude', 'fit_equation', 'flat_top_lag', 'identify', 'nelder_mead',
    'regressor_columns', 'sensor_noise_meat', 'solve', 'summary',
]
