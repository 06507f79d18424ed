"""A model that predicts held-out data worse than its base file, or diverges, is not written;
on a plant that is not the model's form the identification stays physical and is written.

The plant is the issue's case: the REMUS 100 whose cross-flow drag is strip theory over its
hull with the cross-flow coupled (the ``hull_crossflow`` effect of the simulator: not the
model's separate quadratic terms), flown for 5 minutes in closed loop with BAR doublets and
logged with navigation-grade noise, identified against ``config/remus100.yaml`` (Prestero's
quadratic terms, Mqq 25 times the hull's strip theory).

Oracles: the former procedure (file structure, unbounded, no priors) reproduces the issue's
failure (pitch anti-damping ``CMuq > 0``) and the held-out free runs show it (they are not
written: exit status 3, no ``vehicle.yaml``); the default procedure's coefficients keep their
physical signs and its model predicts an independent flight of the plant better than the base.
"""
from __future__ import annotations

import json
import pathlib

import pytest
from conftest import load_bench

ROOT = pathlib.Path(__file__).resolve().parents[1]
REMUS = ROOT / 'config' / 'remus100.yaml'
PANEL = load_bench('ident_panel')


@pytest.fixture(scope='module')
def flights(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """The plant's 5-minute log (a contract bag without forces) and an independent 5-minute
    flight."""
    from auv_gap import synth
    from auv_logs.simlog import write_record

    root = tmp_path_factory.mktemp('validation')
    plant, effects, _ = PANEL.plant_of('remus100', 'strip')
    log = synth.simulate(plant, effects, PANEL.scenario('remus100', 5), seed=41)
    write_record(root / 'strip', log.record, forces=False, sent_commands=log.commands)
    check = synth.simulate(plant, effects, PANEL.scenario('remus100', 5, shift=7.0), seed=42)
    return {'bag': root / 'strip', 'check': check, 'root': root}


def ident(bag: pathlib.Path, out: pathlib.Path, *extra: str) -> int:
    from auv_ident import cli

    return cli.main([str(bag), '--vehicle', str(REMUS), '--out', str(out), '--partial',
                     '--no-nelder-mead', *extra])


def test_the_former_fit_is_unphysical_and_not_an_answer(flights: dict[str, object]) -> None:
    """The file's structure, unbounded, without priors: the pitch fit bends to Prestero's
    quadratic terms into anti-damping (CMuq > 0) and explains less than the mean (R^2 < 0):
    not identified, its coefficients stay at the base."""
    from auv_bag import read_arrays
    from auv_ident.identify import identify
    from auv_ident.motion import needed_topics, records_from_topics
    from auv_sim.params import load_vehicle

    base = load_vehicle(REMUS)
    records = records_from_topics(read_arrays(flights['bag'], needed_topics('motion')), base,
                                  'motion')
    result = identify(records, base, equations=['pitch'], bounds={}, use_priors=False,
                      structures=False, partial=True)
    fit = result.fits['pitch']
    assert {c.name: c.value for c in fit.coefficients}['CMuq'] > 0.0
    assert fit.r2 < 0.0 and not fit.identified
    assert result.not_identifiable['pitch'].startswith('R^2 = ')
    assert result.params.CMuq == base.CMuq


def test_a_model_that_diverges_on_held_out_data_is_not_written(
        flights: dict[str, object]) -> None:
    """The plant's own file with pitch anti-damping (CMuq = +0.3, the issue's sign) against
    the file as it is, on held-out windows of the plant's log."""
    from auv_ident.freerun import split_windows, window_length
    from auv_ident.identify import LoggedRun
    from auv_ident.validate import validate
    from auv_sim.params import load_vehicle

    check = flights['check']
    base = load_vehicle(REMUS)
    run = LoggedRun(t=check.t, state=check.state, commands=dict(check.commands))
    length, _ = window_length(base, [run])
    windows = split_windows([run], length)
    val = validate([run], windows, base, base.replace(CMuq=0.3))
    assert val.verdict in ('worse', 'diverges') and not val.written
    assert val.message.startswith('not written: the identified model')
    assert val.growth['identified'] > val.growth['base']
    same = validate([run], windows, base, base)
    assert same.verdict == 'as good' and same.written


def test_the_default_fit_stays_physical_and_predicts_better(flights: dict[str, object],
                                                            tmp_path: pathlib.Path) -> None:
    from auv_ident.identify.physics import constraint
    from auv_sim.params import load_vehicle

    assert ident(flights['bag'], tmp_path) == 0
    report = json.loads((tmp_path / 'report.json').read_text())
    base = load_vehicle(REMUS)
    for name, c in report['coefficients'].items():
        con = constraint(name, base)
        assert con.lo <= c['value'] <= con.hi, (name, c['value'])
        assert c['ci95'][1] > c['ci95'][0], name
    assert report['coefficients']['CMuq']['value'] < 0.0
    assert report['equations']['pitch']['structure'] != 'file'
    assert report['validation']['verdict'] in ('better', 'as good')
    assert report['validation']['ratio']['z'] < 1.0
    written = load_vehicle(tmp_path / 'vehicle.yaml')
    depth = PANEL.held_out_depth(flights['check'], base, written)
    assert depth['written'] < depth['base']
    assert written.sources['CMuq'].startswith('identified from strip (pitch')
