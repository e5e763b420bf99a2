"""No silent fallbacks: the fillet-foundation formula outside its fitted range, and a store whose reducer
parameters cannot be read, are warned about and recorded (stiffness result, HTML report)."""

import warnings

import numpy as np
import pytest

from rvdiag.errors import FallbackWarning, ModelRangeWarning, RvdiagWarning
from rvdiag.evaluation.metrics import classification_metrics
from rvdiag.evaluation.report import characteristic_frequencies_for, render_report, store_reducer_params
from rvdiag.gears import GearPair, mesh_stiffness
from rvdiag.gears import tvms
from rvdiag.params import ReducerParams


@pytest.fixture
def fresh_warnings(monkeypatch):
    monkeypatch.setattr(tvms, "_WARNED", set())


def test_rv20e_sun_is_outside_the_sainsot_range_and_the_result_says_so(fresh_warnings):
    """The built-in sun's case is documented (docs/tvms.md) and noted, not warned (test_warning_lines.py); a sun
    outside the range otherwise warns, once per process."""
    pair = GearPair.sun_planet(ReducerParams.default().replace(bodies={"sun_shaft_radius": 5.5e-3}))
    assert not tvms.foundation_in_range(pair.driver) and tvms.foundation_in_range(pair.driven)
    with pytest.warns(ModelRangeWarning, match=r"theta_f = 0\.274 rad \(fitted 0\.01-0\.12 rad\)") as rec:
        res = mesh_stiffness(pair, cycles=1, points_per_cycle=12)
    assert len(rec) == 1 and issubclass(ModelRangeWarning, RvdiagWarning)
    assert res.foundation_in_range is False
    assert len(res.notes) == 1 and "driver gear (11 teeth)" in res.notes[0] and "h_fi = 1.057" in res.notes[0]
    assert res.to_dict()["foundation_in_range"] is False and res.to_dict()["notes"] == list(res.notes)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # once per process: a library build does not repeat it per simulation
        again = mesh_stiffness(pair, cycles=1, points_per_cycle=12)
    assert again.notes == res.notes


def test_a_pair_inside_the_range_has_no_note(fresh_warnings):
    pair = GearPair.from_dimensions(30, 45, 2e-3, 0.02)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = mesh_stiffness(pair, cycles=1, points_per_cycle=12)
    assert res.foundation_in_range is True and res.notes == ()
    assert tvms.foundation_range_notes(GearPair.from_dimensions(20, 40, 2e-3, 0.02)) == (
        "fillet-foundation stiffness of the driver gear (20 teeth) is extrapolated beyond the fit of Sainsot et "
        "al. (2004): theta_f = 0.151 rad (fitted 0.01-0.12 rad)",)


SPEED = {"output_speed_deg_s": np.full(4, 45.0)}


def test_unreadable_store_parameters_warn_and_are_noted():
    notes = []
    with pytest.warns(FallbackWarning, match="cannot be read"):
        f = characteristic_frequencies_for({"params": {"nonsense": 1}}, SPEED, notes=notes)
    default = characteristic_frequencies_for({}, SPEED)
    assert f == default  # the RV-20E's figures ...
    assert len(notes) == 2 and "cannot be read" in notes[0] and "default RV-20E" in notes[1]  # ... and said so


def test_store_parameters_are_used_and_their_tvms_caveat_noted():
    p = ReducerParams.default()
    notes = []
    f = characteristic_frequencies_for({"params": p.to_dict()}, SPEED, notes=notes)
    assert f["fsp"] == pytest.approx(165.0, rel=1e-3)
    assert notes == [f"sun-planet mesh stiffness (TVMS): {tvms.foundation_range_notes(GearPair.sun_planet(p))[0]}"]
    params, notes2 = store_reducer_params({"params": p.to_dict()})
    assert params == p and notes2 == notes
    assert store_reducer_params({"params": None}) == (None, [])  # measured data: nothing to say until used
    n3 = []
    characteristic_frequencies_for({"params": None}, SPEED, notes=n3)
    assert n3 == ["characteristic frequencies: the store gives no reducer parameters, those of the default "
                  "RV-20E are marked"]


def test_report_shows_the_caveats_before_the_library_config():
    y = np.array(["T1", "T2"] * 5)
    m = classification_metrics(y, y, labels=["T1", "T2"])
    card = {"model": "svm", "kind": "classical", "classes": ["T1", "T2"], "input_length": 8}
    store = {"path": "lib.zarr", "split": "test", "kind": "simulated", "config": {}, "config_hash": "x"}
    html = render_report(title="t", metrics=m, card=card, store_info=store,
                         notes=["sun-planet mesh stiffness (TVMS): theta_f <out>"])
    assert "<b>1 caveat(s)</b>" in html
    assert html.index(">Caveats<") < html.index(">Library config<")
    assert "<li>sun-planet mesh stiffness (TVMS): theta_f &lt;out&gt;</li>" in html
    assert "Caveats" not in render_report(title="t", metrics=m, card=card, store_info=store)
