"""precompile fills the cache the nodes read: every family's whole-run kernel and stepper."""
from mmg_tuner.cli.precompile import command
from mmg_tuner.core._numba_cache import cache_dir
from mmg_tuner.core.models import REGISTRY
from mmg_tuner.core.precompile import kernels, ships_by_family
from mmg_tuner.core.ship import load_ship


def test_every_family_has_an_embedded_ship_to_precompile_with():
    ships = ships_by_family()
    assert set(ships) == set(REGISTRY)
    assert all(load_ship(f).model == family for family, f in ships.items())


def test_the_stepper_is_warmed_for_every_family():
    """The stepper is compiled per family (its tag is in its type): sim_node on any family."""
    jobs = set(kernels())
    driven = [fam for fam, f in ships_by_family().items()
              if load_ship(f).family.inputs[:2] == ('rpm', 'rudder')]   # what sim_node drives
    assert len(driven) >= 3, driven
    assert {f'stepper, {family} family (sim_node)' for family in driven} <= jobs, jobs
    assert {f'simulate, {family} family (simulate, replay_node)' for family in REGISTRY} <= jobs


def test_precompile_leaves_the_kernels_in_the_installations_cache(capsys):
    assert command([]) == 0
    out = capsys.readouterr().out
    assert str(cache_dir()) in out
    assert all(f'{family} family' in out for family in REGISTRY) and 'stepper' in out
    index = {f.name.split('-')[0] for f in cache_dir().rglob('*.nbi')}
    assert {'stepper._advance_checked', 'integrate._simulate_one'} <= index, sorted(index)


def test_precompile_compiles_the_signatures_tuning_calls():
    """The warm-up's argument types are tune's: a real objective then compiles nothing new."""
    import numpy as np

    from mmg_tuner.core import integrate
    from mmg_tuner.data.generate import generate_trial, SensorNoise
    from mmg_tuner.tuning.factory import make_objective
    from mmg_tuner.tuning.identifiability import residuals
    ship = load_ship('suzaku')
    kernels()[f'cost and residuals, {ship.model} family (tune, diagnose)']()
    before = (len(integrate._cost_many.signatures), len(integrate._residuals_many.signatures))
    _, trial = generate_trial(ship, 'zigzag', 10.0, 10.0, 60.0, 5.0, 20.0, 1.0, SensorNoise(),
                              0, 'z')
    obj = make_objective(ship, [trial])
    p = np.atleast_2d(ship.params)
    assert np.isfinite(obj(p)).all() and np.isfinite(residuals(obj, p)).all()
    assert (len(integrate._cost_many.signatures),
            len(integrate._residuals_many.signatures)) == before
