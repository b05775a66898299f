"""Identification on synthetic data: the truth recovered within the stated intervals, the relative error
brought to its floor, the structural list found by the SVD, a poor pose set's deficiencies named."""

from __future__ import annotations

import numpy as np
import pytest

from sim import calibration_sessions as synthetic
from station.calibration import (
    CalibrationError,
    CalibrationModel,
    analyse,
    equivalent_errors,
    identify,
    observation_arrays,
    relative_error_um,
    true_values,
)
from station.kinematics import A465_DH, Kinematics

STRUCTURAL_REPORTED = ["alpha0", "a0", "d1", "theta1_offset", "d2-d3", "d6", "theta6_offset"]


def _truth_values(fitted) -> dict[str, float]:
    """The truth in the identified parameterisation, by reported name (natural units)."""
    model = CalibrationModel(synthetic.setup_for())
    truth = fitted.truth
    artifacts = {k: (truth.points[k], truth.normals[k]) for k in truth.points}
    return true_values(model, truth.kinematics.dh, truth.kinematics.tool, artifacts)


def test_every_parameter_outside_the_structural_list_is_identified(fitted):
    result = fitted.result
    identified = [p.name for p in result.parameters if p.identified]
    assert result.identified_count == len(identified) == 25 + 6 + 4 * 5 - 7
    assert "d2+d3" in identified
    assert sorted(result.unidentifiable) == sorted(STRUCTURAL_REPORTED)
    assert not any(p.identified for p in result.parameters if p.structural)
    assert result.identifiability.deficient == []


def test_fit_recovers_the_truth_within_its_intervals(fitted):
    truth = _truth_values(fitted)
    z, inside = [], []
    for p in fitted.result.parameters:
        if not p.identified:
            continue
        assert p.sigma is not None
        assert p.interval is not None
        z.append((p.estimate - truth[p.name]) / p.sigma)
        inside.append(p.interval[0] <= truth[p.name] <= p.interval[1])
    assert np.mean(inside) >= 0.9, f"{np.mean(inside):.0%} of the intervals hold the truth"
    assert np.max(np.abs(z)) < 4.0, f"largest error {np.max(np.abs(z)):.2f} sigma"


def test_relative_error_after_is_ten_times_smaller_and_near_the_floor(fitted):
    held = [o for o in fitted.observations if o.configuration in set(fitted.holdout)]
    nominal = Kinematics(A465_DH, tool=synthetic.NOMINAL_TOOL)
    before, after, floor = (
        relative_error_um(held, k, synthetic.CAMERA, synthetic.MOUNT)
        for k in (nominal, fitted.result.kinematics(), fitted.truth.kinematics)
    )
    assert after * 10 <= before
    assert after <= 2 * floor
    assert fitted.result.cross_validation.relative_error_um == pytest.approx(
        {"before": before, "after": after}
    )


def test_fit_explains_the_data_to_the_noise_and_predicts_held_out_configurations(fitted):
    result = fitted.result
    assert result.fit.s2 == pytest.approx(1.0, abs=0.3)  # 5 um noise, 5 um sigmas
    assert result.residuals["after"].rms_xy_mm < 0.01 < result.residuals["before"].rms_xy_mm
    cv = result.cross_validation
    assert cv.held_out_configurations == fitted.holdout
    assert cv.after is not None
    assert cv.before is not None
    assert cv.after.rms_xy_mm < 0.015 < cv.before.rms_xy_mm


def test_svd_finds_the_structural_list_and_what_each_trades_with(fitted):
    report = analyse(fitted.observations, synthetic.setup_for())
    assert report.structural_verified
    assert report.null_dimension == 7
    assert report.unidentifiable == STRUCTURAL_REPORTED
    by_name = {d.name: d for d in report.structural}
    assert all(d.residual < 1e-6 for d in report.structural)
    assert by_name["d3"].combination == pytest.approx({"d2": 1.0}, abs=1e-6)
    assert by_name["d6"].combination == pytest.approx({"tool_z": 1.0}, abs=1e-6)
    assert by_name["theta6_offset"].combination == pytest.approx({"tool_rz": 1.0}, abs=1e-6)
    assert by_name["d1"].combination == pytest.approx({f"artifact{k}_z": -1.0 for k in range(4)}, abs=1e-6)
    assert set(by_name["a0"].combination) == {f"artifact{k}_x" for k in range(4)}
    assert all(n.startswith("artifact") for n in by_name["theta1_offset"].combination)
    assert all(n.startswith("artifact") for n in by_name["alpha0"].combination)
    assert np.isfinite(report.condition_number)
    assert report.condition_number < 1e6


def test_one_configuration_names_what_a_richer_set_resolves(fitted):
    truth = fitted.truth
    poor = synthetic.session(truth, seed=11, turns=(0.0,), max_solutions=1, inview=8, placements=(0,))
    assert len({o.configuration for o in poor}) == 1
    setup = synthetic.setup_for()
    poor_report = analyse(poor, setup)
    rich_report = analyse(fitted.observations, setup)
    assert len(poor_report.deficient) > 10
    assert {"a2", "d4", "theta2_offset", "tool_x"} <= set(poor_report.deficient)
    assert poor_report.dropped
    assert all(d.name in poor_report.deficient for d in poor_report.dropped)
    resolved = poor_report.resolved_by(rich_report)
    assert resolved == list(poor_report.deficient)
    assert rich_report.deficient == ()


def test_refuses_too_little_data_with_what_to_do(fitted):
    one = [o for o in fitted.observations if o.configuration == 0][:1]
    with pytest.raises(CalibrationError, match="capture more configurations"):
        identify(one, synthetic.setup_for())


def test_refuses_holding_out_every_configuration(fitted):
    every = sorted({o.configuration for o in fitted.observations})
    with pytest.raises(CalibrationError, match="held out"):
        identify(fitted.observations, synthetic.setup_for(), holdout=every)


def test_equivalent_errors_reproduce_the_true_arms_measurements_with_the_structural_list_nominal(fitted):
    setup = synthetic.setup_for()
    model = CalibrationModel(setup)
    truth = fitted.truth
    delta = equivalent_errors(
        model,
        truth.kinematics.dh,
        truth.kinematics.tool,
        {k: (truth.points[k], truth.normals[k]) for k in truth.points},
    )
    assert all(delta[model.index[n]] == 0.0 for n in ("alpha0", "a0", "d1", "theta1_offset", "d3", "d6"))
    exact = synthetic.session(truth, seed=21, noise_mm=0.0)
    xy, dz = model.residuals_mm(delta, observation_arrays(exact, model.placements))
    assert np.abs(xy).max() < 1e-3  # mm: only d3 x the true alpha2 and beta2 is left (second order)
    assert np.abs(dz).max() < 1e-3
    xy_nominal, _ = model.residuals_mm(model.zeros(), observation_arrays(exact, model.placements))
    assert np.abs(xy_nominal).max() > 0.1


def test_relative_error_takes_a_result_for_its_calibrated_model(fitted):
    held = [o for o in fitted.observations if o.configuration in set(fitted.holdout)]
    args = (synthetic.CAMERA, synthetic.MOUNT)
    assert relative_error_um(held, fitted.result, *args) == relative_error_um(
        held, fitted.result.kinematics(), *args
    )


def test_each_observations_residual_is_kept_and_agrees_with_the_summaries(fitted):
    """The result lists every observation's residual (µm) for the report's histograms; the RMS and the
    largest are the summaries' (to the lists' 0.01 µm rounding)."""
    result = fitted.result
    for summary in (result.residuals["before"], result.residuals["after"], result.cross_validation.after):
        xy = np.asarray(summary.xy_um)
        assert xy.size == summary.n
        assert np.all(xy >= 0)
        assert np.sqrt(np.mean(xy**2)) == pytest.approx(summary.rms_xy_mm * 1000, abs=0.01)
        assert xy.max() == pytest.approx(summary.max_xy_mm * 1000, abs=0.01)
        z = np.asarray(summary.z_um)
        assert z.size == summary.n_z
        if z.size:
            assert np.abs(z).max() == pytest.approx(summary.max_z_mm * 1000, abs=0.01)
    # fitted and held-out observations together are all of them
    n_fitted, n_held = result.residuals["after"].n, result.cross_validation.after.n
    assert n_fitted + n_held == len(fitted.observations)


def test_the_report_draws_each_observations_residual(fitted):
    """The calibration report's histograms: one step histogram per data set, holding every observation."""
    from station.kinds.calibration.report_figures import calibration_histogram_figure
    from station.kinds.calibration.results import CalibrationResults

    result = fitted.result
    doc = result.model_dump(mode="json")
    results = CalibrationResults.model_validate(
        {
            "relative_error_um": {"before": 900.0, "after": 10.0, "floor": 9.0},
            "condition_number": result.condition_number,
            "identified_count": result.identified_count,
            "parameters": [],
            "calibration": doc,
        }
    )
    named = calibration_histogram_figure(results)
    assert named is not None
    assert named.name == "calibration-residual-histograms"
    axes = named.figure.axes
    titles = [ax.get_title() for ax in axes]
    has_z = bool(result.residuals["after"].z_um)
    assert titles[0] == "Image residual, calibrated model"
    assert titles[-1] == "Image residual, nominal model"
    assert len(axes) == (3 if has_z else 2)
    # the histograms' counts are the observations: fitted and held out, per panel
    for ax, fitted_n, held_n in (
        (axes[0], result.residuals["after"].n, result.cross_validation.after.n),
        (axes[-1], result.residuals["before"].n, result.cross_validation.before.n),
    ):
        legend = ax.get_legend()
        assert legend is not None
        labels = [t.get_text() for t in legend.get_texts()]
        assert labels == [f"fitted (n={fitted_n})", f"held out (n={held_n})"]
    # results written before the residuals were listed: no histogram, no error
    drop = ("xy_um", "z_um")
    old = doc | {
        "residuals": {k: {f: x for f, x in v.items() if f not in drop} for k, v in doc["residuals"].items()}
    }
    older = CalibrationResults.model_validate(
        {
            "relative_error_um": {"before": 900.0, "after": 10.0},
            "condition_number": 1.0,
            "identified_count": 1,
            "parameters": [],
            "calibration": old,
        }
    )
    assert calibration_histogram_figure(older) is None


def test_a_robust_loss_keeps_a_few_mismeasured_captures_from_pulling_the_fit(fitted):
    """Ten fitted captures measured 150 um off (a misread crossing): least squares spreads them over
    the parameters and the held-out error grows; soft_l1 weighs them less, counts them, and stays near
    the clean fit."""
    import dataclasses

    observations = list(fitted.observations)
    held = set(fitted.holdout)
    fitted_ids = [i for i, o in enumerate(observations) if o.configuration not in held]
    rng = np.random.default_rng(7)
    bad = sorted(rng.choice(fitted_ids, size=10, replace=False).tolist())
    for i in bad:
        u, v = observations[i].center_px
        observations[i] = dataclasses.replace(observations[i], center_px=(u + 15.0, v))  # 150 um
    setup = synthetic.setup_for()
    clean = fitted.result.cross_validation.relative_error_um["after"]
    plain = identify(observations, setup, holdout=fitted.holdout)
    robust = identify(observations, setup, holdout=fitted.holdout, loss="soft_l1", f_scale=3.0)
    e_plain = plain.cross_validation.relative_error_um["after"]
    e_robust = robust.cross_validation.relative_error_um["after"]
    print(
        f"held-out relative error: clean {clean:.2f}, least squares {e_plain:.2f}, soft_l1 {e_robust:.2f} um"
    )
    assert e_plain > 1.3 * clean
    assert e_robust < 1.15 * clean
    assert robust.fit.loss == "soft_l1"
    assert robust.fit.method == "trf"
    assert robust.fit.f_scale == 3.0
    assert plain.fit.loss == "linear"
    assert plain.fit.downweighted == 0
    # the ten outliers' residuals (x, and y which stays small) are among the down-weighted ones
    assert robust.fit.downweighted >= 10
    after = np.asarray(robust.residuals["after"].xy_um)
    assert np.sort(after)[-10:].min() > 100.0  # each outlier keeps its own residual, not spread out
    # the report says how the fit weighed them
    from station.kinds.calibration.report_tables import calibration_residuals_table
    from station.kinds.calibration.results import CalibrationResults

    results = CalibrationResults.model_validate(
        {
            "relative_error_um": {"before": 900.0, "after": e_robust},
            "condition_number": robust.condition_number,
            "identified_count": robust.identified_count,
            "parameters": [],
            "calibration": robust.model_dump(mode="json"),
        }
    )
    notes = " ".join(calibration_residuals_table(results).notes)
    assert f"robust loss soft_l1 (scale 3 sigmas): {robust.fit.downweighted} residuals weigh less" in notes


def test_an_unknown_loss_or_scale_is_refused_with_the_choices(fitted):
    setup = synthetic.setup_for()
    with pytest.raises(CalibrationError, match="soft_l1"):
        identify(fitted.observations, setup, loss="tukey")
    with pytest.raises(CalibrationError, match="f_scale"):
        identify(fitted.observations, setup, loss="huber", f_scale=0.0)


def test_the_calibration_plan_offers_exactly_the_fits_losses():
    """The plan's ``loss`` parameter (a Literal, for its schema and messages) lists ``LOSSES``."""
    import typing

    from station.calibration import LOSSES
    from station.kinds.calibration.params import CalibrationParams

    assert typing.get_args(CalibrationParams.model_fields["loss"].annotation) == LOSSES
