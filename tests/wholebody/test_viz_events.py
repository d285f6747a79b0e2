"""The Meshcat page marks what the online estimator reported: detected load changes and run-off (issue 27)."""

from __future__ import annotations

import json

import numpy as np

from wholebody.viz import Scene
from wholebody.viz.page import animation_js
from wholebody.viz.scene import add_estimator_events


def test_load_change_and_runoff_readouts_step_at_their_times():
    report = {
        "load_changes": [{"t_change": 10.0, "t_detected": 10.2, "mass_before": 20.0, "mass_after": 30.3}],
        "runoff_flags": [{"t": 1.0, "kind": "nonpositive_inertia", "detail": ""}, {"t": 5.0, "kind": "misfit"}],
    }
    t = np.arange(0.0, 20.0, 0.1)
    with Scene(["shopping_cart"]) as sc:
        add_estimator_events(sc, report, t)
        readouts = list(sc._readouts)
    rows = [r.as_json() for r in readouts]
    mass, onset, flags = rows
    assert "load change detected" in mass["label"] and "misfit" in flags["label"]
    k = [int(round(x * 10)) for x in (10.1, 10.2, 4.9, 5.0)]
    assert mass["v"][k[0]] is None and mass["v"][k[1]] == 30.3 and onset["v"][k[1]] == 10.0  # "-" until detected
    assert flags["v"][k[2]] == 1 and flags["v"][k[3]] == 2
    json.dumps(rows, allow_nan=False)  # strict JSON: no NaN on the page
    script = animation_js((), True, readouts)
    assert "load change detected (new mass)" in script and "Number.isFinite(v)" in script  # null shows as "-"


def test_no_readouts_without_events():
    with Scene(["shopping_cart"]) as sc:
        add_estimator_events(sc, {"load_changes": [], "runoff_flags": []}, np.arange(3.0))
        add_estimator_events(sc, None, np.arange(3.0))
        assert sc._readouts == []


def test_a_run_page_shows_each_change_with_the_mass_known_at_its_detection():
    """The report's last change carries the estimate at the report's time (the run's end): a page showing it from
    the detection on showed a future value (25.6 kg at 12.3 s for an estimate of 30.6 kg then)."""
    report = {"load_changes": [{"t_change": 10.0, "t_detected": 10.2, "mass_before": 20.0, "mass_after": 25.6}]}
    t = np.arange(0.0, 20.0, 0.1)
    with Scene(["shopping_cart"]) as sc:
        add_estimator_events(sc, report, t, masses=[30.5])
        mass = sc._readouts[0].as_json()
    assert mass["label"] == "load change detected (mass at detection)"
    assert mass["v"][int(round(10.2 * 10))] == 30.5 and 25.6 not in mass["v"]
