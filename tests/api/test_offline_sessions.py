"""Sessions that measure stored images again, through the service: a sweep whose grid names its
parameters in any case (as ``--set`` and ``--grid`` do; ``{"TESTWIDTH": ...}`` as the README shows failed
at analysis), and a re-analysis of a repeatability (it failed with "no reference pose": it took the
station's context of today, and the service gives a kind without devices none)."""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from tests.api.conftest import Served, wait_final

PATTERN = [[0.0, 0.0], [254.0, 0.0], [254.0, 254.0], [0.0, 254.0]]


def run(c: httpx.Client, kind: str, params: dict[str, Any]) -> dict[str, Any]:
    r = c.post("/api/v1/sessions", json={"kind": kind, "params": params})
    assert r.status_code == 201, r.text
    final = wait_final(c, r.json()["id"])
    assert final["state"] == "succeeded", final["error"]
    return final


def test_a_sweep_grid_names_its_parameters_in_any_case(served: Served) -> None:
    with served.client() as c:
        validation = run(c, "validation", {"pattern_um": PATTERN})["id"]
        upper = run(c, "sweep", {"session": validation, "grid": {"TESTWIDTH": [3, 5], "Skip": [1]}})
        lower = run(c, "sweep", {"session": validation, "grid": {"testwidth": [3, 5], "skip": [1]}})
        trials = upper["results"]["trials"]
        assert [t["overrides"] for t in trials] == [{"testwidth": 3, "skip": 1}, {"testwidth": 5, "skip": 1}]
        assert all(t["error"] is None for t in trials)
        assert trials == lower["results"]["trials"]  # the same trials, the same numbers
        assert upper["params"]["plan"]["grid"] == {"testwidth": [3, 5], "skip": [1]}

        # what cannot be a grid is refused when the session is asked for, naming the parameter
        for grid, says in (
            ({"NOSUCH": [1]}, "grid 'NOSUCH': unknown parameter; known:"),
            ({"testwidth": [3], "TESTWIDTH": [5]}, "testwidth is already in the grid"),
            ({"TESTWIDTH": []}, "grid 'TESTWIDTH': no values"),
        ):
            r = c.post(
                "/api/v1/sessions", json={"kind": "sweep", "params": {"session": validation, "grid": grid}}
            )
            assert r.status_code == 422, r.text
            assert says in r.json()["detail"]


@pytest.mark.timeout(180)
def test_a_repeatability_is_analysed_again_as_it_was_run(served: Served) -> None:
    with served.client() as c:
        source = run(c, "repeatability", {"cycles": 3, "joints": [1, 2], "warmup_cycles": 0})
        again = run(c, "reanalyse", {"session": source["id"]})
    before, after = source["results"], again["results"]
    assert (after["kind"], after["source_session"]) == ("repeatability", source["id"])
    inner = after["repeatability"]
    # the same images measured with the same parameters: the same RP
    assert inner["rp_mm"] == pytest.approx(before["rp_mm"], rel=1e-12)
    for test in ("J1", "J2"):
        # each excursion's direction as the session chose it (from the recorded camera height: J2 moves
        # down in the simulated cell, so its excursion is negative), not +1 for want of a station
        assert inner["tests"][test]["delta_deg"] == before["tests"][test]["delta_deg"]
        assert inner["tests"][test]["away_deg"] == before["tests"][test]["away_deg"]
    assert before["tests"]["J2"]["delta_deg"] < 0
    # the analysis's checks; the controller's self-test check is the session's that drove the arm
    # (station.selftest_status), not a re-analysis's
    assert {ch["name"] for ch in after["checks"]} == {ch["name"] for ch in before["checks"]} - {"selftest"}
