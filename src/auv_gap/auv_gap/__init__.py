"""Sim-to-real gap diagnosis: where a vehicle model departs from logs of the real vehicle,
and which unmodelled effect of the catalogue explains it (see :func:`diagnose`)."""
from auv_gap.catalogue import CATALOGUE, Effect, Parameter, Perturbation, register
from auv_gap.diagnose import Diagnosis, diagnose
from auv_gap.logs import GapLog, from_arrays, load_bag
from auv_gap.report import write_report

__all__ = ['CATALOGUE', 'Diagnosis', 'Effect', 'GapLog', 'Parameter', 'Perturbation',
           'diagnose', 'from_arrays', 'load_bag', 'register', 'write_report']
